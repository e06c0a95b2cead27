"""Training the learned density so that the same seed gives the same weights on any core count.

XLA's CPU backend splits a long reduction, and the contraction over the batch in a batched
gradient, over its intra-op threads; with one thread it sums in another order, so the last
bits of a gradient depend on how many cores the process may use. Training amplifies those
bits into other weights, the weights choose the next round's design points, and rattle's chaos
turns those into other simulations. Here every sum over simulations is therefore explicit: a
gradient is computed per simulation and the per-simulation values are added by
:func:`pairwise_sum`, a fixed binary tree of elementwise additions, which XLA neither splits
nor reorders.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import paramax


def pairwise_sum(x):
    """The sum of ``x`` over its leading axis, added in a fixed binary tree (the result does
    not depend on the thread count)."""
    n = x.shape[0]
    size = 1 << max(n - 1, 0).bit_length()
    if size > n:
        x = jnp.concatenate([x, jnp.zeros((size - n, *x.shape[1:]), x.dtype)])
    while x.shape[0] > 1:
        half = x.shape[0] // 2
        x = x[:half] + x[half:]
    return x[0]


def pairwise_mean(x):
    """:func:`pairwise_sum` divided by the count."""
    return pairwise_sum(x) / x.shape[0]


#: Simulations whose gradients are summed by XLA itself, inside one chunk: a contraction this
#: short runs on one thread whatever the thread count.
CHUNK = 16


def mean_value_and_grad(loss_one: Callable, params, *data):
    """The mean over the leading axis (N) of ``data`` of ``loss_one(params, *row)`` and its
    gradient with respect to ``params``: per chunk of :data:`CHUNK` rows by XLA, over the
    chunks by :func:`pairwise_sum` (rows padded to a whole chunk carry zero weight)."""
    n = data[0].shape[0]
    pad = -n % CHUNK
    weight = jnp.concatenate([jnp.ones(n), jnp.zeros(pad)]).reshape(-1, CHUNK)
    chunks = [
        jnp.concatenate([a, jnp.repeat(a[-1:], pad, axis=0)]).reshape(-1, CHUNK, *a.shape[1:])
        for a in data
    ]

    def chunk_loss(p, weight, *rows):
        losses = jax.vmap(loss_one, in_axes=(None, *[0] * len(rows)))(p, *rows)
        return jnp.sum(weight * losses)

    values, grads = jax.vmap(jax.value_and_grad(chunk_loss), in_axes=(None, 0, *[0] * len(chunks)))(
        params, weight, *chunks
    )
    return pairwise_sum(values) / n, jax.tree_util.tree_map(lambda g: pairwise_sum(g) / n, grads)


def partition(tree):
    """Trainable arrays and the rest of ``tree`` (paramax's non-trainable leaves are kept
    out, as flowjax does)."""
    return eqx.partition(
        tree, eqx.is_inexact_array, is_leaf=lambda leaf: isinstance(leaf, paramax.NonTrainable)
    )


def flow_nll(params, static, w, x):
    """The negative log-likelihood of one whitened simulation ``w`` (F,) at ``x`` (P,)."""
    flow = paramax.unwrap(eqx.combine(params, static))
    return -flow.log_prob(w, condition=x)


@eqx.filter_jit
def flow_epoch(params, state, static, batches_w, batches_x, learning_rate):
    """One epoch of Adam at ``learning_rate`` over the batches (B, batch, ·): the parameters,
    the optimiser state and the mean training loss."""
    optimizer = optax.adam(learning_rate)

    def step(carry, batch):
        params, state = carry
        loss, grads = mean_value_and_grad(lambda p, w, x: flow_nll(p, static, w, x), params, *batch)
        updates, state = optimizer.update(grads, state, params)
        return (optax.apply_updates(params, updates), state), loss

    (params, state), losses = jax.lax.scan(step, (params, state), (batches_w, batches_x))
    return params, state, pairwise_mean(losses)


@eqx.filter_jit
def flow_loss(params, static, w, x):
    """The mean negative log-likelihood of the simulations ``w`` (N, F) at ``x`` (N, P)."""
    return pairwise_mean(jax.vmap(lambda wi, xi: flow_nll(params, static, wi, xi))(w, x))


def train_flow(
    flow,
    w,
    x,
    rng: np.random.Generator,
    *,
    learning_rate: float,
    batch_size: int,
    max_epochs: int,
    patience: int,
    validation: float,
):
    """Maximum-likelihood training of a conditional ``flow`` on whitened features ``w``
    (N, F) at inputs ``x`` (N, P): Adam on shuffled minibatches of ``batch_size`` (the last,
    incomplete one dropped), stopped after ``patience`` epochs without improvement of the
    loss on a held-out ``validation`` fraction. Returns the flow at its best epoch and the
    per-epoch held-out losses. Deterministic for a given ``rng`` state.
    """
    w, x = np.asarray(w), np.asarray(x)
    order = rng.permutation(len(w))
    n_val = max(1, round(validation * len(w)))
    val, train = order[:n_val], order[n_val:]
    batch = min(batch_size, len(train))
    params, static = partition(flow)
    state = optax.adam(learning_rate).init(params)
    rate = jnp.asarray(learning_rate)
    best, losses = params, []
    val_w, val_x = jnp.asarray(w[val]), jnp.asarray(x[val])
    for _ in range(max_epochs):
        idx = rng.permutation(train)[: len(train) // batch * batch].reshape(-1, batch)
        params, state, _ = flow_epoch(
            params, state, static, jnp.asarray(w[idx]), jnp.asarray(x[idx]), rate
        )
        losses.append(float(flow_loss(params, static, val_w, val_x)))
        if losses[-1] <= min(losses):
            best = params
        elif len(losses) - 1 - int(np.argmin(losses)) > patience:
            break
    return eqx.combine(best, static), losses
