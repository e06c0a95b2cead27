"""The fit's starting points: seeded scrambled Sobol' sequences over the free parameters.

Rattle's cost has narrow basins where it locks into periodic orbits, so Levenberg–Marquardt
runs only from the best of many screened starts (:mod:`rattlefit.inference.least_squares`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import qmc

from ..problem.parameters import ParameterSpec
from ..problem.problem import Problem

#: Starting points for (a, T_b) when ``FitOptions.n_starts`` is None; twice as many for
#: each further film half-length (a fit across lubrications).
START_POINTS = 64
#: How far the nuisance starts spread each parameter with a prior, in its prior's standard
#: deviations (log): :func:`starting_points`.
START_NUISANCE_SDS = 1.0


def prior_centre(specs) -> np.ndarray:
    """z of every parameter's prior centre (0, the middle of the range, where it has none)."""
    return np.array([s.z_of(s.center) if s.center else 0.0 for s in specs])


def starting_points(
    problem: Problem, n_starts: int | None, rng, *, nuisance_starts: int | None = 0
) -> np.ndarray:
    """The fit's starting points (N, P), from seeded scrambled Sobol' sequences.

    First ``n_starts`` with each film half-length and the drag torque spread log-uniformly over
    their :attr:`~rattlefit.problem.parameters.ParameterSpec.start_range` and the other
    parameters at their prior medians; None gives
    :data:`START_POINTS` for (a, T_b), twice as many for each further film half-length (a fit
    across lubrications). Then ``nuisance_starts`` more (None: as many again) spread the same
    way, with each parameter that has a prior spread too, over its median × exp(±
    :data:`START_NUISANCE_SDS` log_sd) (:func:`nuisance_start_range`). The second set is drawn
    from a child of ``rng`` (:meth:`numpy.random.Generator.spawn`), which leaves ``rng``'s own
    stream as without it.
    """
    specs = problem.specs
    spread = [
        (i, s.start_range or (s.lower, s.upper))
        for i, s in enumerate(specs)
        if s.role == "physical"
    ]
    n = n_starts or START_POINTS * 2 ** (len(spread) - 2)
    starts = sobol_points(specs, spread, n, rng)
    m = n if nuisance_starts is None else nuisance_starts
    if m > 0:
        nuisances = [
            (i, nuisance_start_range(s, START_NUISANCE_SDS))
            for i, s in enumerate(specs)
            if s.nuisance
        ]
        (child,) = rng.spawn(1)
        starts = np.concatenate([starts, sobol_points(specs, spread + nuisances, m, child)])
    return starts


def sobol_points(specs, spread, n: int, rng) -> np.ndarray:
    """``n`` points (n, P) at the prior centres but for the parameters ``spread`` — (index,
    (low, high)) — each spread log-uniformly over its (low, high) by a seeded scrambled Sobol'
    sequence, in that order of dimensions."""
    starts = np.tile(prior_centre(specs), (n, 1))
    u = qmc.Sobol(d=len(spread), scramble=True, seed=rng).random_base2(math.ceil(math.log2(n)))
    for col, (i, (lo, hi)) in enumerate(spread):
        vals = np.exp(np.log(lo) + u[:n, col] * math.log(hi / lo))
        starts[:, i] = [specs[i].z_of(v) for v in vals]
    return starts


def nuisance_start_range(spec: ParameterSpec, sds: float) -> tuple[float, float]:
    """Where starts spread a parameter with a prior: its median × exp(± ``sds`` log_sd), kept
    5 % inside its range (a wide prior a caller set may reach past it)."""
    w = sds * spec.log_sd
    return (
        max(spec.center * math.exp(-w), spec.lower * math.exp(0.05)),
        min(spec.center * math.exp(w), spec.upper * math.exp(-0.05)),
    )
