"""The learned feature distribution: a conditional Gaussian whitening followed by a
conditional normalising flow, over one recording's features given the parameters.

Two stages map the standardised features ``y`` (F,) at a standardised design point ``x`` to a
residual ``r`` (F,) that is standard normal where the simulator's distribution has been
learned:

1. :class:`Whitening`, a small network: the features' mean and log scale at ``x`` and a
   correlation factor shared over ``x``, ``w = L⁻¹ (y − m(x)) / s(x)``. It holds the bulk:
   a mean that follows the parameters and a spread that changes by orders of magnitude
   between chaotic and periodic regimes.
2. A masked autoregressive flow with rational-quadratic spline transformers (flowjax),
   conditioned on ``x``, ``r = f⁻¹(w; x)``. It starts at the identity and holds what a
   Gaussian cannot: skewed features, and bands that are bimodal where regimes coexist. Its
   training stops early on held-out simulations, so where the design is thin it stays near
   the identity and the density near the Gaussian.

Both are trained by maximising the likelihood of single simulations, the whitening first, with
gradients summed in an order that does not depend on the thread count
(:mod:`rattlefit.likelihood.training`).
``|r|²`` is χ² on F degrees of freedom where the model holds. A variance ``floor`` (F,) is
added to the training features as Gaussian noise, so the density is that of a simulation plus
that noise: the floor of what any recording can be compared with, whatever the simulator's own
spread.
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from flowjax.bijections import RationalQuadraticSpline
from flowjax.distributions import Normal
from flowjax.flows import masked_autoregressive_flow

from .training import mean_value_and_grad, pairwise_mean, pairwise_sum, train_flow


@dataclasses.dataclass(frozen=True)
class DensityOptions:
    """How the feature density is built and trained.

    Whitening: trained when ``whitening`` (else the identity: the flow alone, for comparison);
    ``whitening_width`` hidden units in each of ``whitening_depth`` tanh layers,
    ``whitening_steps`` full-batch AdamW steps from ``whitening_rate`` (cosine decay to 1/30)
    with decoupled ``weight_decay``.
    Flow: ``layers`` autoregressive layers with ``width`` hidden units (one hidden layer),
    splines of ``knots`` knots on ``[-interval, interval]`` (identity outside); Adam at
    ``learning_rate`` on minibatches of ``batch_size``, at most ``max_epochs``, stopped after
    ``patience`` epochs without improvement on a held-out ``validation`` fraction (the best
    epoch kept).
    """

    whitening: bool = True
    whitening_width: int = 48
    whitening_depth: int = 2
    whitening_steps: int = 1500
    whitening_rate: float = 3e-3
    weight_decay: float = 1e-4
    layers: int = 3
    width: int = 48
    knots: int = 8
    interval: float = 5.0
    learning_rate: float = 1e-3
    batch_size: int = 256
    max_epochs: int = 300
    patience: int = 10
    validation: float = 0.1

    def __post_init__(self):
        counts = ("whitening_width", "whitening_depth", "whitening_steps", "layers", "width")
        for name in (*counts, "knots", "batch_size", "max_epochs", "patience"):
            if getattr(self, name) < 1:
                raise ValueError(f"DensityOptions.{name}: need at least 1")
        rates = (self.whitening_rate, self.learning_rate, self.interval)
        if not (min(rates) > 0 and self.weight_decay >= 0 and 0 < self.validation < 1):
            raise ValueError(
                "DensityOptions: rates and interval > 0, weight_decay ≥ 0 and "
                "0 < validation < 1 needed"
            )


class Whitening(eqx.Module):
    """A standardised design point (P,) → the standardised features' mean and log scale (F,)
    each, with a unit lower-triangular correlation factor shared over the design."""

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

    def whiten(self, y, x):
        """``w = L⁻¹ (y − m) / s`` (F,) and ``Σ log s``."""
        mean, log_scale = self(x)
        w = jax.scipy.linalg.solve_triangular(
            self.factor(), (y - mean) * jnp.exp(-log_scale), lower=True, unit_diagonal=True
        )
        return w, jnp.sum(log_scale)

    def colour(self, w, x):
        """The inverse of :meth:`whiten`: ``y = m + s · L w``."""
        mean, log_scale = self(x)
        return mean + jnp.exp(log_scale) * (self.factor() @ w)

    def nll(self, x, y):
        """The negative log-likelihood of standardised features ``y`` (F,) at ``x`` (P,),
        less its constant."""
        w, log_s = self.whiten(y, x)
        return 0.5 * jnp.sum(w**2) + log_s


def make_flow(n_in: int, n_out: int, options: DensityOptions, key):
    """A flow over ``n_out`` features conditioned on ``n_in`` inputs that starts at the
    identity (each conditioner's last layer zeroed)."""
    flow = masked_autoregressive_flow(
        key,
        base_dist=Normal(jnp.zeros(n_out)),
        transformer=RationalQuadraticSpline(knots=options.knots, interval=options.interval),
        cond_dim=n_in,
        flow_layers=options.layers,
        nn_width=options.width,
        nn_depth=1,
    )

    def last(f):
        return f.bijection.bijection.bijection.bijections[0].masked_autoregressive_mlp.layers[-1]

    layer = last(flow)
    return eqx.tree_at(
        lambda f: (last(f).weight.args[1], last(f).bias),
        flow,
        (jnp.zeros_like(layer.weight.args[1]), jnp.zeros_like(layer.bias)),
    )


class FeatureDensity(eqx.Module):
    """The trained whitening and flow with their input and output standardisation.

    Every method takes a design point ``u`` (P,: the fit's full parameter vector in the unit
    box); :attr:`columns` are the parameter indices this recording reads. Features are in
    their own units; log densities include every stage's Jacobian.
    """

    whitening: Whitening
    flow: eqx.Module
    x_shift: jax.Array  # (P',)
    x_scale: jax.Array  # (P',)
    y_shift: jax.Array  # (F,)
    y_scale: jax.Array  # (F,)
    #: the variance (F,) added to the training features (module docstring)
    floor: jax.Array
    columns: tuple[int, ...] = eqx.field(static=True)

    def condition(self, u):
        return (u[..., jnp.asarray(self.columns)] - self.x_shift) / self.x_scale

    def whitened(self, y, u):
        """The whitening's output ``w`` (F,), the standardised input ``x`` and the log
        Jacobian of ``y → w``."""
        x = self.condition(u)
        w, log_s = self.whitening.whiten((y - self.y_shift) / self.y_scale, x)
        return w, x, -log_s - jnp.sum(jnp.log(self.y_scale))

    def residual_and_log_jacobian(self, y, u):
        """The whitened residual r (F,) of features ``y`` and the log Jacobian of ``y → r``,
        from one pass through both stages."""
        w, x, log_jac = self.whitened(y, u)
        r, log_det = self.flow.bijection.inverse_and_log_det(w, condition=x)
        return r, log_jac + log_det

    def log_prob(self, y, u):
        """log p(y | u) of features ``y`` (F,)."""
        r, log_jac = self.residual_and_log_jacobian(y, u)
        return self.flow.base_dist.log_prob(r) + log_jac

    def residual(self, y, u):
        """The whitened residual r (F,) of features ``y``: standard normal under the model."""
        return self.residual_and_log_jacobian(y, u)[0]

    def chi2_terms(self, y, u):
        """``|r|²`` and the rest of ``−2 log p(y | u) − F log 2π`` (the log-volume term,
        the Gaussian's ``log det C``)."""
        r, log_jac = self.residual_and_log_jacobian(y, u)
        chi2 = jnp.sum(r**2)
        log_p = self.flow.base_dist.log_prob(r) + log_jac
        return chi2, -2 * log_p - chi2 - r.shape[0] * math.log(2 * math.pi)

    def sample(self, key, u, n: int):
        """``n`` draws (n, F) of the features at ``u``."""
        x = self.condition(u)
        w = self.flow.sample(key, (n,), condition=x)
        ys = jax.vmap(lambda wi: self.whitening.colour(wi, x))(w)
        return self.y_shift + self.y_scale * ys

    def moments(self, u, n: int = 512, seed: int = 0):
        """The features' mean (F,) and covariance (F, F) at ``u`` from ``n`` draws (a fixed
        key: deterministic)."""
        draws = self.sample(jax.random.key(seed), u, n)
        mean = pairwise_mean(draws)
        centred = draws - mean
        return mean, pairwise_sum(centred[:, :, None] * centred[:, None, :]) / (n - 1)


def standardisation(x, y):
    """Shift and scale (each clipped below at 1e-6) of inputs ``x`` and features ``y``."""
    return (
        x.mean(axis=0),
        np.maximum(x.std(axis=0), 1e-6),
        y.mean(axis=0),
        np.maximum(y.std(axis=0), 1e-6),
    )


def fit_density(
    u,
    features,
    columns,
    options: DensityOptions,
    seed: np.random.SeedSequence,
    *,
    floor=None,
) -> tuple[FeatureDensity, float]:
    """Train a :class:`FeatureDensity` on single simulations: design points ``u`` (N, P full)
    and their features (N, F), with the variance ``floor`` (F,) added as noise (module
    docstring). Returns it and the flow's best validation loss (mean negative
    log-likelihood per simulation of the whitened features).

    Deterministic for a given ``seed``.
    """
    u = np.asarray(u, float)
    y = np.asarray(features, float)
    s_noise, s_whiten, s_flow, s_train = seed.spawn(4)
    floor = np.zeros(y.shape[1]) if floor is None else np.asarray(floor, float)
    y = y + np.sqrt(floor) * np.random.default_rng(s_noise).normal(size=y.shape)
    x = u[:, list(columns)]
    shifts = standardisation(x, y)
    xs = (x - shifts[0]) / shifts[1]
    ys = (y - shifts[2]) / shifts[3]
    whitening = train_whitening(xs, ys, options, key_of(s_whiten))
    w, _ = jax.vmap(whitening.whiten)(jnp.asarray(ys), jnp.asarray(xs))
    flow, losses = train_flow(
        make_flow(xs.shape[1], ys.shape[1], options, key_of(s_flow)),
        w,
        xs,
        np.random.default_rng(s_train),
        learning_rate=options.learning_rate,
        batch_size=options.batch_size,
        max_epochs=options.max_epochs,
        patience=options.patience,
        validation=options.validation,
    )
    density = FeatureDensity(
        whitening,
        flow,
        *(jnp.asarray(a) for a in shifts),
        jnp.asarray(floor),
        tuple(int(c) for c in columns),
    )
    return density, float(min(losses))


def train_whitening(xs, ys, options: DensityOptions, key) -> Whitening:
    """The :class:`Whitening` trained full-batch on standardised inputs ``xs`` (N, P) and
    features ``ys`` (N, F), in single precision (the data's own noise is far above its
    rounding), returned in double; the identity when ``options.whitening`` is off."""
    net = Whitening(xs.shape[1], ys.shape[1], options.whitening_width, options.whitening_depth, key)
    if not options.whitening:
        last = net.mlp.layers[-1]
        zero = (jnp.zeros_like(last.weight), jnp.zeros_like(last.bias))
        return eqx.tree_at(lambda n: (n.mlp.layers[-1].weight, n.mlp.layers[-1].bias), net, zero)
    net = cast(net, jnp.float32)
    net = whitening_steps(net, jnp.asarray(xs, jnp.float32), jnp.asarray(ys, jnp.float32), options)
    return cast(net, jnp.float64)


def cast(tree, dtype):
    return jax.tree_util.tree_map(lambda a: a.astype(dtype) if eqx.is_inexact_array(a) else a, tree)


@eqx.filter_jit
def whitening_steps(net: Whitening, xs, ys, options: DensityOptions) -> Whitening:
    """``options.whitening_steps`` full-batch AdamW steps on the whitening's likelihood."""
    schedule = optax.cosine_decay_schedule(
        options.whitening_rate, options.whitening_steps, alpha=1 / 30
    )
    opt = optax.adamw(schedule, weight_decay=options.weight_decay)
    params, static = eqx.partition(net, eqx.is_inexact_array)

    def step(carry, _):
        params, state = carry
        _, grads = mean_value_and_grad(
            lambda p, x, y: eqx.combine(p, static).nll(x, y), params, xs, ys
        )
        updates, state = opt.update(grads, state, params)
        return (optax.apply_updates(params, updates), state), None

    (params, _), _ = jax.lax.scan(step, (params, opt.init(params)), None, options.whitening_steps)
    return eqx.combine(params, static)


def key_of(seed: np.random.SeedSequence):
    """A JAX key from a seed sequence."""
    return jax.random.key(int(np.random.default_rng(seed).integers(2**31)))
