"""The learned likelihood of a fit: the recordings' features given the parameters.

Each recording's features have the density its
:class:`~rattlefit.likelihood.density.FeatureDensity` (a conditional flow) learned at the
parameters; recordings are independent. The cost is −2 log of the posterior density in the
parameters' logs, less its constant: each recording's ``|r|² + (the flow's log-volume term)``
(for a Gaussian, ``(y − m)ᵀ C⁻¹ (y − m) + log det C``), plus the squared prior rows of the
parameters with a log-normal prior (a log-uniform prior is flat in the log). It is smooth and
deterministic, and JAX differentiates it exactly.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp

from .density import FeatureDensity


class LearnedLikelihood(eqx.Module):
    """The recordings' learned likelihood and the parameters' priors (a pytree).

    ``data`` (R, F): each recording's measured features; ``densities``: one per recording;
    ``specs``: the fit's :class:`~rattlefit.problem.parameters.ParameterSpec` tuple, whose
    unconstrained coordinate ``z`` every method takes ((P,) arrays).
    """

    densities: tuple[FeatureDensity, ...]
    data: jax.Array
    specs: tuple = eqx.field(static=True)

    def log_values(self, z):
        """Each parameter's natural log value at ``z`` (P,)."""
        s = jax.nn.sigmoid(z)
        lower = jnp.asarray([math.log(p.lower) for p in self.specs])
        span = jnp.asarray([p.log_range for p in self.specs])
        return lower + span * s

    def moments(self, z):
        """Each recording's feature mean (R, F) and covariance (R, F, F) at ``z``, from the
        learned density's draws (deterministic)."""
        u = jax.nn.sigmoid(z)
        pairs = [d.moments(u) for d in self.densities]
        return jnp.stack([m for m, _ in pairs]), jnp.stack([c for _, c in pairs])

    def residuals(self, z):
        """Each recording's whitened residual (R, F) at ``z``: standard normal under the
        model."""
        u = jax.nn.sigmoid(z)
        return jnp.stack([d.residual(y, u) for d, y in zip(self.densities, self.data, strict=True)])

    @eqx.filter_jit
    def chi2_terms(self, z):
        """Each recording's ``|r|²`` (R,) and log-volume term (R,) at ``z``
        (:meth:`~rattlefit.likelihood.density.FeatureDensity.chi2_terms`)."""
        u = jax.nn.sigmoid(z)
        terms = [d.chi2_terms(y, u) for d, y in zip(self.densities, self.data, strict=True)]
        return jnp.stack([c for c, _ in terms]), jnp.stack([v for _, v in terms])

    def prior_rows(self, z):
        """``(log v − log center)/log_sd`` of each parameter with a log-normal prior."""
        logv = self.log_values(z)
        rows = [
            (logv[i] - math.log(p.center)) / p.log_sd
            for i, p in enumerate(self.specs)
            if p.log_sd is not None
        ]
        return jnp.stack(rows) if rows else jnp.zeros((0,))

    @eqx.filter_jit
    def cost(self, z):
        """−2 log posterior density in the parameters' logs, less its constant."""
        chi2, volume = self.chi2_terms(z)
        return jnp.sum(chi2 + volume) + jnp.sum(self.prior_rows(z) ** 2)

    @eqx.filter_jit
    def chi2(self, z):
        """The recordings' summed ``|r|²`` at ``z``: χ² on R·F degrees of freedom where the
        model holds."""
        return jnp.sum(self.chi2_terms(z)[0])

    @eqx.filter_jit
    def log_density(self, z, tempering: float = 1.0):
        """Log posterior density in ``z`` itself (the coordinate map's Jacobian included),
        with the likelihood raised to ``tempering``; for samplers."""
        chi2, volume = self.chi2_terms(z)
        s = jax.nn.sigmoid(z)
        jac = jnp.sum(jnp.log(s * (1 - s)))  # d log v / dz up to constant factors
        prior = -0.5 * jnp.sum(self.prior_rows(z) ** 2)
        return -0.5 * tempering * jnp.sum(chi2 + volume) + prior + jac

    def replace_data(self, data) -> LearnedLikelihood:
        """The same likelihood for other measured features ``data`` (R, F)."""
        return eqx.tree_at(lambda m: m.data, self, jnp.asarray(data))

    @property
    def n_features(self) -> int:
        return int(self.data.size)


# The methods above and these evaluations are compiled once per shape and reused by every
# likelihood of the same structure (the likelihood is an argument, not a constant of the
# program): a fit after fit in one process then compiles nothing new, where a program per
# likelihood would pile up compiled code until the process runs out of memory maps.


@eqx.filter_jit
def batch_cost(like: LearnedLikelihood, z):
    """:meth:`LearnedLikelihood.cost` at each row of ``z`` (K, P): (K,)."""
    return jax.vmap(like.cost)(z)


@eqx.filter_jit
def batch_log_density(like: LearnedLikelihood, z, tempering: float):
    """:meth:`LearnedLikelihood.log_density` at each row of ``z`` (K, P): (K,)."""
    return jax.vmap(lambda zz: like.log_density(zz, tempering))(z)


@eqx.filter_jit
def cost_hessian(like: LearnedLikelihood, z):
    """The Hessian (P, P) of :meth:`LearnedLikelihood.cost` at ``z`` (P,)."""
    return jax.hessian(like.cost)(z)


@eqx.filter_jit
def batch_chi2_terms(like: LearnedLikelihood, z):
    """:meth:`LearnedLikelihood.chi2_terms` at each row of ``z`` (K, P): two (K, R) arrays."""
    return jax.vmap(like.chi2_terms)(z)
