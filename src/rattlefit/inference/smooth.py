"""Estimates on a smooth, deterministic likelihood: the optimum, profile intervals and the
Laplace covariance (the synthetic likelihood's noisy cost has its own stack:
:mod:`~rattlefit.inference.least_squares`, :mod:`~rattlefit.inference.laplace`,
:mod:`~rattlefit.inference.profile`).

The learned cost (:class:`~rattlefit.likelihood.model.LearnedLikelihood`) is smooth and
deterministic and JAX differentiates it exactly, so the optimum is found by quasi-Newton
minimisation (optimistix's BFGS) and a parameter's 95 % interval is where its profile (the
cost with the parameter held and the others re-minimised) stays within χ²₁'s 95 % quantile
of the optimum's cost: no allowance for Monte Carlo noise is needed, because the cost has
none. The learned density's own error is measured by :mod:`rattlefit.likelihood.check`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from scipy import stats

from ..confidence import CHI2_1_95 as CHI2_95
from ..likelihood.design import EDGE
from ..likelihood.model import LearnedLikelihood, cost_hessian
from ..physics.model import squeeze_momentum

#: A profile point this far below the optimum's cost means the optimum was not the least:
#: the fit starts again from it.
BELOW_TOLERANCE = 1e-3


@eqx.filter_jit
def minimise(like: LearnedLikelihood, z0, index, value, max_steps: int = 400):
    """The least cost from ``z0`` with parameter ``index`` held at ``value`` (in ``z``;
    ``index`` −1 holds none): returns ``(z, cost, converged, steps)``."""
    hold = jnp.arange(z0.shape[0]) == index  # index and value are traced: one program

    def cost(z, _):
        return like.cost(jnp.where(hold, value, z))

    solver = optx.BFGS(rtol=1e-8, atol=1e-8)
    sol = optx.minimise(cost, solver, z0, max_steps=max_steps, throw=False)
    z = jnp.where(hold, value, sol.value)
    return z, cost(z, None), sol.result == optx.RESULTS.successful, sol.stats["num_steps"]


@dataclasses.dataclass(frozen=True)
class Optimum:
    """The least learned cost found: ``z`` (P,), ``cost``, whether its minimisation converged,
    and the quasi-Newton steps over all starts."""

    z: np.ndarray
    cost: float
    converged: bool
    steps: int


def optimum(like: LearnedLikelihood, starts) -> Optimum:
    """The least cost over minimisations from each of ``starts`` (K, P) in ``z``."""
    best, steps = None, 0
    for z0 in np.atleast_2d(starts):
        z, c, ok, n = minimise(
            like, jnp.asarray(z0, dtype=float), jnp.asarray(-1), jnp.asarray(0.0)
        )
        steps += int(n)
        if np.isfinite(float(c)) and (best is None or float(c) < best.cost):
            best = Optimum(np.asarray(z), float(c), bool(ok), 0)
    return dataclasses.replace(best, steps=steps)


@dataclasses.dataclass(frozen=True)
class Profile:
    """One parameter's profile: values in ``z`` (K,) in increasing order, the cost above the
    optimum's at each (K,), the optimum's ``z`` at each (K, P), and the 95 % interval's ends
    in ``z`` (a range end where the profile stays inside up to it)."""

    index: int
    z: np.ndarray
    delta: np.ndarray
    points: np.ndarray
    lower: float
    upper: float


def walk(like, opt: Optimum, index: int, direction: int, step: float, threshold: float):
    """Profile points from the optimum outwards in ``direction`` (±1) in steps of ``step``
    in the parameter's log (growing while far inside the threshold), until the cost is
    ``threshold`` + 2 above the optimum's or the range ends: a list of (z_i, Δ, z)."""
    spec = like.specs[index]
    u = float(jax.nn.sigmoid(opt.z[index]))
    z_prev = jnp.asarray(opt.z)
    out = []
    du = step / spec.log_range
    while True:
        u = min(max(u + direction * du, EDGE), 1 - EDGE)
        zi = math.log(u / (1 - u))
        z, c, _, _ = minimise(like, z_prev, jnp.asarray(index), jnp.asarray(zi))
        delta = float(c) - opt.cost
        out.append((zi, delta, np.asarray(z)))
        if delta > threshold + 2 or u in (EDGE, 1 - EDGE) or not np.isfinite(delta):
            return out
        z_prev = z
        if delta < 0.25 * threshold:
            du = min(1.5 * du, 0.5 / spec.log_range)


