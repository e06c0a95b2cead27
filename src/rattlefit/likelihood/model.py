"""The learned likelihood of a fit: the recordings' features given the parameters.

For each recording the features are Gaussian with the mean and covariance its
:class:`~rattlefit.likelihood.emulator.FeatureEmulator` predicts at the parameters (the
chaotic spread plus the emulator's own error), plus an optional floor; recordings are
independent. The cost is
−2 log of the posterior density in the parameters' logs, less its constant: each recording's
``(y − m)ᵀ C⁻¹ (y − m) + log det C``, plus the squared prior rows of the parameters with a
log-normal prior (a log-uniform prior is flat in the log). It is smooth and deterministic, and
JAX differentiates it exactly.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp

from .emulator import FeatureEmulator


class LearnedLikelihood(eqx.Module):
    """The recordings' learned likelihood and the parameters' priors (a pytree).

    ``data`` (R, F): each recording's measured features; ``emulators``: one per recording;
    ``specs``: the fit's :class:`~rattlefit.inference.parameters.ParameterSpec` tuple, whose
    unconstrained coordinate ``z`` every method takes ((P,) arrays).
    """

    emulators: tuple[FeatureEmulator, ...]
    data: jax.Array
    specs: tuple = eqx.field(static=True)
    #: variance (F,) added to every recording's features: the floor of what any recording can
    #: be compared with, whatever the simulator's own spread (zeros: none)
    floor: jax.Array | None = None

    def log_values(self, z):
        """Each parameter's natural log value at ``z`` (P,)."""
        s = jax.nn.sigmoid(z)
        lower = jnp.asarray([math.log(p.lower) for p in self.specs])
        span = jnp.asarray([p.log_range for p in self.specs])
        return lower + span * s

    def moments(self, z):
        """Each recording's predicted feature mean (R, F) and covariance (R, F, F) at ``z``,
        the :attr:`floor` included."""
        u = jax.nn.sigmoid(z)
        pairs = [e.predict(u) for e in self.emulators]
        cov = jnp.stack([c for _, c in pairs])
        if self.floor is not None:
            cov = cov + jnp.diag(self.floor)[None]
        return jnp.stack([m for m, _ in pairs]), cov

    def chi2_terms(self, z):
        """Each recording's ``(y − m)ᵀ C⁻¹ (y − m)`` (R,) and ``log det C`` (R,) at ``z``."""
        mean, cov = self.moments(z)
        chol = jnp.linalg.cholesky(cov)
        w = jax.vmap(lambda c, r: jax.scipy.linalg.solve_triangular(c, r, lower=True))(
            chol, self.data - mean
        )
        logdet = 2 * jnp.sum(jnp.log(jnp.diagonal(chol, axis1=1, axis2=2)), axis=1)
        return jnp.sum(w**2, axis=1), logdet

    def prior_rows(self, z):
        """``(log v − log center)/log_sd`` of each parameter with a log-normal prior."""
        logv = self.log_values(z)
        rows = [
            (logv[i] - math.log(p.center)) / p.log_sd
            for i, p in enumerate(self.specs)
            if p.log_sd is not None
        ]
        return jnp.stack(rows) if rows else jnp.zeros((0,))

    def cost(self, z):
        """−2 log posterior density in the parameters' logs, less its constant."""
        chi2, logdet = self.chi2_terms(z)
        return jnp.sum(chi2 + logdet) + jnp.sum(self.prior_rows(z) ** 2)

    def chi2(self, z):
        """The recordings' summed ``(y − m)ᵀ C⁻¹ (y − m)`` at ``z``: χ² on R·F degrees of
        freedom where the model holds."""
        return jnp.sum(self.chi2_terms(z)[0])

    def log_density(self, z, tempering: float = 1.0):
        """Log posterior density in ``z`` itself (the coordinate map's Jacobian included),
        with the likelihood raised to ``tempering``; for samplers."""
        chi2, logdet = self.chi2_terms(z)
        s = jax.nn.sigmoid(z)
        jac = jnp.sum(jnp.log(s * (1 - s)))  # d log v / dz up to constant factors
        prior = -0.5 * jnp.sum(self.prior_rows(z) ** 2)
        return -0.5 * tempering * jnp.sum(chi2 + logdet) + prior + jac

    def with_floor(self, floor) -> LearnedLikelihood:
        """The same likelihood with the variance ``floor`` (F,) added to every recording's
        features."""
        return eqx.tree_at(
            lambda m: m.floor, self, jnp.asarray(floor, dtype=float), is_leaf=lambda x: x is None
        )

    def replace_data(self, data) -> LearnedLikelihood:
        """The same likelihood for other measured features ``data`` (R, F)."""
        return eqx.tree_at(lambda m: m.data, self, jnp.asarray(data))

    @property
    def n_features(self) -> int:
        return int(self.data.size)
