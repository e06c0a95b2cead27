"""Where each candidate effect is screened before it is fitted.

An effect's fields are screened over a few decades below the top of their ranges, each
together with alternatives of the free parameters (the film half-lengths and the drag
torque), since a dissipative effect can stand in for the squeeze film and part of the drag
that the fit without it has given all the dissipation there is.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..physics.effects import effect_class
from ..problem.parameters import Z_END
from ..problem.problem import Problem
from .trial import Trial, costs, validated

#: Where each effect field is screened before the fit: decades below the top of its range
#: (each range's top is a generous size for a production gearbox, so the sizes worth finding
#: lie within a few decades of it; the lower end means absent). Quarter decades (a factor
#: 1.78) over the top two: an effect's basin can be narrower than half a decade.
SCREEN_DECADES = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 3.0)
#: The screening ranks its points on this many of the fit's realisations (a basin stands out
#: of the Monte Carlo noise on few), then the :data:`SCREEN_FINALISTS` best on all of them.
SCREEN_REALISATIONS = 2
SCREEN_FINALISTS = 4


#: The alternatives of (film half-length, drag torque) in the screening, as factors on their
#: fitted values (a film factor 0: the bottom of its range, dry flanks). A dissipative effect
#: can stand in for the squeeze film and for part of the drag, which the fit without it will
#: have given all the dissipation there is; but the drag can be understated as well (the fit
#: giving a film what is drag), hence the dry alternatives with more drag too.
FREE_FACTORS = (
    (1.0, 1.0),
    (0.1, 1.0),
    (0.01, 1.0),
    (0.0, 1.0),
    (1.0, 0.5),
    (0.0, 0.5),
    (1.0, 0.25),
    (0.0, 0.25),
    (0.0, 2.0),
    (0.0, 4.0),
    (0.0, 8.0),
    (1.0, 4.0),
)
#: Drag torques of the dry alternatives that do not follow the fitted one, as shares of the way
#: across the drag's start range in the log (0: its lower end, 1: its upper): a fit without the
#: effect can drive the drag to the end of its range, out of reach of any factor on it.
DRAG_SPREAD = (0.0, 0.5, 1.0)


def screen_points(
    z_off: np.ndarray,
    indices: Sequence[int],
    problem: Problem,
    *,
    shape: Sequence[int] = (),
) -> np.ndarray:
    """Starting points: each field of an effect (its coordinates ``indices`` in ``problem``)
    alone at :data:`SCREEN_DECADES` below the top of its range (the others absent), and,
    with several fields, all of them together; each with the film half-length and the drag
    torque at :data:`FREE_FACTORS` of their values at ``z_off``. The fields at ``shape`` (the
    effect's ``shape_fields``, which do not size it) are screened only together with the
    others: alone, the effect is absent."""
    specs = [problem.specs[i] for i in indices]
    grid = [np.array([s.z_of(s.upper * 10.0**-k) for s in specs]) for k in SCREEN_DECADES]
    fields = []
    for j, i in enumerate(indices):
        if i in shape:
            continue
        for g in grid:
            z = z_off.copy()
            z[i] = g[j]
            fields.append(z)
    if len(specs) > 1:
        for g in grid:
            z = z_off.copy()
            z[list(indices)] = g
            fields.append(z)
    free = free_indices(problem)
    points = []
    for alt in free_alternatives(z_off, problem):
        for z in fields:
            z = z.copy()
            z[free] = alt[free]
            points.append(z)
    return np.stack(points)


def film_indices(problem) -> list[int]:
    """Where the film half-length(s) sit in the problem's coordinates (one per lubrication)."""
    films = set(problem.films)
    return [i for i, sp in enumerate(problem.specs) if sp.name in films]


def free_indices(problem) -> list[int]:
    """Where the physical parameters, the film half-length(s) and the drag torque, sit in the
    problem's coordinates (the films first)."""
    space = problem.space
    physical = [space.index(n) for n in space.of_role("physical")]
    films = film_indices(problem)
    return [*films, *(i for i in physical if i not in films)]


def free_alternatives(z: np.ndarray, problem) -> np.ndarray:
    """``z`` with the film half-length(s) and the drag torque at each of
    :data:`FREE_FACTORS` of their values in ``z`` (a factor 0: the bottom of the range), one
    row per pair, every film half-length scaled alike; then dry, with the drag at each of
    :data:`DRAG_SPREAD` across its start range (:func:`spread_drags`)."""
    i_drag = free_indices(problem)[-1]

    def scaled(i, factor):
        spec = problem.specs[i]
        if factor == 0:
            return -Z_END
        return spec.z_of(max(float(spec.value(z[i])) * factor, spec.lower))

    rows = []
    for f_film, f_drag in FREE_FACTORS:
        row = np.array(z, dtype=float, copy=True)
        for i_film in film_indices(problem):
            row[i_film] = scaled(i_film, f_film)
        row[i_drag] = scaled(i_drag, f_drag)
        rows.append(row)
    for drag in spread_drags(problem.specs[i_drag]):
        row = np.array(z, dtype=float, copy=True)
        for i_film in film_indices(problem):
            row[i_film] = -Z_END
        row[i_drag] = drag
        rows.append(row)
    return np.stack(rows)


def spread_drags(spec) -> list[float]:
    """The drag coordinates at :data:`DRAG_SPREAD` across ``spec``'s start range in the log
    (its range when it has none)."""
    lo, hi = spec.start_range or (spec.lower, spec.upper)
    return [spec.z_of(float(lo * (hi / lo) ** t)) for t in DRAG_SPREAD]


def distinct_rows(points: np.ndarray) -> np.ndarray:
    """``points`` (K, P) without repeated rows, in the order of their first appearance (a
    dry recording's film alternatives, or fields clipped to the ends of their ranges,
    coincide)."""
    _, first = np.unique(points, axis=0, return_index=True)
    return points[np.sort(first)]


def shape_indices(trial: Trial, name: str) -> list[int]:
    """The coordinates of effect ``name``'s ``shape_fields`` in ``trial.problem``."""
    shape = {f"{name}.{field}" for field in effect_class(name).shape_fields}
    return [i for i in trial.candidates[name] if trial.problem.specs[i].name in shape]


def screen(trial: Trial, name: str, z_base) -> tuple[np.ndarray, float, float]:
    """The starts for effect ``name`` from ``z_base`` (every effect absent), by
    successive halving: every distinct screening point (:func:`screen_points`) costed on the
    first :data:`SCREEN_REALISATIONS` realisations, the :data:`SCREEN_FINALISTS` cheapest
    then compared on the validation states (:func:`~rattlefit.diagnosis.trial.validated`).
    Returns the finalists (F, P), the best on the validation states first, the cost at
    ``z_base`` and the best finalist's (both on all the fit's realisations)."""
    points = screen_points(
        z_base, trial.candidates[name], trial.problem, shape=shape_indices(trial, name)
    )
    starts = distinct_rows(trial.dried(points))
    m = min(SCREEN_REALISATIONS, trial.problem.y0.shape[1])
    rough = costs(trial, starts, realisations=np.arange(m))
    finalists = starts[np.argsort(rough, kind="stable")[:SCREEN_FINALISTS]]
    _, values = validated(trial, finalists)
    finalists = finalists[np.argsort(values, kind="stable")]
    cost = costs(trial, np.stack([z_base, finalists[0]]))
    return finalists, float(cost[0]), float(cost[1])
