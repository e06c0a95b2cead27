"""What the velocity's absolute tolerance costs in steps and in band features.

The fit's simulations take their absolute tolerances per state component, ``rtol`` times the
state's characteristic sizes (:data:`rattlefit.simulation.solve.STATE_SCALES`: 1 mm for q,
30 mm/s for v; :data:`~rattlefit.simulation.solve.DRY_STATE_SCALES`, 1 mm/s for v, for dry
flanks). This script simulates M realisations (released
across the gap, seeded) at the truth of shared recordings with the lockstep integrator, at the
fit's rtol and several velocity scales, and compares each ensemble's mean band features with a
tight lockstep reference (rtol 1e-7, the dry scales): the rms and largest difference over the
bands in units of their standard error (each ensemble's spread over √M, with the fit's floor
``sigma_floor`` per realisation, so that a periodic orbit, whose realisations agree, is judged
at the resolution the fit has; independent chaotic ensembles give rms z about 1), and the
steps of the batch's slowest member (a lockstep batch takes as many iterations as that
member's steps; in a chaotic regime that maximum varies by ±20 % between realisations) and
their mean.

    python benchmarks/state_tolerance.py                    # the three default files, M = 48
    python benchmarks/state_tolerance.py --scales 1e-3 3e-2 1e-1 --rtol-loose 1e-4

Nothing asserts a number; benchmarks/README.md discusses the outcome.
"""

from __future__ import annotations

import argparse
import sys
import time

NAMES = (
    "pairII_boundary_65.0_10pct_8Hz",  # mild rattle: a periodic orbit
    "pairII_dry_65.6_20pct_16Hz",  # dry: chaotic, hard impacts
    "pairI_oiljet_65.4_20pct_8Hz",
)
SIGMA_FLOOR = 0.03  # FitOptions.sigma_floor: the smallest band spread the fit resolves


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--names", nargs="+", default=list(NAMES))
    ap.add_argument("--realisations", type=int, default=48)
    ap.add_argument("--rtol", type=float, default=1e-5, help="the fit's rtol")
    ap.add_argument(
        "--scales", type=float, nargs="+", default=[1e-3, 3e-2, 5e-2, 1e-1], help="v sizes, m/s"
    )
    ap.add_argument("--rtol-loose", type=float, nargs="*", default=[1e-4])
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)

    import rattlefit

    rattlefit.configure()
    import jax.numpy as jnp
    import numpy as np

    from rattlefit.features.spectra import spectral_features
    from rattlefit.simulation.solve import (
        DRY_STATE_SCALES,
        STATE_SCALES,
        broadcast_params,
        simulate_batch,
    )
    from rattlefit.testing.shared import operating_points, truth_params  # the shared files

    m = args.realisations
    print(f"seed {args.seed}, {m} realisations, fit rtol {args.rtol}", flush=True)
    q_scale, v_old = STATE_SCALES[0], DRY_STATE_SCALES[1]  # m; m/s, the dry velocity scale
    settings = [("reference", 1e-7, v_old)]
    settings += [(f"v {s * 1e3:g} mm/s", args.rtol, s) for s in args.scales]
    settings += [(f"rtol {r:g}, v 1 mm/s", r, v_old) for r in args.rtol_loose]
    for name, rig, truth in operating_points(args.names):
        params = broadcast_params(truth_params(rig, truth), m)
        c = rig.geometry.backlash / 2
        rng = np.random.default_rng(args.seed)
        y0 = jnp.asarray(np.stack([rng.uniform(-0.9 * c, 0.9 * c, m), np.zeros(m)], axis=1))
        feats, steps = {}, {}
        for label, rtol, v_scale in settings:
            t0 = time.perf_counter()
            sol = simulate_batch(
                rig.model,
                params,
                rig.drive,
                y0=y0,
                batch="lockstep",
                rtol=rtol,
                atol=(rtol * q_scale, rtol * v_scale),
                duration=3.0,
                burn_in=0.5,
            )
            f = spectral_features(sol.relative_motion, rig.bands, noise_floor=rig.noise_floor)
            feats[label] = np.asarray(f)
            steps[label] = (int(np.max(sol.num_steps)), float(np.mean(sol.num_steps)))
            print(
                f"  {name} {label}: {steps[label][0]} steps (slowest member), "
                f"{time.perf_counter() - t0:.1f} s",
                file=sys.stderr,
                flush=True,
            )
        ref = feats["reference"]
        base = steps[settings[1][0]]
        print(f"{name}: reference {steps['reference'][0]} steps (slowest member)")
        for label, _, _ in settings[1:]:
            f = feats[label]
            se = np.sqrt(
                np.maximum(ref.var(axis=0, ddof=1), SIGMA_FLOOR**2) / m
                + np.maximum(f.var(axis=0, ddof=1), SIGMA_FLOOR**2) / m
            )
            z = (f.mean(axis=0) - ref.mean(axis=0)) / se
            slowest, mean = steps[label]
            print(
                f"  {label:>22s}: steps {slowest:6d} slowest ({slowest / base[0]:.2f}×), "
                f"{mean:6.0f} mean ({mean / base[1]:.2f}×), "
                f"band means rms z {np.sqrt(np.mean(z**2)):.2f}, max |z| {np.max(np.abs(z)):.2f}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
