"""Critical values of the profile-likelihood ratio by simulation: the learned likelihood's
95 % intervals by a local Neyman construction.

χ²₁'s 3.84 is the right threshold for a profile only where the likelihood is exact. A learned
density is not: where rattle is nearly deterministic it can be narrower than the simulator's
spread, or its mean off by about that spread, and intervals cut at 3.84 then hold their truth
less often than 95 %. Here the threshold is measured instead of assumed:

1. parameters ``θ_m`` are drawn around the fit's optimum, from its Laplace Gaussian in the
   fit's coordinate ``z`` with the sd widened by :data:`WIDEN` (a neighbourhood wider than the
   intervals it calibrates);
2. at each, every recording is simulated once, with the density's variance floor as noise,
   as the likelihood's own training simulations are
   (:func:`~rattlefit.likelihood.check.simulations_with_floor`);
3. on each simulated data set the learned likelihood gives the profile-likelihood-ratio
   statistic of each profiled quantity at its true value,
   ``λ = (least cost with the quantity held at its truth) − (least cost)``;
4. a quantity's critical value is the ``⌈0.95 (n + 1)⌉``-th smallest of its ``n`` statistics,
   never below χ²₁'s 3.84.

Its interval, where the profile stays within the critical value of the optimum's cost, then
holds the truth in at least 95 % of the recordings simulated near the fit, whatever the
density's error there, up to the quantile's own sampling error: a density that is too narrow
widens the interval instead of breaking its coverage. This is the Neyman inversion of LF2I
(Dalmasso, Masserano, Zhao, Izbicki & Lee) with the critical value held constant over the
fit's neighbourhood instead of regressed on θ, and the coverage it buys is for recordings the
simulator could have made: a model-form difference is not in it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..confidence import CHI2_1_95
from ..likelihood.check import simulations_with_floor
from ..likelihood.design import EDGE, unit_of_z
from ..likelihood.model import LearnedLikelihood
from ..problem.problem import Problem
from .smooth import LearnedFit, minimise_held

#: The draws' sd over the Laplace sd: the neighbourhood calibrated reaches beyond the
#: intervals it calibrates.
WIDEN = 1.5
#: The coverage the critical values are set for.
LEVEL = 0.95
#: The fit's coordinate is kept this far inside the unit box's ends (as the design is).
Z_LIMIT = math.log((1 - EDGE) / EDGE)


@dataclasses.dataclass(frozen=True)
class CriticalValues:
    """The critical values of a fit: ``values`` (quantity → Δcost; a parameter's index or a
    derived quantity's name), each quantity's ``statistics`` (n,), the draws ``z`` (n, P),
    and the ``level``. A quantity whose statistics were all non-finite keeps χ²₁'s 3.84."""

    values: dict
    statistics: dict
    z: np.ndarray
    level: float = LEVEL

    @property
    def simulations(self) -> int:
        return int(self.z.shape[0])

    def as_dict(self, names: Mapping) -> dict:
        """The JSON record: each quantity by ``names[key]``, its critical value and the share
        of its statistics at or below χ²₁'s 3.84 (the coverage the χ²₁ threshold would
        give)."""
        return {
            "level": self.level,
            "simulations": self.simulations,
            "widen": WIDEN,
            "critical_values": {names[k]: float(v) for k, v in self.values.items()},
            "chi2_1_coverage": {
                names[k]: float(np.mean(s <= CHI2_1_95)) for k, s in self.statistics.items()
            },
        }


def draws(fit: LearnedFit, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` points (n, P) in ``z`` around ``fit``'s optimum: its Laplace Gaussian with the sd
    widened by :data:`WIDEN`, kept inside the unit box's margin."""
    cov = WIDEN**2 * np.asarray(fit.covariance_z)
    z = rng.multivariate_normal(np.asarray(fit.optimum.z), cov, size=n, method="eigh")
    return np.clip(z, -Z_LIMIT, Z_LIMIT)


def simulated_data(problem: Problem, like: LearnedLikelihood, z, seed) -> np.ndarray:
    """One simulated data set (n, R, F) per point of ``z`` (n, P), every recording simulated
    with its density's floor as noise."""
    u = unit_of_z(z)
    seeds = seed.spawn(problem.n_rec)
    per = [simulations_with_floor(problem, like, u, r, seeds[r]) for r in range(problem.n_rec)]
    return np.stack(per, axis=1)


#: The statistics' quasi-Newton tolerance: a cost difference to about 10⁻³, far below the
#: spread of the statistics it sets a quantile of.
TOLERANCE = 1e-6


@eqx.filter_jit
def least_cost(like: LearnedLikelihood, z0, index, value):
    """The least cost from ``z0`` (P,) with parameter ``index`` held at ``value`` (``index``
    −1 holds none), to :data:`TOLERANCE`."""
    hold = jnp.arange(z0.shape[0]) == index

    def cost(z, _):
        return like.cost(jnp.where(hold, value, z))

    solver = optx.BFGS(rtol=TOLERANCE, atol=TOLERANCE)
    sol = optx.minimise(cost, solver, z0, max_steps=400, throw=False)
    return cost(sol.value, None)


def draw_statistics(like: LearnedLikelihood, optimum_z, data, z, profiled, derived) -> dict:
    """The profile-likelihood ratio at the truth ``z`` (P,) of each quantity on one data set
    ``data`` (R, F): the parameters ``profiled`` (indices) and the ``derived`` quantities
    (name → function of ``z``). The least cost is the lower of the searches from the truth
    and from the fit's optimum ``optimum_z``."""
    one = like.replace_data(jnp.asarray(data))
    z = jnp.asarray(z)
    none = (jnp.asarray(-1), jnp.asarray(0.0))
    best = min(float(least_cost(one, z, *none)), float(least_cost(one, optimum_z, *none)))
    out = {i: float(least_cost(one, z, jnp.asarray(i), z[i])) - best for i in profiled}
    for name, g in derived.items():
        out[name] = float(minimise_held(one, g, z, g(z))[1]) - best
    return {k: max(v, 0.0) for k, v in out.items()}


def ratio_statistics(like: LearnedLikelihood, fit: LearnedFit, data, z, profiled, derived):
    """:func:`draw_statistics` of every data set ``data`` (n, R, F) at its truth ``z``
    (n, P), on as many threads as JAX has devices (each data set's statistics are the same on
    any thread): each quantity's statistics (n,)."""
    optimum_z = jnp.asarray(fit.optimum.z)

    def one(m):
        return draw_statistics(like, optimum_z, data[m], z[m], profiled, derived)

    with ThreadPoolExecutor(max(len(jax.local_devices()), 1)) as pool:
        rows = list(pool.map(one, range(len(z))))
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def critical_value(statistics, level: float = LEVEL) -> float:
    """The ``⌈level (n + 1)⌉``-th smallest finite statistic (the largest when there are too
    few), never below χ²₁'s 3.84; 3.84 when none is finite."""
    s = np.sort(np.asarray(statistics, float)[np.isfinite(statistics)])
    if s.size == 0:
        return CHI2_1_95
    k = min(math.ceil(level * (s.size + 1)), s.size)
    return max(float(s[k - 1]), CHI2_1_95)


def critical_values(
    problem: Problem,
    like: LearnedLikelihood,
    fit: LearnedFit,
    *,
    n: int,
    seed: np.random.SeedSequence,
    derived: Mapping | None = None,
) -> CriticalValues:
    """The critical values (module docstring) of every parameter ``fit`` profiles and of each
    ``derived`` quantity (name → function of ``z``), from ``n`` simulated data sets drawn
    from ``seed``."""
    s_draw, s_sim = seed.spawn(2)
    z = draws(fit, n, np.random.default_rng(s_draw))
    data = simulated_data(problem, like, z, s_sim)
    stats = ratio_statistics(like, fit, data, z, list(fit.profiles), dict(derived or {}))
    return CriticalValues({k: critical_value(s) for k, s in stats.items()}, stats, z)
