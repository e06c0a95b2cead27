"""How far the fit's dither moves the mean features at the truth, in mild rattle.

`FitOptions.dither` gives each simulated realisation a fixed, centred log-offset of `a` and
`drag_torque` (half of it for the viscosity), so that the mean features are a smooth function
of the parameters. A recording, though, is one realisation at exactly its parameters. This
study measures, at the truth of the joint-fit test's backlash sweep (pair II, boundary, 10 %
at 8 Hz), the gap between

* E[data]: the mean features of `--realisations` undithered realisations made the way
  `rattlefit.simulation.synthetic.synthesize` makes a recording (commanded drive, rtol 1e-7,
  nothing set aside), and
* the fit's mean features (measured drive, the fit's rtol, regimes set aside) with each dither,

in units of one recording's run-to-run spread, then the undithered profile of that gap along
log `drag_torque` (the other parameters at the truth).

    python benchmarks/dither_bias.py [--center-distance 65.4] [--realisations 24] [--seed 5]

A few minutes at 65.4 mm on 2 cores; at 65.0 mm the rtol 1e-7 reference takes far longer.
benchmarks/README.md ("Dither bias in mild rattle") discusses the outcome.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import rattlefit as rf
from rattlefit.features.ensemble import ensemble_mean
from rattlefit.inference.forward import evaluate
from rattlefit.inference.options import FitOptions
from rattlefit.inference.problem import build_problem
from rattlefit.io.recording import OperatingPoint
from rattlefit.simulation.synthetic import synthesize

TRUTH = {"film_half_length": 0.085e-3, "drag_torque": 0.025, "viscosity": 0.4942}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--center-distance", type=float, default=65.4)
    ap.add_argument("--realisations", type=int, default=24)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--dithers", type=float, nargs="+", default=[0.0, 0.03, 0.1])
    args = ap.parse_args()
    print(f"{rf.use_cpu_cores()} JAX device(s); seed {args.seed}", flush=True)
    op = OperatingPoint("boundary", 20.0, 52.36, 5.236, 8.0)
    g = rf.table2_pair("II", center_distance_mm=args.center_distance)
    truth = rf.RattleParams(
        TRUTH["film_half_length"], TRUTH["drag_torque"], TRUTH["viscosity"], g.backlash
    )
    # one recording, only for its measured drive (the fit's θ1)
    rec, _ = synthesize(g, op, truth, seed=args.seed)

    def problem(stream=0, **kw):
        # the reference draws its release states from its own stream: with the fit's, two
        # nearly periodic ensembles would share trajectories and agree better than they should
        opts = FitOptions(seed=args.seed, n_realisations=args.realisations, **kw)
        prob, rigs = build_problem([rec], opts, np.random.default_rng([args.seed, stream]))
        values = {
            "film_half_length": TRUTH["film_half_length"],
            "drag_torque": TRUTH["drag_torque"],
            "viscosity_scale": TRUTH["viscosity"] / float(rigs[0].viscosity),
            "backlash[0]": g.backlash,
        }
        z = np.array([s.z_of(values.get(s.name, s.center or 1.0)) for s in prob.specs])
        return prob, z

    def mean_features(prob, zs, threshold):
        t = time.perf_counter()
        f = evaluate(prob, np.atleast_2d(zs))[:, 0]  # (K, M, B)
        print(f"  ({len(f)}×{args.realisations} simulations, {time.perf_counter() - t:.0f} s)")
        return f, np.asarray(ensemble_mean(f, threshold))

    ref, z = problem(1, dither=0.0, regime_threshold=None, rtol=1e-7, drive="commanded")
    f, _ = mean_features(ref, z, None)
    expected, sd = f[0].mean(axis=0), f[0].std(axis=0, ddof=1)
    sd = np.maximum(sd, 1e-3)  # a locked orbit has no spread in its low bands
    print("one recording's run-to-run sd per band (log10):", np.round(sd, 3))

    def gap(mean):
        e = (expected - mean) / sd
        return f"mean square {np.mean(e**2):9.2f}, largest {np.max(np.abs(e)):7.2f}"

    for dither in args.dithers:
        prob, z = problem(dither=dither)
        _, m = mean_features(prob, z, prob.regime_threshold)
        print(f"dither {dither:5.3f}: (E[data] − fit mean)/sd at the truth: {gap(m[0])}")

    prob, z = problem(dither=0.0)
    i = [s.name for s in prob.specs].index("drag_torque")
    ts = np.linspace(-0.2, 0.2, 11)
    zs = np.tile(z, (len(ts), 1))
    zs[:, i] += ts / float(prob.specs[i].dlog_dz(z[i]))
    _, m = mean_features(prob, zs, prob.regime_threshold)
    print("undithered, along log drag_torque (others at the truth):")
    for t, mk in zip(ts, m, strict=True):
        print(f"  {t:+.2f}: {gap(mk)}")


if __name__ == "__main__":
    main()
