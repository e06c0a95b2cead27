"""The learned feature distribution: an ensemble of small networks, each a Gaussian over the
features given the parameters.

Each member maps a design point ``u`` (:mod:`rattlefit.likelihood.design`) to the mean and
the spread of the features of one simulation, and shares one correlation factor across the
parameter space; it is trained by maximising the Gaussian likelihood of single simulations,
so the spread it learns is the simulator's run-to-run (chaotic) spread at each point. The
members differ only in their initial weights. Their mean is the emulated mean, and their
disagreement is the emulator's own error, which :func:`predict` adds to the covariance
(a mixture's moments), so that the likelihood widens where the design is thin.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax


@dataclasses.dataclass(frozen=True)
class EmulatorOptions:
    """How the feature emulator is built and trained.

    ``members``: networks in the ensemble (≥ 2: their spread is the emulator's error).
    ``width``, ``depth``: hidden units per layer and hidden layers of each network (tanh).
    ``steps``: full-batch Adam steps; ``learning_rate``: its initial rate (cosine decay to
    1/30 of it); ``weight_decay``: AdamW's decoupled weight decay.
    """

    members: int = 4
    width: int = 48
    depth: int = 2
    steps: int = 1500
    learning_rate: float = 3e-3
    weight_decay: float = 1e-4

    def __post_init__(self):
        if self.members < 2:
            raise ValueError(f"EmulatorOptions.members: need at least 2, got {self.members}")
        for name in ("width", "depth", "steps"):
            if getattr(self, name) < 1:
                raise ValueError(f"EmulatorOptions.{name}: need at least 1")
        if not self.learning_rate > 0 or self.weight_decay < 0:
            raise ValueError("EmulatorOptions: learning_rate > 0 and weight_decay ≥ 0 needed")


class Member(eqx.Module):
    """One network: a design point (standardised, (P,)) → the standardised features' mean and
    log scale (F,) each, and a unit lower-triangular correlation factor shared over ``u``."""

    mlp: eqx.nn.MLP
    lower: jax.Array  # (F, F), only the strictly lower triangle is used

    def __init__(self, n_in: int, n_out: int, width: int, depth: int, key):
        self.mlp = eqx.nn.MLP(n_in, 2 * n_out, width, depth, activation=jnp.tanh, key=key)
        self.lower = jnp.zeros((n_out, n_out))

    def factor(self) -> jax.Array:
        """The correlation factor L (F, F): unit diagonal, learned strictly lower triangle."""
        n = self.lower.shape[0]
        return jnp.tril(self.lower, -1) + jnp.eye(n)

    def __call__(self, x):
        out = self.mlp(x)
        n = out.shape[0] // 2
        return out[:n], out[n:]

    def nll(self, xs, ys):
        """Mean negative log-likelihood of standardised features ``ys`` (N, F) at ``xs``
        (N, P), less its constant: ½|L⁻¹(y − m)/s|² + Σ log s per simulation."""
        mean, log_scale = jax.vmap(self)(xs)
        r = (ys - mean) * jnp.exp(-log_scale)
        eye = jnp.eye(r.shape[1], dtype=r.dtype)
        inverse = jax.scipy.linalg.solve_triangular(
            self.factor(), eye, lower=True, unit_diagonal=True
        )
        w = r @ inverse.T
        return jnp.mean(0.5 * jnp.sum(w**2, axis=1) + jnp.sum(log_scale, axis=1))


class FeatureEmulator(eqx.Module):
    """The trained ensemble with its input and output standardisation.

    ``predict(u)`` gives the features' mean (F,) and covariance (F, F) at a design point
    ``u`` (P,); :attr:`columns` are the fit's parameter indices this recording reads.
    """

    members: Member  # stacked over the ensemble
    x_shift: jax.Array  # (P,)
    x_scale: jax.Array  # (P,)
    y_shift: jax.Array  # (F,)
    y_scale: jax.Array  # (F,)
    columns: tuple[int, ...] = eqx.field(static=True)

    def standardise(self, u):
        return (u[..., jnp.asarray(self.columns)] - self.x_shift) / self.x_scale

    def member_moments(self, u):
        """Each member's mean (E, F) and covariance (E, F, F) at ``u`` (full P), in feature
        units."""
        x = self.standardise(u)

        def one(member):
            mean, log_scale = member(x)
            lf = member.factor() * jnp.exp(log_scale)[:, None]
            return mean, lf @ lf.T

        mean, cov = eqx.filter_vmap(one)(self.members)
        s = self.y_scale
        return self.y_shift + s * mean, cov * s[:, None] * s[None, :]

    def moments(self, u):
        """The features' mean (F,) at ``u``, their chaotic covariance (F, F; the members'
        average) and the emulator's error covariance (F, F; the members' spread of the
        mean)."""
        mean, cov = self.member_moments(u)
        m = jnp.mean(mean, axis=0)
        d = mean - m
        return m, jnp.mean(cov, axis=0), d.T @ d / mean.shape[0]

    def predict(self, u):
        """The features' mean (F,) and covariance (F, F) at ``u``: the ensemble's mixture
        moments, so the members' disagreement (the emulator's error) adds to the chaotic
        spread."""
        m, chaotic, error = self.moments(u)
        return m, chaotic + error

    def emulator_variance(self, u):
        """The members' variance of the mean (F,): the emulator's own error at ``u``."""
        return jnp.diagonal(self.moments(u)[2])


def fit_emulator(
    u, features, columns, options: EmulatorOptions, seed: np.random.SeedSequence
) -> tuple[FeatureEmulator, np.ndarray]:
    """Train a :class:`FeatureEmulator` on single simulations: design points ``u`` (N, P full)
    and their features (N, F). Returns it and each member's final training loss (E,) (mean
    negative log-likelihood per simulation in standardised units).

    Deterministic for a given ``seed``: full-batch training, seeded initial weights.
    """
    u = np.asarray(u, float)
    y = np.asarray(features, float)
    x = u[:, list(columns)]
    x_shift, x_scale = x.mean(axis=0), np.maximum(x.std(axis=0), 1e-6)
    y_shift, y_scale = y.mean(axis=0), np.maximum(y.std(axis=0), 1e-6)
    # trained in single precision (twice as fast; the data's own noise is far above its
    # rounding), evaluated in the caller's precision
    xs = jnp.asarray((x - x_shift) / x_scale, dtype=jnp.float32)
    ys = jnp.asarray((y - y_shift) / y_scale, dtype=jnp.float32)
    key = jax.random.key(int(np.random.default_rng(seed).integers(2**31)))
    keys = jax.random.split(key, options.members)
    make = lambda k: Member(xs.shape[1], ys.shape[1], options.width, options.depth, k)  # noqa: E731
    members = eqx.filter_vmap(make)(keys)
    members = jax.tree_util.tree_map(
        lambda a: a.astype(jnp.float32) if eqx.is_inexact_array(a) else a, members
    )
    members, losses = train_members(members, xs, ys, options)
    members = jax.tree_util.tree_map(
        lambda a: a.astype(jnp.float64) if eqx.is_inexact_array(a) else a, members
    )
    emulator = FeatureEmulator(
        members,
        jnp.asarray(x_shift),
        jnp.asarray(x_scale),
        jnp.asarray(y_shift),
        jnp.asarray(y_scale),
        tuple(int(c) for c in columns),
    )
    return emulator, np.asarray(losses)


def optimiser(options: EmulatorOptions) -> optax.GradientTransformation:
    """AdamW with a cosine decay of the learning rate to 1/30 of ``learning_rate``."""
    schedule = optax.cosine_decay_schedule(options.learning_rate, options.steps, alpha=1 / 30)
    return optax.adamw(schedule, weight_decay=options.weight_decay)


@eqx.filter_jit
def train_members(members: Member, xs, ys, options: EmulatorOptions):
    """Train every member (stacked) for ``options.steps`` full-batch steps on the
    standardised data; returns them and their final mean losses (E,)."""
    opt = optimiser(options)

    def loss(member):
        return member.nll(xs, ys)

    def train_one(member):
        params, static = eqx.partition(member, eqx.is_inexact_array)
        state = opt.init(params)

        def step(carry, _):
            params, state = carry
            value, grads = jax.value_and_grad(lambda p: loss(eqx.combine(p, static)))(params)
            updates, state = opt.update(grads, state, params)
            return (optax.apply_updates(params, updates), state), value

        (params, _), values = jax.lax.scan(step, (params, state), None, length=options.steps)
        return eqx.combine(params, static), values[-1]

    return eqx.filter_vmap(train_one)(members)
