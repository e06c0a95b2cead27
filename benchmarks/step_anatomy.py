"""Where a lockstep step's time goes: the integrator alone, the drive, the whole vector field.

Every fit, learning round and null simulates through
:func:`rattlefit.simulation.lockstep.solve_lockstep`. This script times one block of rows on one
device with three vector fields of the same shape, in one process, alternated:

* ``integrator``: a damped linear oscillator, a few multiplications: what is left is the
  integrator's own work (Tsit5's stages, the error control, the dense output into the samples),
  and once more with the samples dropped (XLA then removes the dense output and the writes into
  the sample buffer, so the difference is their cost);
* ``drive``: the gear in free flight under the Fourier drive and the drag torque
  (:meth:`rattlefit.physics.drive.Drive.angle_and_acceleration`), no contact and no film;
* ``model``: :meth:`rattlefit.physics.model.RattleModel.vector_field`, what the fits run.

Each is reported in µs per member and loop iteration (the lockstep's unit of work: every
member pays for every iteration of the block), the best of ``--repeats`` rounds after one that
compiles (a round repeats a block for half a second at least), and as a share of the whole
model's step. The rows are the bundled boundary recording's pair, drive and truth, released
across the gap, 3.5 s simulated at the fit's tolerances (rtol 10⁻⁴). Nothing asserts a time.

    python benchmarks/step_anatomy.py [--rows 24] [--repeats 9] [--json FILE]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import rattlefit as rf
from rattlefit.io.recording import read_truth
from rattlefit.physics.model import share_stiffness_tables, with_stiffness_tables
from rattlefit.simulation.lockstep import solve_lockstep
from rattlefit.simulation.solve import absolute_tolerances, broadcast_params
from rattlefit.testing.results import provenance, write_result

ROOT = Path(__file__).resolve().parents[1]
RECORDING = ROOT / "data" / "pairII_boundary_65.6_20pct_16Hz.h5"
RTOL, DURATION, BURN_IN, SAMPLE_RATE = 1e-4, 3.0, 0.5, 10_000.0


def oscillator(t, y, row):
    """A damped linear oscillator at ten times the drive's frequency (the integrator's cost)."""
    _, _, drive = row
    omega = 20 * jnp.pi * drive.frequency
    return jnp.stack([y[1], -(omega**2) * y[0] - 0.1 * omega * y[1]])


def free_flight(t, y, row):
    """The driven gear in flight: the drive's inertial forcing and the drag torque only."""
    model, params, drive = row
    _, acc1 = drive.angle_and_acceleration(t)
    return jnp.stack([y[1], -params.drag_torque / (model.r2 * model.mass) - model.r1 * acc1])


def model_field(t, y, row):
    """The rattle model's vector field, as every fit runs it."""
    model, params, drive = row
    return model.vector_field(t, y, (params, drive))


#: name → (vector field, whether the samples are kept). Without its samples XLA drops the
#: dense output and the writes into the sample buffer: the difference is what they cost.
CASES = {
    "integrator, samples dropped": (oscillator, False),
    "integrator": (oscillator, True),
    "drive": (free_flight, True),
    "model": (model_field, True),
}


def rows_of(n: int):
    """``n`` rows of the bundled boundary recording at its truth, released across the gap:
    (models without their tables, params, drives), the shared table stack, and y0 (n, 2)."""
    setup = rf.rig.setup(rf.read_recording(RECORDING))
    truth = read_truth(RECORDING)
    params = rf.RattleParams(
        truth["film_half_length"], truth["drag_torque"], truth["viscosity"], setup.geometry.backlash
    )
    models = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (n, *jnp.shape(x))), setup.model)
    untabled, tables = share_stiffness_tables(models)
    drives = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (n, *jnp.shape(x))), setup.drive)
    half = 0.5 * float(params.backlash)
    y0 = np.stack([np.linspace(-0.9 * half, 0.9 * half, n), np.zeros(n)], axis=1)
    return (untabled, broadcast_params(params, n), drives), tables, jnp.asarray(y0)


