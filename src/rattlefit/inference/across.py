"""Starts of a fit across lubrications, from each lubrication's own search.

A fit across lubrications (e.g. a boundary recording with its oil-jet companion) has one film
half-length per lubrication and shares the rest. Its joint cost adds rugged landscapes whose
narrow basins rarely overlap on a Sobol' start, so the joint search can end far above the
basin each recording reaches alone. :func:`lubrication_starts` therefore runs the search stage
(:func:`~rattlefit.inference.least_squares.refine_starts`) on each lubrication's recordings
alone, and :func:`combined_starts` turns their optima into starts of the joint fit: every film
half-length and backlash from its own lubrication's optimum, and the shared parameters from
each lubrication's optimum in turn (one start per lubrication).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from ..io.recording import Recording
from ..problem.options import FitOptions
from ..problem.problem import Problem, problem_from
from ..quantities import FILM
from .least_squares import refine_starts
from .starts import starting_points


def lubrication_groups(films: Sequence[str]) -> dict[str, list[int]]:
    """Each film half-length's name → the indices of the recordings that use it, in order."""
    groups: dict[str, list[int]] = {}
    for r, film in enumerate(films):
        groups.setdefault(film, []).append(r)
    return groups


def backlash_index(name: str) -> int | None:
    """The recording index of a backlash parameter (``"backlash[2]"`` → 2), else None."""
    if not name.startswith("backlash["):
        return None
    return int(name[len("backlash[") : -1])


def group_name(joint_name: str, film: str, members: Sequence[int]) -> str | None:
    """The name a joint parameter has in the fit of one lubrication's recordings ``members``
    (whose film half-length the joint fit calls ``film``); None if that fit lacks it."""
    if joint_name == film:
        return FILM
    if joint_name.startswith(f"{FILM}["):
        return None  # another lubrication's film half-length
    r = backlash_index(joint_name)
    if r is not None:
        return f"backlash[{members.index(r)}]" if r in members else None
    return joint_name


def group_options(options: FitOptions, film: str, members: Sequence[int]) -> FitOptions:
    """``options`` for the fit of one lubrication's recordings: the joint priors that apply
    renamed to that fit's parameters."""
    priors = {}
    for name, spec in options.priors.items():
        own = group_name(name, film, members)
        if own is not None:
            priors[own] = dataclasses.replace(spec, name=own)
    return options.replace(priors=priors)


def owner_of(joint_name: str, films: Sequence[str], donor: str) -> str:
    """Which lubrication's optimum a joint parameter's start comes from: a film half-length's
    and a backlash's own, the ``donor``'s for a shared parameter."""
    if joint_name in films:
        return joint_name
    r = backlash_index(joint_name)
    return donor if r is None else films[r]


def combined_starts(problem: Problem, optima: dict[str, tuple[Problem, np.ndarray]]) -> np.ndarray:
    """Starts (G, P) of the joint ``problem`` from each lubrication's optimum.

    ``optima`` maps each film half-length's name to ``(group_problem, z)``: the problem of
    that lubrication's recordings alone and its search's optimum. Row g takes the shared
    parameters from the g-th lubrication's optimum; every film half-length and backlash comes
    from its own lubrication's. Values carry over in SI units, so the coordinates of the two
    problems need not agree.
    """
    groups = lubrication_groups(problem.films)
    values = {}  # film → {joint name: value} of the parameters that lubrication's fit has
    for film, (group_problem, z) in optima.items():
        own = {s.name: s.value(float(z[i])) for i, s in enumerate(group_problem.specs)}
        values[film] = {
            s.name: own[n]
            for s in problem.specs
            if (n := group_name(s.name, film, groups[film])) is not None
        }
    rows = []
    for donor in optima:
        rows.append(
            [
                spec.z_of(float(values[owner_of(spec.name, problem.films, donor)][spec.name]))
                for spec in problem.specs
            ]
        )
    return np.asarray(rows, dtype=float)


def lubrication_starts(
    recordings: Sequence[Recording], problem: Problem, options: FitOptions, say: Callable
) -> np.ndarray:
    """The :func:`combined_starts` of a fit across lubrications, after the search stage on
    each lubrication's recordings alone (with ``options``, its own seeded problem and starts);
    an empty (0, P) array when the recordings share one lubrication."""
    groups = lubrication_groups(problem.films)
    if len(groups) < 2:
        return np.empty((0, len(problem.specs)))
    optima = {}
    for film, members in groups.items():
        say(f"searching {film} alone ({len(members)} recording(s)) for the joint fit's starts …")
        sub_options = group_options(options, film, members)
        sub_problem, _, rng = problem_from([recordings[r] for r in members], sub_options)
        starts = starting_points(
            sub_problem,
            options.n_starts,
            rng,
            nuisance_starts=options.nuisance_starts,
        )
        refined = refine_starts(sub_problem, starts, sub_options, rng, lambda m: say("  " + m))
        optima[film] = (refined.problem, refined.optimum)
    return combined_starts(problem, optima)
