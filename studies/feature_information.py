"""How much each feature family says about `a`, `T_b` and the viscosity: the Fisher
information of one recording, from rattlefit's simulator.

At each operating regime, ``n`` seeded recordings are simulated at the truth and at each
parameter moved by a factor ``e^{±δ}`` (independent seeds per point). For a family of
features (the 28 log-band PSDs, the drive-cycle-folded statistics of
:mod:`rattlefit.features.folded`, or both), the mean's derivative ``D`` (per unit log of each
parameter, central differences) and the ensemble covariance ``C`` at the truth (band spreads
floored as in the fit, the correlation shrunk) give the Fisher information of one recording,
``F = Dᵀ C⁻¹ D``, less the bias that the Monte Carlo noise of ``D`` adds to its diagonal,
``2p / (n (2δ)²)`` (its negative eigenvalues then set to zero). The nuisances (viscosity,
h_min, stiffness scale) are parameters too, with the fit's priors added. The predicted 95 %
interval of each parameter is the factor ``exp(2 · 1.96 · sd)``, sd from
``F⁻¹``. This predicts what a fit with those features could reach; it is not a fit.

    python studies/feature_information.py [--n 24] [--delta 0.4] [--json out.json]

Seeds: the truth's recordings use seeds 0…n−1, each moved point the next n.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from common import tree_state, write_result

import rattlefit as rf
from rattlefit.features.ensemble import shrunk_correlation
from rattlefit.features.folded import PHASE_BINS
from rattlefit.features.spectra import BandSpec, spectral_features
from rattlefit.io.recording import OperatingPoint
from rattlefit.reproducibility import platform_info
from rattlefit.rig import setup

#: (name, pair, centre distance mm, lubrication, fluctuation %, frequency Hz, a m, viscosity)
REGIMES = (
    ("headline boundary", "II", 65.6, "boundary", 20.0, 16.0, 0.085e-3, 0.4942),
    ("mild boundary", "II", 65.0, "boundary", 10.0, 8.0, 0.085e-3, 0.4942),
    ("oil jet", "II", 65.6, "oil_jet", 20.0, 16.0, 1.0e-3, 0.3477),
    ("dry", "II", 65.6, "dry", 20.0, 16.0, 0.0, 0.4942),
)
DRAG = 0.025
MEAN_SPEED = 52.36
MIN_FILM = 2e-6
#: The nuisances' priors (log-sd), as the fit's.
PRIORS = {"viscosity": 0.25, "min_film": 0.7, "stiffness_scale": 0.3}
#: σ floors of the band features (log10, as the fit's) and of the folded statistics.
FLOORS = (0.03, 0.01)
Z95 = 1.959964


def features(rec) -> tuple[np.ndarray, np.ndarray]:
    """(bands, folded) features of a recording, the folded ones from the speed's maximum."""
    x = rec.relative_motion
    bands = np.asarray(spectral_features(x, BandSpec.for_recording(rec.sample_rate_hz)))
    return bands, setup(rec).folded()


def ensemble(geometry, op, params: dict, seeds) -> tuple[np.ndarray, np.ndarray]:
    """Features of the recordings at ``params`` with ``seeds``: (n, 28), (n, 3·bins)."""
    p = rf.RattleParams(
        params["film_half_length"], params["drag_torque"], params["viscosity"], geometry.backlash
    )
    out = [features(rf.synthesize(geometry, op, p, seed=int(s), rtol=1e-6)[0]) for s in seeds]
    return np.stack([b for b, _ in out]), np.stack([f for _, f in out])


def joined(families: tuple[np.ndarray, ...], cols) -> np.ndarray:
    """The feature families ``cols`` of ``families`` side by side: (n, Σ p)."""
    return np.concatenate([families[c] for c in cols], axis=1)