def crossing(z0, d0, z1, d1, threshold: float) -> float:
    """Where the profile crosses ``threshold`` between two points (linear in Δ)."""
    if d1 == d0:
        return z1
    return z0 + (threshold - d0) * (z1 - z0) / (d1 - d0)


def profile(
    like: LearnedLikelihood,
    opt: Optimum,
    index: int,
    *,
    threshold: float = CHI2_95,
    step: float = 0.05,
) -> Profile:
    """The profile of parameter ``index`` around the optimum ``opt`` and its interval."""
    down = walk(like, opt, index, -1, step, threshold)[::-1]
    up = walk(like, opt, index, +1, step, threshold)
    pts = [*down, (float(opt.z[index]), 0.0, opt.z), *up]
    return interval_of(index, pts, len(down), threshold)


def interval_of(index: int, pts, k0: int, threshold: float) -> Profile:
    """The :class:`Profile` of points ``pts`` ((value, Δ, z), increasing, the optimum at
    ``k0``): the interval's ends where Δ crosses ``threshold`` (linear in Δ), or the last
    points where it does not."""
    zs = np.array([p[0] for p in pts])
    delta = np.array([p[1] for p in pts])
    lower, upper = zs[0], zs[-1]
    for k in range(k0, 0, -1):
        if delta[k - 1] > threshold:
            lower = crossing(zs[k], delta[k], zs[k - 1], delta[k - 1], threshold)
            break
    for k in range(k0, len(zs) - 1):
        if delta[k + 1] > threshold:
            upper = crossing(zs[k], delta[k], zs[k + 1], delta[k + 1], threshold)
            break
    return Profile(index, zs, delta, np.stack([p[2] for p in pts]), float(lower), float(upper))


#: The Laplace covariance's largest sd in ``z``: a direction the cost barely curves (a film
#: half-length on dry flanks, a parameter at a range's end) gets this, not an unbounded one.
MAX_SD_Z = 4.0


def laplace_covariance(like: LearnedLikelihood, z) -> np.ndarray:
    """The Laplace covariance in ``z`` (P, P): the inverse of half the cost's Hessian (the
    cost is −2 log density), each eigenvalue floored at 1/:data:`MAX_SD_Z`² so that it is
    positive definite where the cost is flat or not convex."""
    h = np.asarray(cost_hessian(like, jnp.asarray(z)))
    info = 0.25 * (h + h.T)
    w, v = np.linalg.eigh(info)
    w = np.maximum(w, 1.0 / MAX_SD_Z**2)
    return (v / w) @ v.T


class LogMomentum(eqx.Module):
    """The log of a film's squeeze momentum (N s,
    :func:`~rattlefit.physics.model.squeeze_momentum`) as a function of ``z``: the film's,
    the viscosity factor's and ``h_min``'s indices, the catalogue viscosity (Pa s), the
    curvature radius and axial width (m) of the flanks it is stated on, and the specs."""

    film: int
    viscosity: int
    min_film: int
    mu: float
    radius: float
    width: float
    specs: tuple = eqx.field(static=True)

    def __call__(self, z):
        value = [s.value(z[i]) for i, s in enumerate(self.specs)]
        momentum = squeeze_momentum(
            value[self.film],
            value[self.viscosity] * self.mu,
            value[self.min_film],
            self.radius,
            self.width,
        )
        return jnp.log(momentum)


#: Weight of the penalty that holds a derived quantity at its profile value: its log is
#: held to about 1/√weight = 0.01.
PENALTY = 1e4
#: A profile point of a derived quantity whose log missed its value by more than this has
#: reached the end of what the parameters' ranges allow.
MISSED_VALUE = 0.05


