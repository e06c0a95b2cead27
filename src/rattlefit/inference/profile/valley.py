"""The film's valley: profile guesses that trade a film half-length against the viscosity.

Under oil jet the squeeze force saturates in ``a`` near contact but not at larger gaps, so
``a`` trades against the viscosity along a curved valley of the cost, and where the
recording's regime is reached only in a narrow pocket the cost off it is in the thousands:
neither a profile scan's straight paths nor a continuation's secant stay in it. At a new
value of a film's ``a``, :func:`film_valley` guesses the viscosity that keeps the squeeze
coefficient unchanged at a few gaps near contact (:data:`VALLEY_GAPS`).
"""

from __future__ import annotations

import numpy as np

from ...physics.model import equivalent_viscosity
from ...problem.problem import Problem
from ...quantities import MIN_FILM, VISCOSITY_SCALE
from .curves import Valley

#: The gaps, in multiples of ``h_min``, at which :func:`film_valley` keeps the squeeze
#: coefficient while a film half-length moves along its profile (one guess each). Which gap
#: the data pin moves with the other parameters, so a few are tried, about a factor 1.5 apart.
VALLEY_GAPS = (2.0, 3.0, 4.5, 7.0)


def film_valley(problem: Problem) -> Valley | None:
    """The :data:`~rattlefit.inference.profile.Valley` of the film half-lengths: at a new value of a
    film's ``a``, the viscosity factor that keeps the squeeze coefficient unchanged at each
    gap of :data:`VALLEY_GAPS` × ``h_min`` (:func:`~rattlefit.physics.model.equivalent_viscosity`,
    with the curvature radius of that film's first recording), where it stays inside its
    range. Other parameters get no guesses."""
    specs = problem.specs
    names = [s.name for s in specs]
    if VISCOSITY_SCALE not in names or MIN_FILM not in names:
        return None
    i_mu, i_h = names.index(VISCOSITY_SCALE), names.index(MIN_FILM)
    radii = np.asarray(problem.models.curvature_radius).reshape(-1)
    radius = {name: float(radii[problem.films.index(name)]) for name in set(problem.films)}
    mu_spec = specs[i_mu]

    def valley(i: int, near, t: float) -> list[np.ndarray]:
        spec = specs[i]
        if spec.name not in radius:
            return []
        a, a_new = float(spec.value(near[i])), float(spec.value(t))
        mu, h_min = float(mu_spec.value(near[i_mu])), float(specs[i_h].value(near[i_h]))
        points = []
        for factor in VALLEY_GAPS:
            mu_new = float(equivalent_viscosity(factor * h_min, a, mu, a_new, radius[spec.name]))
            if mu_spec.lower < mu_new < mu_spec.upper:
                point = np.array(near, dtype=float)
                point[i], point[i_mu] = t, mu_spec.z_of(mu_new)
                points.append(point)
        return points

    return valley