def fisher(center: np.ndarray, plus: list, minus: list, delta: float, floor) -> np.ndarray:
    """Bias-corrected Fisher information (P, P) of one recording from the features at the
    truth (n, p) and at each parameter's ± points (lists of (n, p))."""
    n = center.shape[0]
    sd = np.maximum(center.std(axis=0, ddof=1), floor)
    corr = shrunk_correlation(center)
    cov = corr * np.outer(sd, sd)
    d = np.stack(
        [(hi.mean(0) - lo.mean(0)) / (2 * delta) for hi, lo in zip(plus, minus, strict=True)], 1
    )
    info = d.T @ np.linalg.solve(cov, d)
    info -= np.eye(len(plus)) * 2 * center.shape[1] / (n * (2 * delta) ** 2)
    value, vector = np.linalg.eigh(info)  # the correction can overshoot: keep it ≥ 0
    return (vector * np.maximum(value, 0.0)) @ vector.T


def regime_study(regime, n: int, delta: float, say) -> dict:
    name, pair, cd, lub, pct, freq, a, mu = regime
    g = rf.table2_pair(pair, center_distance_mm=cd)
    op = OperatingPoint(lub, 20.0, MEAN_SPEED, MEAN_SPEED * pct / 100, freq)
    truth = {"film_half_length": a, "drag_torque": DRAG, "viscosity": mu, "min_film": MIN_FILM}
    truth["stiffness_scale"] = 1.0
    names = ["drag_torque", "stiffness_scale"] if lub == "dry" else list(truth)
    t0 = time.perf_counter()
    center = ensemble(g, op, truth, range(n))
    plus, minus = [], []
    for k, p in enumerate(names):
        seeds = [range(n * (2 * k + 1), n * (2 * k + 2)), range(n * (2 * k + 2), n * (2 * k + 3))]
        plus.append(ensemble(g, op, truth | {p: truth[p] * math.exp(delta)}, seeds[0]))
        minus.append(ensemble(g, op, truth | {p: truth[p] * math.exp(-delta)}, seeds[1]))
    out = {"regime": name, "parameters": names, "seconds": round(time.perf_counter() - t0, 1)}
    for family, cols in (("bands", [0]), ("folded", [1]), ("bands+folded", [0, 1])):
        floor = np.concatenate([np.full(center[c].shape[1], FLOORS[c]) for c in cols])
        info = fisher(
            joined(center, cols),
            [joined(e, cols) for e in plus],
            [joined(e, cols) for e in minus],
            delta,
            floor,
        )
        info += np.diag([1 / PRIORS[p] ** 2 if p in PRIORS else 0.0 for p in names])
        sd = np.sqrt(np.diag(np.linalg.pinv(info)))
        out[family] = {p: round(math.exp(2 * Z95 * s), 3) for p, s in zip(names, sd, strict=True)}
        say(f"{name:18s} {family:13s} 95 % factor: {out[family]}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--delta", type=float, default=0.4)
    ap.add_argument("--json")
    args = ap.parse_args()
    rows = [regime_study(r, args.n, args.delta, print) for r in REGIMES]
    if args.json:
        write_result(args.json, result_document(rows, args.n, args.delta))


def result_document(rows: list[dict], n: int, delta: float) -> dict:
    """The result file (``studies/results/``) of the regimes' ``rows``."""
    head = {r["regime"]: r for r in rows}
    h = head["headline boundary"]

    def factors(family: str) -> str:
        f = h[family]
        return f"a {f['film_half_length']}, T_b {f['drag_torque']}, μ {f['viscosity']}"

    return {
        "order": 12.5,
        "what": "the Fisher information of one 3 s recording about a, T_b and μ per feature "
        "family, as predicted 95 % interval factors (rattlefit's simulator; h_min and the "
        "stiffness scale with the fit's priors)",
        "summary": f"headline boundary point (pair II, 65.6 mm, 20 % at 16 Hz): "
        f"{factors('bands')} with the band PSDs; {factors('bands+folded')} with the "
        "drive-cycle statistics added",
        "aim": "—",
        "verdict": "—",
        "measured": f"{n} seeded recordings per point, central differences at e^±{delta}, "
        "the Monte Carlo bias of the derivatives removed",
        "command": "python studies/feature_information.py --json OUT",
        "results": {"n": n, "delta": delta, "phase_bins": PHASE_BINS, "regimes": rows},
        "platform": platform_info(),
        **tree_state(),
    }


if __name__ == "__main__":
    rf.configure()
    main()