@eqx.filter_jit
def minimise_held(like: LearnedLikelihood, g, z0, target, max_steps: int = 600):
    """The least cost from ``z0`` with the derived quantity ``g(z)`` held near ``target``
    by a quadratic penalty (:data:`PENALTY`): returns ``(z, cost without the penalty,
    g(z))``."""

    def cost(z, _):
        return like.cost(z) + PENALTY * (g(z) - target) ** 2

    solver = optx.BFGS(rtol=1e-8, atol=1e-8)
    sol = optx.minimise(cost, solver, z0, max_steps=max_steps, throw=False)
    return sol.value, like.cost(sol.value), g(sol.value)


def walk_derived(like, g, opt: Optimum, direction: int, step: float, threshold: float):
    """Profile points of ``g`` from the optimum outwards in ``direction`` (±1), ``step``
    apart in its log (growing while far inside the threshold), until the cost is
    ``threshold`` + 2 above the optimum's or ``g`` cannot be held at its value: a list of
    (value, Δ, z)."""
    value = float(g(jnp.asarray(opt.z)))
    z_prev, out = jnp.asarray(opt.z), []
    while True:
        value += direction * step
        z, c, reached = minimise_held(like, g, z_prev, jnp.asarray(value))
        if abs(float(reached) - value) > MISSED_VALUE or not np.isfinite(float(c)):
            return out
        delta = float(c) - opt.cost
        out.append((value, delta, np.asarray(z)))
        if delta > threshold + 2 or len(out) > 60:
            return out
        z_prev = z
        if delta < 0.25 * threshold:
            step *= 1.5


def profile_derived(
    like: LearnedLikelihood, g, opt: Optimum, *, threshold: float = CHI2_95, step: float = 0.1
) -> Profile:
    """The profile of the derived quantity ``g`` (a function of ``z``, e.g.
    :class:`LogMomentum`) around ``opt``: its values (in ``g``'s units) in increasing order,
    each held by a penalty while the parameters are re-minimised. ``index`` is −1; an end
    where ``g`` cannot go further (a range's end) stays the last value held."""
    down = walk_derived(like, g, opt, -1, step, threshold)[::-1]
    up = walk_derived(like, g, opt, +1, step, threshold)
    pts = [*down, (float(g(jnp.asarray(opt.z))), 0.0, opt.z), *up]
    return interval_of(-1, pts, len(down), threshold)


@dataclasses.dataclass(frozen=True)
class LearnedFit:
    """The fit on the learned likelihood: the optimum, its χ² and degrees of freedom, the
    profiles of the parameters asked for, the Laplace covariance in ``z``, and the re-starts
    the profiles caused (a point below the optimum's cost moves the optimum there)."""

    optimum: Optimum
    chi2: float
    dof: int
    profiles: dict[int, Profile]
    covariance_z: np.ndarray
    restarts: int

    @property
    def p_value(self) -> float:
        return float(stats.chi2.sf(self.chi2, max(self.dof, 1)))


def fit_learned(
    like: LearnedLikelihood,
    starts,
    profiled,
    *,
    threshold: float | Mapping[int, float] = CHI2_95,
    max_restarts: int = 3,
) -> LearnedFit:
    """Minimise from ``starts`` (K, P in ``z``) and profile each parameter index in
    ``profiled``, its interval cut at ``threshold`` (one for all, or per index; an index
    missing from the mapping gets χ²₁'s 3.84); a profile point below the optimum's cost
    starts the search again there (at most ``max_restarts`` times)."""
    cut = threshold if isinstance(threshold, Mapping) else {}
    default = CHI2_95 if isinstance(threshold, Mapping) else threshold
    opt = optimum(like, starts)
    restarts = 0
    while True:
        profiles = {i: profile(like, opt, i, threshold=cut.get(i, default)) for i in profiled}
        lowest = min(
            ((float(p.delta.min()), p) for p in profiles.values()),
            key=lambda t: t[0],
            default=(0.0, None),
        )
        if lowest[0] > -BELOW_TOLERANCE or restarts >= max_restarts:
            break
        p = lowest[1]
        opt = optimum(like, p.points[int(np.argmin(p.delta))][None])
        restarts += 1
    n_free = sum(1 for s in like.specs if s.log_sd is None)
    return LearnedFit(
        opt,
        float(like.chi2(jnp.asarray(opt.z))),
        max(like.n_features - n_free, 1),
        profiles,
        laplace_covariance(like, opt.z),
        restarts,
    )