def compiled_block(field, tables, keep_samples: bool):
    """One block's solve with ``field``, compiled once: (rows, y0) → (samples or None, steps,
    result). Each row's model reads its stiffness table out of the shared stack ``tables``,
    as the fits' rows do."""

    def with_table(t, y, row):
        return field(t, y, (with_stiffness_tables(row[0], tables), *row[1:]))

    def block(rows, y0):
        ys, steps, result = solve_lockstep(
            with_table,
            y0,
            rows,
            t0=-BURN_IN,
            n_samples=round(DURATION * SAMPLE_RATE),
            sample_rate=SAMPLE_RATE,
            rtol=RTOL,
            atol=absolute_tolerances(RTOL),
            max_steps=400_000,
        )
        return (ys if keep_samples else None), steps, result

    return jax.jit(block)


#: Each timing repeats its block until this much wall time (s) has passed: the integrator's
#: block alone takes a few tens of milliseconds.
MIN_WALL_S = 0.5


def timed(block, rows, y0) -> tuple[float, int]:
    """Wall time (s) of one block (the mean over repeats filling :data:`MIN_WALL_S`) and its
    loop iterations (the longest member's steps)."""
    calls, t0 = 0, time.perf_counter()
    while True:
        _, steps, result = jax.block_until_ready(block(rows, y0))
        calls += 1
        wall = time.perf_counter() - t0
        if wall >= MIN_WALL_S:
            break
    if not np.all(np.asarray(result) == 0):
        raise RuntimeError("a member failed")
    return wall / calls, int(np.asarray(steps).max())


def measure(n_rows: int, repeats: int) -> dict[str, dict]:
    """µs per member and iteration of each field (best of ``repeats`` after a compiling run)."""
    rows, tables, y0 = rows_of(n_rows)
    blocks = {name: compiled_block(f, tables, keep) for name, (f, keep) in CASES.items()}
    best: dict[str, float] = {}
    iterations: dict[str, int] = {}
    for k in range(repeats + 1):
        for name, block in blocks.items():
            wall, its = timed(block, rows, y0)
            if k:  # the first round compiles
                best[name] = min(best.get(name, np.inf), wall)
            iterations[name] = its
        print(f"[{k}/{repeats}]", file=sys.stderr, flush=True)
    return {
        name: {
            "us_per_member_iteration": best[name] / (iterations[name] * n_rows) * 1e6,
            "iterations": iterations[name],
            "wall_s": best[name],
        }
        for name in CASES
    }


def document(results: dict, n_rows: int, repeats: int) -> dict:
    whole = results["model"]["us_per_member_iteration"]
    share = {k: v["us_per_member_iteration"] / whole for k, v in results.items()}
    return {
        "order": 2.5,
        "what": "where a lockstep step's time goes: the integrator alone, the drive, the model",
        "summary": f"{whole:.2f} µs per member and iteration for the model's step; the "
        f"integrator alone {share['integrator']:.0%} of it (its dense output and sample writes "
        f"{share['integrator'] - share['integrator, samples dropped']:.0%}), with the drive "
        f"{share['drive']:.0%}; the forces (contact, film, stiffness table) the rest",
        "aim": "—",
        "verdict": "—",
        "measured": f"{n_rows} rows on one device, best of {repeats} rounds of ≥ {MIN_WALL_S} s "
        "after a compiling one, "
        "the fields alternated; 3.5 s at rtol 1e-4 from the bundled boundary recording's "
        "truth, rows released across the gap",
        "results": {"fields": results, "share_of_model_step": share, "rows": n_rows},
        **provenance(),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=24)
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--json", type=Path, help="write the result file here")
    args = ap.parse_args(argv)
    rf.configure(cpu_cores=1)
    results = measure(args.rows, args.repeats)
    for name, r in results.items():
        print(f"{name:11s} {r['us_per_member_iteration']:6.3f} µs per member and iteration "
              f"({r['iterations']} iterations, {r['wall_s']:.2f} s)")  # fmt: skip
    if args.json:
        write_result(args.json, document(results, args.rows, args.repeats))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
