"""Is a recording a typical draw of the model at its truth, and which change makes it one?

Rattle can be multistable: at one operating point the driven gear settles into one of several
regimes, and a recording is a single draw. `identify` compares a recording with the mean of
the simulated realisations' common regime (`FitOptions.regime_threshold`), so a recording in a
minority regime is fitted by moving the majority towards it. This script, for one of the
independent simulator's shared recordings (with its `truth.json`):

* simulates `--realisations` realisations at the truth (lockstep, rtol 1e-5, released at rest
  across the gap) and reports, band by band, their mean minus the recording (log10 PSD with the
  white quantisation floor), and each realisation's rms distance to the recording;
* with `--reference N`, does the same with N runs of the sharp scipy reference (DOP853, rtol
  1e-8; about 10 s each), to tell the smoothed model from the equations;
* with `--variants`, repeats the rattlefit part with one parameter changed at a time (`h_min`,
  μ, `T_b`, a, the stiffness scale) and reports how the bands below the drive and the rms move.

    python benchmarks/regimes.py [--recording pairII_oiljet_65.6_20pct_16Hz]
                                 [--realisations 48] [--reference 16] [--variants]
                                 [--devices N]

The realisations are seeded by their release states, but the compiled program, and so each
chaotic draw, depends on the device count: the README's tables are from `--devices 1`.

About 1 minute without the reference on 2 cores. Results are in benchmarks/README.md ("The
pair II oil-jet shared file is a regime this model reaches rarely").
"""

from __future__ import annotations

import argparse
import time

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import rattlefit as rf
from rattlefit.features.spectra import spectral_features
from rattlefit.physics.model import DEFAULT_MIN_FILM, RattleParams
from rattlefit.simulation.reference import simulate_reference
from rattlefit.simulation.solve import broadcast_params, simulate_batch
from studies import operating_points, truth_params  # the shared files

#: (label, field of RattleParams, factor on the truth) for ``--variants``
VARIANTS = (
    *(
        (f"h_min {h:g} µm", "min_film", h * 1e-6 / DEFAULT_MIN_FILM)
        for h in (2.5, 3, 3.5, 4, 5, 6, 10)
    ),
    *((f"μ × {f:g}", "viscosity", f) for f in (0.9, 0.8, 0.7, 0.6, 0.5)),
    ("T_b × 2", "drag_torque", 2.0),
    ("a × 0.3", "film_half_length", 0.3),
    ("a × 0.1", "film_half_length", 0.1),
)


def _features(setup, motion) -> np.ndarray:
    return np.asarray(spectral_features(motion, setup.bands, noise_floor=setup.noise_floor))


def _releases(setup, n: int) -> np.ndarray:
    return np.linspace(-0.95, 0.95, n) * setup.geometry.backlash / 2


def _rattlefit(setup, params: RattleParams, n: int) -> np.ndarray:
    q0 = jnp.asarray(_releases(setup, n))
    sol = simulate_batch(
        setup.model,
        broadcast_params(params, n),
        setup.drive,
        y0=jnp.stack([q0, jnp.zeros(n)], axis=1),
        batch="lockstep",
        duration=setup.duration,
        sample_rate=setup.sample_rate,
        rtol=1e-5,
        atol=1e-8,
    )
    if not bool(np.all(np.asarray(sol.success))):
        raise RuntimeError("a realisation failed to solve")
    return _features(setup, sol.relative_motion)


def _summary(label: str, feats: np.ndarray, data: np.ndarray, low: int) -> str:
    d = feats.mean(axis=0) - data
    rms = np.sqrt(np.mean((feats - data) ** 2, axis=1))
    return (
        f"{label:18s} Δ below the drive {' '.join(f'{x:+.2f}' for x in d[:low])}; "
        f"rms median {np.median(rms):.3f} (smallest {rms.min():.3f})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recording", default="pairII_oiljet_65.6_20pct_16Hz")
    ap.add_argument("--realisations", type=int, default=48)
    ap.add_argument("--reference", type=int, default=0, metavar="N")
    ap.add_argument("--variants", action="store_true")
    ap.add_argument(
        "--devices", type=int, help="JAX CPU devices (default one per core; other draws)"
    )
    args = ap.parse_args()

    print(f"{rf.use_cpu_cores(args.devices)} JAX device(s)", flush=True)
    [(_, setup, truth)] = operating_points([args.recording])
    params = truth_params(setup, truth)
    data = np.asarray(setup.features)
    centers = np.asarray(setup.bands.centers)
    low = int(np.sum(centers < 0.9 * setup.recording.operating.drive_frequency_hz))

    t0 = time.perf_counter()
    feats = _rattlefit(setup, params, args.realisations)
    print(
        f"rattlefit: {args.realisations} realisations at the truth, "
        f"{time.perf_counter() - t0:.0f} s"
    )
    ref = None
    if args.reference:
        runs = []
        for k, q0 in enumerate(_releases(setup, args.reference)):
            sol = simulate_reference(
                setup.geometry,
                setup.drive,
                film_half_length=params.film_half_length,
                drag_torque=params.drag_torque,
                viscosity=params.viscosity,
                backlash=params.backlash,
                initial_state=(float(q0), 0.0),
                duration=setup.duration,
                sample_rate=setup.sample_rate,
            )
            runs.append(np.asarray(sol.relative_motion))
            print(f"  reference {k + 1}/{args.reference}", flush=True)
        ref = _features(setup, np.stack(runs))

    print(
        "\nband (Hz)  recording  rattlefit − recording (sd)"
        + ("  reference − rec." if ref is not None else "")
    )
    for b, c in enumerate(centers):
        diff, sd = feats[:, b].mean() - data[b], feats[:, b].std()
        line = f"{c:9.1f}  {data[b]:9.2f}  {diff:+6.2f} ({sd:.2f})"
        if ref is not None:
            line += f"  {ref[:, b].mean() - data[b]:+6.2f}"
        print(line)
    print()
    print(_summary("rattlefit, truth", feats, data, low))
    if ref is not None:
        print(_summary("reference, truth", ref, data, low))
    if args.variants:
        n = max(args.realisations // 2, 2)
        for label, field, factor in VARIANTS:
            value = getattr(params, field) * factor
            changed = eqx.tree_at(lambda p, f=field: getattr(p, f), params, value)
            print(_summary(label, _rattlefit(setup, changed, n), data, low), flush=True)


if __name__ == "__main__":
    main()
