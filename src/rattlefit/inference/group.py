"""The squeeze-film group: what a boundary recording pins of the oil film.

The spectrum sees how much momentum the squeeze film takes from each approach of the flanks,
``M = ∫_{h_min}^∞ S(h) dh`` (N s, the squeeze force's impulse, whatever the approach speed;
:func:`~rattlefit.physics.model.squeeze_momentum`), far better than ``a``, the viscosity or
``h_min`` apart. For a short film M = 4 μ Z a³/h_min², the group μ a³/h_min²; for a long
one, saturated in ``a``, it is ``3π μ Z R^{3/2}/√h_min``, and the fit's valley of long films
with lower viscosities keeps it too. :func:`group_estimates` profiles ``M`` itself, so that a
user who knows ``h_min`` and μ better than the priors can convert it to ``a``
(:func:`~rattlefit.physics.model.film_for_squeeze_momentum`) without refitting.

The profile runs in a copy of the fit's problem whose film coordinate is ``M``
(:func:`group_problem`): ``a`` follows from ``M``, the viscosity factor and ``h_min``
(:meth:`~rattlefit.problem.problem.Problem.film_of_group`) and is then dithered by the
film's own column, so every point simulates exactly the realisations of the same point in
``a``. The noise model, the release states and the profile method
(:func:`~rattlefit.inference.profile.profile_stage`) are the fit's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ..physics.model import DEFAULT_MIN_FILM, film_saturation, squeeze_momentum
from ..problem.options import FitOptions
from ..problem.parameters import ParameterSpec, momentum_name
from ..problem.problem import Problem
from ..quantities import MIN_FILM, VISCOSITY_SCALE
from .laplace import Laplace
from .profile import profile_interval, profile_stage
from .result import ParameterEstimate, estimate

#: The group's finite-difference step in log: three times the film's (M ∝ a³ for a short
#: film).
GROUP_FD_LOG_STEP = 0.6


def flanks(problem: Problem, film: str) -> tuple[float, float, float]:
    """The catalogue viscosity (Pa s), curvature radius R and axial width Z (m) of ``film``'s
    first recording: the flanks its squeeze momentum is stated on."""
    r = problem.films.index(film)
    return (
        float(np.asarray(problem.viscosities)[r]),
        float(np.asarray(problem.models.curvature_radius)[r]),
        float(np.asarray(problem.models.axial_width)[r]),
    )


def group_spec(problem: Problem, film: str) -> ParameterSpec:
    """The squeeze momentum's :class:`ParameterSpec` for ``film`` (N s): the film's range
    carried over at the viscosity factor's and ``h_min``'s prior medians."""
    specs = {s.name: s for s in problem.specs}
    a, h = specs[film], specs[MIN_FILM]
    mu, radius, width = flanks(problem, film)
    mu *= specs[VISCOSITY_SCALE].center or 1.0
    h_c = h.center or DEFAULT_MIN_FILM
    return ParameterSpec(
        momentum_name(film),
        "N s",
        float(squeeze_momentum(a.lower, mu, h_c, radius, width)),
        float(squeeze_momentum(a.upper, mu, h_c, radius, width)),
        fd_log_step=GROUP_FD_LOG_STEP,
        role="group",
        dither=a.dither,
    )


def group_problem(problem: Problem, film: str) -> tuple[Problem, int]:
    """``problem`` with ``film``'s coordinate replaced by its squeeze momentum
    (:func:`group_spec`; its dither column stays the film's); and the coordinate's index."""
    i = problem.index(film)
    specs = list(problem.specs)
    specs[i] = group_spec(problem, film)
    return dataclasses.replace(problem, specs=tuple(specs)), i


def group_value(problem: Problem, z, film: str) -> float:
    """The squeeze momentum M (N s) of ``film`` at ``z`` of ``problem`` (whose coordinates
    hold ``film``)."""
    v = {s.name: float(s.value(z[i])) for i, s in enumerate(problem.specs)}
    mu, radius, width = flanks(problem, film)
    return float(squeeze_momentum(v[film], v[VISCOSITY_SCALE] * mu, v[MIN_FILM], radius, width))


def log_slopes(problem: Problem, z, film: str) -> dict[str, float]:
    """∂ ln M/∂ ln p at ``z`` for p the film, the viscosity factor and ``h_min``: with
    k = y ψ'(y)/ψ(y) = 2y³/((1 + y²)² ψ), y = a/√(R h_min), they are k, 1 and −(1 + k)/2
    (3, 1, −2 for a short film)."""
    v = {s.name: float(s.value(z[i])) for i, s in enumerate(problem.specs)}
    _, radius, _ = flanks(problem, film)
    y = v[film] / math.sqrt(radius * v[MIN_FILM])
    k = 2.0 * y**3 / ((1.0 + y * y) ** 2 * float(film_saturation(y))) if y > 1e-3 else 3.0
    return {film: k, VISCOSITY_SCALE: 1.0, MIN_FILM: -0.5 * (1.0 + k)}


def to_group(problem: Problem, grouped: Problem, i: int, z, cov) -> tuple[np.ndarray, np.ndarray]:
    """``z`` and its covariance ``cov`` in the coordinates of ``grouped``
    (:func:`group_problem`, coordinate ``i``): z's ``i``-th entry becomes the group's, and
    the covariance is carried by the Jacobian of that change (:func:`log_slopes`)."""
    specs = problem.specs
    film = specs[i].name
    g_spec = grouped.specs[i]
    z_g = np.array(z, dtype=float)
    z_g[i] = g_spec.z_of(group_value(problem, z, film))
    jac = np.eye(len(z))
    dz = max(float(g_spec.dlog_dz(z_g[i])), 1e-300)
    for name, slope in log_slopes(problem, z, film).items():
        j = problem.index(name)
        jac[i, j] = slope * float(specs[j].dlog_dz(z[j])) / dz
    return z_g, jac @ cov @ jac.T


def group_films(problem: Problem, lubrications: Sequence[str]) -> list[str]:
    """The films whose squeeze-film group a fit reports: those of boundary recordings."""
    return list(
        dict.fromkeys(
            f for f, lub in zip(problem.films, lubrications, strict=True) if lub == "boundary"
        )
    )


def group_estimates(
    lap: Laplace,
    z,
    y0,
    lubrications: Sequence[str],
    options: FitOptions,
    *,
    dof_rec: float,
    rng,
    say,
) -> dict[str, ParameterEstimate]:
    """The squeeze-film group of each boundary film (:func:`group_films`), profiled about the
    optimum ``z`` of the Laplace stage ``lap`` in the fit's own way: ``{name: estimate}``
    (e.g. ``squeeze_momentum``), the estimate M at ``z``."""
    out = {}
    for film in group_films(lap.problem, lubrications):
        grouped, i = group_problem(lap.problem, film)
        z_g, cov_g = to_group(lap.problem, grouped, i, z, lap.covariance)
        say(f"profiling the squeeze momentum of {film} …")
        stage = profile_stage(
            dataclasses.replace(lap, problem=grouped, covariance=cov_g),
            z_g,
            [z_g],
            y0,
            options,
            valley=None,
            dof_rec=dof_rec,
            rng=rng,
            say=say,
            only=(i,),
        )
        (lo, hi), _ = profile_interval(stage.profiles[i], stage.threshold)
        spec = grouped.specs[i]
        out[spec.name] = g = estimate(spec, z_g[i], lo, hi)
        say(
            f"  {spec.name} = {g.estimate:.3g} N s (95 %: {g.lower:.3g}–{g.upper:.3g}, "
            f"a factor of {g.upper / g.lower if g.lower > 0 else math.inf:.2g})"
        )
    return out
