"""What XLA's library calls cost inside a lockstep step, against the forms rattlefit uses.

On a CPU XLA compiles ``jnp.sin``, ``jnp.cos`` and ``jnp.arctan`` to one library call per
value, and a small batched ``einsum`` to a matrix-product library call; sums and products of a
batch become vector instructions. rattlefit computes the drive's sine and cosine and the
squeeze film's arctangent as polynomials (:mod:`rattlefit.physics.elementary`) and the
integrator's dense output by Horner's rule (:func:`rattlefit.simulation.lockstep.dense_output`).
This times each pair in one process, alternating, as a loop of 20k dependent iterations
over a batch of ``--rows`` values (the fit's 24 rows a device, and a wide batch for the
throughput), and reports ns per value and iteration and the ratio new / library. Nothing
asserts a time; pin it to one core (``taskset -c 0``) for steadier figures.

    python benchmarks/elementwise_cost.py                 # 24 and 240 rows, 5 repetitions
    python benchmarks/elementwise_cost.py --rows 8 24 --reps 9
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

ITERATIONS = 20_000


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, nargs="+", default=[24, 240])
    parser.add_argument("--reps", type=int, default=5)
    args = parser.parse_args(argv)

    import rattlefit

    rattlefit.configure(cpu_cores=1)
    import jax
    import jax.numpy as jnp

    from rattlefit.physics.elementary import arctan, sin_cos_cycles
    from rattlefit.simulation.lockstep import dense_output

    def weights(s):  # diffrax's factored Tsit5 interpolant, as the integrator had it
        s2 = s * s
        b1 = -1.0530884977290216 * s * (s - 1.3299890189751412)
        b1 = b1 * (s2 - 1.4364028541716351 * s + 0.7139816917074209)
        b2 = 0.1017 * s2 * (s2 - 2.1966568338249754 * s + 1.2949852507374631)
        b3 = 2.490627285651252793 * s2 * (s2 - 2.38535645472061657 * s + 1.57803468208092486)
        b4 = -16.54810288924490272 * (s - 1.21712927295533244) * (s - 0.61620406037800089) * s2
        b5 = 47.37952196281928122 * (s - 1.203071208372362603) * (s - 0.658047292653547382) * s2
        b6 = -34.87065786149660974 * (s - 1.2) * (s - 0.666666666666666667) * s2
        b7 = 2.5 * (s - 1) * (s - 0.6) * s2
        return jnp.stack([b1, b2, b3, b4, b5, b6, b7], axis=-1)

    slots = jnp.linspace(0.1, 0.9, 9)

    def dense_einsum(x):
        kh = jnp.stack([x * (0.1 * i + 1.0) for i in range(7)], 1)[..., None] * 1e-3
        y = jnp.einsum("bsi,bid->bsd", weights(jnp.broadcast_to(slots, (x.shape[0], 9))), kh)
        return x + 1e-3 * y[:, 4, 0]

    def dense_horner(x):
        kh = [(x * (0.1 * i + 1.0))[:, None] * 1e-3 for i in range(7)]
        y = dense_output(jnp.zeros((x.shape[0], 1)), kh, jnp.broadcast_to(slots, (x.shape[0], 9)))
        return x + 1e-3 * y[:, 4, 0]

    pairs = {
        "sin and cos": (
            lambda x: jnp.sin(2 * jnp.pi * x) + jnp.cos(2 * jnp.pi * x),
            lambda x: sum(sin_cos_cycles(x)),
        ),
        "arctan": (jnp.arctan, arctan),
        "dense output": (dense_einsum, dense_horner),
    }
    for b in args.rows:
        x0 = jnp.linspace(0.1, 0.9, b)
        for name, (library, ours) in pairs.items():
            runs = {}
            for label, fn in (("library", library), ("rattlefit", ours)):
                run = jax.jit(
                    lambda x, fn=fn: jax.lax.fori_loop(
                        0, ITERATIONS, lambda i, v: 0.5 * fn(v) * 1e-3 + 0.5 * v, x
                    )
                )
                run(x0).block_until_ready()  # compile
                runs[label] = run
            times = {k: [] for k in runs}
            for _ in range(args.reps):
                for label, run in runs.items():
                    t0 = time.perf_counter()
                    run(x0).block_until_ready()
                    times[label].append((time.perf_counter() - t0) / ITERATIONS / b * 1e9)
            lib, new = (statistics.median(times[k]) for k in ("library", "rattlefit"))
            print(
                f"{b:4d} rows  {name:13s} library {lib:6.2f} ns  rattlefit {new:6.2f} ns a value "
                f"(median of {args.reps})  ratio {new / lib:.2f}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
