"""The squeeze-film group: what a boundary recording pins of the oil film.

Near contact the squeeze force of eq. (6) scales as μ a³/h², and in boundary lubrication the
flanks rattle close enough that the recording pins the group ``G = μ a³/h_min²`` (Pa s m, μ
the viscosity at the recording's temperature) far better than ``a``, the viscosity or
``h_min`` apart: ``a`` is known only as well as ``h_min`` is (a ∝ h_min^(2/3) at fixed G).
:func:`group_estimates` profiles ``G`` itself, so that a user who knows ``h_min`` and μ
better than the priors can convert it, ``a = (G h_min²/μ)^(1/3)``, without refitting.

The profile runs in a copy of the fit's problem whose film coordinate is ``G``
(:func:`group_problem`): ``a`` follows from ``G``, the viscosity factor and ``h_min``
(:meth:`~rattlefit.inference.problem.Problem.params_for`), and each realisation's dither of
``G`` is 3× that of ``a`` plus the viscosity's, so every point simulates exactly the
realisations of the same point in ``a``. The noise model, the release states and the
profile method (:func:`~rattlefit.inference.profile.profile_stage`) are the fit's.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ..physics.model import DEFAULT_MIN_FILM
from .laplace import Laplace
from .options import FitOptions
from .parameters import ParameterSpec, group_name
from .problem import Problem
from .profile import profile_interval, profile_stage
from .result import ParameterEstimate, estimate

#: The group's finite-difference step in log: three times the film's (G ∝ a³).
GROUP_FD_LOG_STEP = 0.6


def group_spec(problem: Problem, film: str) -> ParameterSpec:
    """The squeeze-film group's :class:`ParameterSpec` for ``film``: the film's range carried
    over at the viscosity factor's and ``h_min``'s prior medians (unit Pa s m)."""
    specs = {s.name: s for s in problem.specs}
    a, h = specs[film], specs["min_film"]
    mu = float(np.asarray(problem.viscosities)[problem.films.index(film)])
    mu *= specs["viscosity_scale"].center or 1.0
    h_c = h.center or DEFAULT_MIN_FILM
    return ParameterSpec(
        group_name(film),
        "Pa s m",
        mu * a.lower**3 / h_c**2,
        mu * a.upper**3 / h_c**2,
        fd_log_step=GROUP_FD_LOG_STEP,
    )


def group_problem(problem: Problem, film: str) -> tuple[Problem, int]:
    """``problem`` with ``film``'s coordinate replaced by its squeeze-film group
    (:func:`group_spec`), the group's dither column 3× the film's plus the viscosity's; and
    the coordinate's index."""
    names = [s.name for s in problem.specs]
    i, i_mu = names.index(film), names.index("viscosity_scale")
    specs = list(problem.specs)
    specs[i] = group_spec(problem, film)
    dither = np.array(problem.dither)
    dither[:, i] = 3.0 * dither[:, i] + dither[:, i_mu]
    return dataclasses.replace(problem, specs=tuple(specs), dither=dither), i


def group_value(problem: Problem, z, film: str) -> float:
    """G = μ a³/h_min² (Pa s m) at ``z`` of ``problem`` (whose coordinates hold ``film``)."""
    v = {s.name: float(s.value(z[i])) for i, s in enumerate(problem.specs)}
    mu = v["viscosity_scale"] * float(np.asarray(problem.viscosities)[problem.films.index(film)])
    return mu * v[film] ** 3 / v["min_film"] ** 2


def to_group(problem: Problem, grouped: Problem, i: int, z, cov) -> tuple[np.ndarray, np.ndarray]:
    """``z`` and its covariance ``cov`` in the coordinates of ``grouped``
    (:func:`group_problem`, coordinate ``i``): z's ``i``-th entry becomes the group's, and
    the covariance is carried by the Jacobian of that change (d log G = 3 d log a + d log μ
    − 2 d log h_min)."""
    specs = problem.specs
    names = [s.name for s in specs]
    film = specs[i].name
    g_spec = grouped.specs[i]
    z_g = np.array(z, dtype=float)
    z_g[i] = g_spec.z_of(group_value(problem, z, film))
    jac = np.eye(len(z))
    dz = float(g_spec.dlog_dz(z_g[i]))
    for name, power in ((film, 3.0), ("viscosity_scale", 1.0), ("min_film", -2.0)):
        j = names.index(name)
        jac[i, j] = power * float(specs[j].dlog_dz(z[j])) / max(dz, 1e-300)
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
    (e.g. ``squeeze_film_group``), the estimate G at ``z``."""
    out = {}
    for film in group_films(lap.problem, lubrications):
        grouped, i = group_problem(lap.problem, film)
        z_g, cov_g = to_group(lap.problem, grouped, i, z, lap.covariance)
        say(f"profiling the squeeze-film group μ·{film}³/h_min² …")
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
            f"  {spec.name} = {g.estimate:.3g} Pa s m (95 %: {g.lower:.3g}–{g.upper:.3g}, "
            f"a factor of {g.upper / g.lower if g.lower > 0 else math.inf:.2g})"
        )
    return out
