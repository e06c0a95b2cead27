"""Two effects together: tried when the best single candidate leaves a significant misfit.

A recording can carry two unmodelled effects, and then neither alone closes the band gap.
The best supported single candidate (or, when the encoders found an effect, that effect's
candidate: it is known to be present) is paired with each of the next
:data:`~.policy.PAIR_PARTNERS` supported ones: both start at their own fitted sizes (the film
half-lengths and the drag torque where the better one put them) and are re-fitted together.
Before pairing, the first member is fitted on until its cost settles
(:func:`settled_single`), since the pair's refit continues its coordinates. The pair is judged
like a single effect against the model without effects, and in addition against its first
member so fitted: the second effect must remove a significant part of what the first leaves
(an F-test at the same level, and a drop above the Monte Carlo noise) to be named.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..confidence import Z95_ONE_SIDED
from .outcome import EffectOutcome
from .policy import PAIR_PARTNERS, is_pair, pair_name
from .trial import (
    Trial,
    difference_sd,
    f_test,
    judge_effect,
    moves,
    refit,
    settled_path,
    validated,
)


def pair_candidates(
    outcomes: list[EffectOutcome], seen: frozenset[str] = frozenset()
) -> list[tuple[EffectOutcome, EffectOutcome]]:
    """The pairs worth fitting: the first member is the single candidate of an effect the
    model-free tests found (``seen``; the least misfit of them), else the supported one with
    the least misfit; its partners are the next :data:`~.policy.PAIR_PARTNERS` supported ones."""
    singles = sorted(
        (o for o in outcomes if not o.failure and not is_pair(o.name)), key=lambda o: o.chi2_with
    )
    found = [o for o in singles if o.name in seen]
    supported = [o for o in singles if o.supported]
    if not found and not supported:
        return []
    first = found[0] if found else supported[0]
    partners = [o for o in supported if o is not first]
    return [(first, o) for o in partners[:PAIR_PARTNERS]]


def settled_single(
    trial: Trial, single: EffectOutcome, z_fit, z_base, chi2_without: float, level: float
) -> tuple[EffectOutcome, object]:
    """``single`` fitted on from its point ``z_fit`` until its cost settles, the nuisances
    free with their priors as in the re-fit without effects
    (:func:`~rattlefit.diagnosis.trial.settled_path`, at most ``trial.base_iterations``; of
    its points the one :func:`~rattlefit.diagnosis.trial.validated` chooses), and judged
    again: the better of the two outcomes and its point. A pair refits the first
    effect's coordinates beyond its single fit, so the second effect must beat the first fitted
    as far: in a narrow basin (dry flanks with friction) a few iterations leave the single
    short of its minimum, and any second dissipative effect then takes up the rest."""
    held = trial.held(single.name, nuisances=False)
    path = settled_path(trial, z_fit, held, iterations=trial.base_iterations)
    z = path[validated(trial, path)[0]]
    settled = judge_effect(trial, single.name, chi2_without, z, level)
    if settled.failure or not settled.chi2_with < single.chi2_with:
        return single, z_fit
    settled = dataclasses.replace(
        settled, wall_time=single.wall_time, moves=moves(trial, z_base, z)
    )
    return settled, z


def pair_start(trial: Trial, second: str, z_first, z_second):
    """The first effect's fitted point with the second effect's fields at its own fit."""
    z = z_first.copy()
    idx = trial.candidates[second]
    z[idx] = z_second[idx]
    return z


def beyond_single(trial: Trial, pair: EffectOutcome, single: EffectOutcome, level: float):
    """``pair`` with ``p_beyond`` (F-test of its χ² against ``single``'s, the second
    effect's fields as the extra degrees of freedom) and ``beyond_single`` (p below
    ``level`` and the drop above the Monte Carlo noise of a difference of two χ²s)."""
    d = len(trial.fields(pair.name)) - len(trial.fields(single.name))
    dof_with = max(trial.dof - len(trial.fields(pair.name)), 1)
    delta = single.chi2_with - pair.chi2_with
    p = f_test(delta, d, pair.chi2_with, dof_with)
    noise = Z95_ONE_SIDED * difference_sd(trial, single.chi2_with, pair.chi2_with)
    clear = bool(p < level and delta > noise)
    return dataclasses.replace(pair, p_beyond=p, beyond_single=clear)


def try_pair(
    trial: Trial,
    first: EffectOutcome,
    second: EffectOutcome,
    fitted: dict,
    chi2_without: float,
    level: float,
) -> tuple[EffectOutcome, object]:
    """The two effects fitted together from their single fits (``fitted``: name → fitted
    point; the fit or its start, whichever :func:`~rattlefit.diagnosis.trial.validated`
    chooses) and judged: the outcome (named ``"<first>+<second>"``) and its point."""
    name = pair_name(first.name, second.name)
    z0 = pair_start(trial, second.name, fitted[first.name], fitted[second.name])
    points = np.stack([refit(trial, z0, trial.held(name)), z0])
    z_fit = points[validated(trial, points)[0]]
    outcome = judge_effect(trial, name, chi2_without, z_fit, level)
    if outcome.failure:
        return outcome, z_fit
    return beyond_single(trial, outcome, first, level), z_fit
