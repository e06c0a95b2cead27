"""An event-free fixed-step scheme for the smoothed model: how accurate, and how fast.

One of the routes to cheaper simulations: classical fourth-order Runge–Kutta at a fixed step
``h = 1 / (k · sample_rate)``, a sample every ``k`` steps (no interpolation, no error estimate,
no rejected step, a ``lax.scan`` over samples with ``k`` steps inside), on
:meth:`rattlefit.physics.model.RattleModel.vector_field` exactly as the fits integrate it. At
each of the seven operating points of the forward comparison (``benchmarks/run.py``) it
simulates the same ``M`` release states as the sharp reference and reports, per ``k``:

* ``z``: the rms over bands of the ensemble-mean feature difference from the sharp reference,
  in units of its chaotic standard error (``suite_report.rms_z``, the forward comparison's
  measure; it matches below ``Z_MATCH``). The reference's features are read from the forward
  comparison's raw results (``benchmarks/results/raw/full.json``, the sharp reference at its
  tight tolerances), which this script does not recompute;
* ``finite``: whether every realisation stayed finite (a fixed step can go unstable where the
  squeeze film's damping is stiff);
* the wall time of one simulation, and its ratio to :func:`rattlefit.simulate` at rtol 1e-4
  (the forward comparison's matched tolerance) timed in this process.

Then, in batches (what fits and learning rounds run), it times ``--rows`` members of the
bundled boundary recording's rows (``step_anatomy.rows_of``) through the lockstep integrator
(:func:`rattlefit.simulation.lockstep.solve_lockstep`, rtol 1e-4) and through the fixed-step
scheme over the same rows, vmapped and one member at a time (``lax.map``), alternately, and
reports each per member.

Nothing asserts a time or an accuracy.

    python benchmarks/fixed_step.py [--steps-per-sample 1 2 3 5 10] [--batch-steps 2 3]
        [--rows 32] [--repeats 3] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import rattlefit as rf
from rattlefit.features.spectra import spectral_features
from rattlefit.physics.model import with_stiffness_tables
from rattlefit.simulation.solve import simulate
from rattlefit.testing.results import provenance, write_result
from rattlefit.testing.shared import operating_points, truth_params
from run import FORWARD_POINTS as POINTS
from step_anatomy import SAMPLE_RATE, compiled_block, model_field, rows_of
from suite_report import rms_z
from suite_steps import BURN_IN, DURATION, Z_MATCH, M, release_fractions, sim_options

RAW = Path(__file__).resolve().parent / "results" / "raw" / "full.json"
#: rattlefit's adaptive path at the forward comparison's matched tolerance.
ADAPTIVE_RTOL = 1e-4


def rk4_step(field, t, y, h, args):
    """One classical Runge–Kutta step of ``field(t, y, args)`` from ``(t, y)``."""
    k1 = field(t, y, args)
    k2 = field(t + h / 2, y + h / 2 * k1, args)
    k3 = field(t + h / 2, y + h / 2 * k2, args)
    k4 = field(t + h, y + h * k3, args)
    return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def fixed_step_motion(model, params, drive, y0, *, k: int, sample_rate: float):
    """Δθ* = −q/r1 at the recorded samples of one RK4 simulation, ``k`` steps per sample,
    released at ``y0`` (q, v) ``BURN_IN`` s before the first sample."""
    h = 1.0 / (k * sample_rate)
    n_burn = round(BURN_IN * sample_rate)
    n = round(DURATION * sample_rate)
    args = (params, drive)

    def sample(y, i):
        t0 = (i - n_burn) / sample_rate

        def step(j, y):
            return rk4_step(model.vector_field, t0 + j * h, y, h, args)

        y = jax.lax.fori_loop(0, k, step, y)
        return y, y[0]

    y = model.full_state(y0)
    _, q = jax.lax.scan(sample, y, jnp.arange(n_burn + n))
    # q[i] is the state at sample i + 1 − n_burn; keep the recorded samples 0 … n − 1
    return -q[n_burn - 1 : n_burn - 1 + n] / model.r1


#: :func:`fixed_step_motion` compiled once per step count and rate (both static).
FIXED_STEP = eqx.filter_jit(fixed_step_motion)


def best_time(fn, repeats: int) -> float:
    """The shortest of ``repeats`` wall times of ``fn()`` (after one call that compiles)."""
    jax.block_until_ready(fn())
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - t)
    return min(times)


def one_point(name, s, truth, reference, ks, repeats):
    """The fixed-step rows of one operating point, and its adaptive time."""
    params = truth_params(s, truth)
    c = s.geometry.backlash / 2
    y0s = [jnp.asarray([f * c, 0.0]) for f in release_fractions(M)]
    adaptive = sim_options(s, ADAPTIVE_RTOL)
    t_adaptive = best_time(lambda: simulate(s.model, params, s.drive, y0=y0s[0], **adaptive), 3)
    rows = []
    for k in ks:
        # the model, parameters and drive are arguments, as simulate()'s are, not constants
        # that XLA could fold into the program
        def run(y0, k=k):
            return FIXED_STEP(s.model, params, s.drive, y0, k=k, sample_rate=s.sample_rate)

        motion = np.stack([np.asarray(run(y0)) for y0 in y0s])
        finite = bool(np.all(np.isfinite(motion)))
        z = None
        if finite:
            feats = spectral_features(motion, s.bands, noise_floor=s.noise_floor)
            z = rms_z(np.asarray(feats), reference)
        t_fixed = best_time(lambda run=run: run(y0s[0]), repeats)
        rows.append(
            {
                "steps_per_sample": k,
                "step_us": 1e6 / (k * s.sample_rate),
                "steps": k * round((DURATION + BURN_IN) * s.sample_rate),
                "finite": finite,
                "z": z,
                "matched": finite and z < Z_MATCH,
                "fixed_ms": 1e3 * t_fixed,
                "adaptive_ms": 1e3 * t_adaptive,
                "speed_vs_adaptive": t_adaptive / t_fixed,
            }
        )
        zs = "unstable" if not finite else f"z {z:.2f}"
        print(
            f"{name} k={k}: {zs}, {1e3 * t_fixed:.0f} ms against {1e3 * t_adaptive:.0f} ms "
            f"adaptive (×{t_adaptive / t_fixed:.2f})",
            file=sys.stderr,
        )
    return rows


def batch_times(n_rows: int, ks, repeats: int) -> dict:
    """Per member (ms): the lockstep block of ``n_rows`` rows, and the fixed-step scheme
    vmapped over the same rows at each ``k``; the best of ``repeats`` alternated rounds."""
    rows, tables, y0 = rows_of(n_rows)
    lockstep = compiled_block(model_field, tables, True)

    def fixed(k, batched):
        def one(row, y):
            model = with_stiffness_tables(row[0], tables)
            return fixed_step_motion(model, row[1], row[2], y, k=k, sample_rate=SAMPLE_RATE)

        if batched:
            return jax.jit(jax.vmap(one))
        return jax.jit(lambda rows, y0: jax.lax.map(lambda a: one(*a), (rows, y0)))

    runs = {"lockstep": lambda rows, y0: lockstep(rows, y0)[0]}
    runs.update({f"fixed k={k}, vmapped": fixed(k, True) for k in ks})
    runs.update({f"fixed k={k}, one member at a time": fixed(k, False) for k in ks})
    for run in runs.values():
        jax.block_until_ready(run(rows, y0))  # compiles
    best = dict.fromkeys(runs, np.inf)
    for _ in range(repeats):
        for name, run in runs.items():
            t = time.perf_counter()
            jax.block_until_ready(run(rows, y0))
            best[name] = min(best[name], time.perf_counter() - t)
    out = {name: 1e3 * t / n_rows for name, t in best.items()}
    for name, ms in out.items():
        print(f"batch of {n_rows}, {name}: {ms:.2f} ms per member", file=sys.stderr)
    return out


def summary(points: dict) -> str:
    """One line: at the cheapest matching step of each point, the speed against the adaptive
    path."""
    best = []
    for rows in points.values():
        ok = [r for r in rows if r["matched"]]
        best.append(max(r["speed_vs_adaptive"] for r in ok) if ok else None)
    matched = [b for b in best if b is not None]
    if not matched:
        return f"no fixed step matched the sharp reference (z < {Z_MATCH}) at any of the points"
    return (
        f"{len(matched)} of {len(best)} points matched by some fixed step; at the cheapest "
        f"matching step {min(matched):.2f}–{max(matched):.2f}× the adaptive path's speed"
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps-per-sample", type=int, nargs="+", default=[2, 5, 10, 20])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--batch-steps", type=int, nargs="+", default=[2, 3])
    ap.add_argument("--rows", type=int, default=32)
    ap.add_argument("--names", nargs="+", default=list(POINTS))
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    rf.configure()
    reference = json.loads(RAW.read_text())["reference"]["points"]
    points = {}
    for name, s, truth in operating_points(args.names):
        ref = np.asarray(reference[name]["tight"]["features"])
        points[name] = one_point(name, s, truth, ref, args.steps_per_sample, args.repeats)
    batch = batch_times(args.rows, args.batch_steps, args.repeats)
    fastest = min(v for k, v in batch.items() if k != "lockstep")
    line = (
        f"{summary(points)}; in a batch of {args.rows} the lockstep costs "
        f"{batch['lockstep']:.1f} ms per member, the fixed step {fastest:.1f} ms at best"
    )
    print(line)
    if args.json:
        doc = {
            "order": 2.7,
            "what": "an event-free fixed-step scheme (RK4): its band features against the sharp "
            "reference, its speed against the adaptive path and the lockstep",
            "summary": line,
            "aim": "—",
            "verdict": "—",
            "measured": f"{M} realisations per point released across the gap, 3 s after 0.5 s "
            f"at each point's truth, steps per sample {args.steps_per_sample}, best of "
            f"{args.repeats} times after a compiling call; the batch: {args.rows} rows of the "
            "bundled boundary recording, the integrators alternated",
            "results": {
                "points": points,
                "batch_ms_per_member": batch,
                "rows": args.rows,
                "z_match": Z_MATCH,
                "realisations": M,
            },
            **provenance(),
        }
        write_result(args.json, doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
