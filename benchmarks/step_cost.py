"""Cost of one lockstep step with the stiffness tables shared, against a copy per row.

Every fit simulates its rows with :func:`rattlefit.simulation.solve.solve_rows`, 24 rows a
device, and the mesh-stiffness table is read at every vector-field call. With a copy of the
table per row (64 KB for the mild shared file's pair, so 1.5 MB for 24 rows) the copies do not
stay in cache; the fit's rows therefore read their table out of one shared stack
(:func:`rattlefit.physics.model.share_stiffness_tables`). This script times both layouts in one
process, alternating them, on the mild shared file's operating point at its truth (rows
released across the gap, 3.5 s at rtol 1e-5 as the fit runs them), and reports µs per step
(per iteration of the lockstep loop, i.e. per step of the row that takes most) and their
ratio. Both layouts give the same table entries; their trajectories differ only by rounding.

    python benchmarks/step_cost.py                 # 24 rows, 5 repetitions, one device
    python benchmarks/step_cost.py --rows 8 24 64

Pin it to one core (``taskset -c 0``) for steadier figures; nothing asserts a time.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

NAME = "pairII_boundary_65.0_10pct_8Hz"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, nargs="+", default=[24])
    parser.add_argument("--reps", type=int, default=5)
    args = parser.parse_args(argv)

    import rattlefit

    rattlefit.configure(cpu_cores=1)
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import numpy as np

    from rattlefit.physics.model import share_stiffness_tables
    from rattlefit.simulation.solve import broadcast_params, solve_rows
    from rattlefit.testing.shared import operating_points, truth_params  # the shared files

    [(_, setup, truth)] = operating_points([NAME])
    params = truth_params(setup, truth)
    opts = dict(
        n_samples=30_000,
        sample_rate=setup.sample_rate,
        burn_in=0.5,
        rtol=1e-5,
        atol=1e-8,
        max_steps=200_000,
    )

    @eqx.filter_jit
    def copies(models, p, drives, y0):
        return solve_rows(models, p, drives, y0, **opts).num_steps

    @eqx.filter_jit
    def shared(models, p, drives, y0, tables):
        return solve_rows(models, p, drives, y0, stiffness_tables=tables, **opts).num_steps

    one = jax.tree_util.tree_map(lambda x: x[None], setup.model)
    untabled, tables = share_stiffness_tables(one)
    report = {}
    for b in args.rows:

        def rows_of(tree, b=b):  # materialised per row, as a fit's rows are
            return jax.tree_util.tree_map(lambda x: jnp.asarray(np.repeat(x, b, axis=0)), tree)

        drives = rows_of(jax.tree_util.tree_map(lambda x: x[None], setup.drive))
        c = float(setup.geometry.backlash) / 2
        y0 = jnp.stack([jnp.linspace(-0.9, 0.9, b) * c, jnp.zeros(b)], axis=1)
        p_rows = broadcast_params(params, b)
        layouts = {
            "copy per row": (copies, (rows_of(one), p_rows, drives, y0)),
            "shared": (shared, (rows_of(untabled), p_rows, drives, y0, tables)),
        }
        times = {k: [] for k in layouts}
        for fn, fn_args in layouts.values():
            jax.block_until_ready(fn(*fn_args))  # compile
        for _ in range(args.reps):
            for k, (fn, fn_args) in layouts.items():
                t0 = time.perf_counter()
                steps = int(np.max(np.asarray(jax.block_until_ready(fn(*fn_args)))))
                times[k].append((time.perf_counter() - t0) / steps * 1e6)
        med = {k: statistics.median(v) for k, v in times.items()}
        report[b] = med | {"ratio": med["shared"] / med["copy per row"]}
        print(
            f"{b:3d} rows: copy per row {med['copy per row']:.1f} µs a step, shared "
            f"{med['shared']:.1f} µs (median of {args.reps}); ratio {report[b]['ratio']:.2f}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
