"""Spread batches of simulations over every local device (CPU cores or GPUs).

An adaptive solve of this model is a long chain of tiny scalar steps, which one XLA CPU device
runs on one core. JAX exposes a single CPU device unless told otherwise, so a batch of
simulations (``simulate_batch``, and every evaluation inside ``identify``) would leave the other
cores idle. :func:`rattlefit.use_cpu_cores` asks JAX for one CPU device per core — it must
run before JAX executes anything, which is why the command-line interface calls it first
thing — and :func:`map_rows` then splits a batch evenly over the devices with ``shard_map``;
each device runs its share with ``jax.lax.map``. With one device :func:`map_rows` is exactly
``jax.lax.map``, so its results never depend on whether the cores were enabled (the features
agree to the last bit). :func:`map_blocks` gives each device its whole share at once, for the
lockstep integrator of :mod:`rattlefit.simulation.lockstep`; a vectorised transcendental may
round differently in another batch layout, and rattle's chaos grows that into another
realisation, so results computed that way depend on the device count. A fit's evaluations do
not use it: :func:`rattlefit.problem.forward.evaluate_rows` runs fixed-size blocks, one
program for every device, so that its results do not.

On a GPU, JAX already lists every GPU, and :func:`map_rows` shards over them unchanged.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, PartitionSpec


def map_rows(fn: Callable, rows):
    """``jax.lax.map(fn, rows)``, with the rows split evenly over all local devices.

    ``rows`` is a pytree whose leaves share a leading axis; the output has that axis too.
    Rows are padded (repeating the last) to a multiple of the device count and the padding is
    dropped from the result, so any batch size works.
    """
    return map_blocks(lambda block: jax.lax.map(fn, block), rows)


def map_blocks(fn: Callable, rows):
    """``fn(rows)`` for a batched ``fn``, with the rows split evenly over all local devices.

    Each device applies ``fn`` to its whole share at once (for a vectorised computation such
    as :func:`rattlefit.simulation.lockstep.solve_lockstep`); the rows are padded and unpadded as in
    :func:`map_rows`, whose one-row-at-a-time loop is the special case.
    """
    devices = jax.local_devices()
    n_dev = len(devices)
    size = jax.tree_util.tree_leaves(rows)[0].shape[0]
    if n_dev == 1 or size == 1:
        return fn(rows)
    n_dev = min(n_dev, size)
    padded = -(-size // n_dev) * n_dev

    def pad(x):
        extra = jnp.repeat(x[-1:], padded - size, axis=0)
        return jnp.concatenate([x, extra]) if padded > size else x

    mesh = Mesh(np.asarray(devices[:n_dev]), ("rows",))
    spec = PartitionSpec("rows")
    sharded = jax.shard_map(
        fn,
        mesh=mesh,
        in_specs=(spec,),
        out_specs=spec,
        # the solver's internal loops mix per-device and replicated values; every row is
        # independent, so no replication check is needed
        check_vma=False,
    )
    out = sharded(jax.tree_util.tree_map(pad, rows))
    return jax.tree_util.tree_map(lambda x: x[:size], out)
