"""How large a named effect is: a profile of the χ² over its size.

The effect's first field (its size: a run-out amplitude, a friction coefficient, a damping
ratio …) is moved off its fitted value by :data:`SIZE_DECADES`; at each value the film
half-lengths and the drag torque are re-fitted (the size held), and the χ² of the data rows
is measured on the fresh realisations of the diagnosis' comparison. The 95 % interval holds
the sizes whose χ² rise stays below :func:`~rattlefit.inference.profile.profile_threshold`
(χ²₁'s quantile plus the Monte Carlo noise of a difference of two χ²s), after scaling the
rise by the misfit per degree of freedom that remains where it exceeds one (as the F-test
does); the crossing is interpolated in the square root of the rise. Where the trial simulates
the misfit's null, the interval also spans every profiled size at which the model with the
effect is not rejected by its own null (:func:`~rattlefit.diagnosis.trial.misfit_p` at least
:data:`ACCEPT_P`; the inversion of that test): in nearly deterministic rattle the band spread
changes with the size, and the χ² rise at the identification's spread is then no likelihood
ratio.

The profile also holds the size's absent end and its *relevance floor*,
:data:`~.policy.RELEVANT_SHARE` of the effect's typical size (``Effect.typical``, a physical
reference): an effect whose interval reaches below the floor cannot be told from no effect
by the band spectrum, whatever share of the gap its fit closed (:func:`relevant`), and a
diagnosis does not name it.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..inference.profile import polish_profile, profile_interval, profile_threshold
from ..physics.effects import effect_class
from .policy import RELEVANT_SHARE, effects_of
from .trial import (
    Trial,
    difference_sd,
    field_key,
    final_chi2,
    fresh_features,
    misfit_ps,
    refit_steps,
    residual_rows,
)

#: Where the size is profiled: decades off its fitted value (clipped to its range); close
#: in, since a size the band spectrum pins can be pinned to a few per cent.
SIZE_DECADES = (-1.0, -0.5, -0.2, -0.07, 0.07, 0.2, 0.5, 1.0)
#: A profiled size whose model the misfit's null does not reject at this p is in the interval.
ACCEPT_P = 0.05


def relevance_floor(effect: str) -> float:
    """The smallest size of ``effect``'s first field worth naming (SI):
    :data:`~.policy.RELEVANT_SHARE` of its typical size, or 0 when it declares none."""
    typical = effect_class(effect).typical
    return 0.0 if typical is None else RELEVANT_SHARE * typical[0]


def size_points(trial: Trial, i: int, z_fit, floor: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """``z_fit`` with the effect field at coordinate ``i`` moved by :data:`SIZE_DECADES`, to
    its absent end (its range's lower end) and to ``floor`` when that lies in the range
    (within its range, repeats dropped): the points (K, P) and their log10 sizes (K,)."""
    spec = trial.problem.specs[i]
    fitted = float(spec.value(z_fit[i]))
    moved = fitted * 10.0 ** np.asarray(SIZE_DECADES)
    ends = [spec.lower] + ([floor] if spec.lower < floor < spec.upper else [])
    sizes = np.unique(np.clip(np.append(moved, ends), spec.lower, spec.upper))
    sizes = sizes[~np.isclose(sizes, fitted, rtol=1e-6)]
    points = np.repeat(np.asarray(z_fit, dtype=float)[None], len(sizes), axis=0)
    points[:, i] = [spec.z_of(float(v)) for v in sizes]
    return points, np.log10(sizes)


def size_interval(
    trial: Trial, name: str, i: int, z_fit, chi2_fit: float, floor: float = 0.0
) -> tuple[float, float, float]:
    """The estimate and 95 % interval (SI) of the field at coordinate ``i`` of effect
    ``name`` (or of ``"<effect>+<effect>"``), from the fitted point ``z_fit`` whose χ² on the
    fresh realisations is ``chi2_fit``: ``(estimate, lower, upper)``, the estimate the
    profile's least χ² (the fitted value or a profiled one), profiled down to the absent end
    and through ``floor`` (:func:`size_points`). An end at a range's end or at the last
    value profiled is a bound."""
    spec = trial.problem.specs[i]
    points, logs = size_points(trial, i, z_fit, floor)
    held = [sorted([*trial.held(name), i])] * len(points)
    polished = polish_profile(
        functools.partial(residual_rows, trial),
        points,
        held,
        refit_steps(trial, points),
        iterations=trial.iterations,
    )
    dof = max(trial.dof - len(trial.fields(name)), 1)
    chi2, accepted = profiled_misfits(trial, polished, dof)
    chi2 = np.append(chi2, chi2_fit)
    chi2 = np.where(np.isfinite(chi2), chi2, np.inf)
    logs = np.append(logs, math.log10(float(spec.value(z_fit[i]))))
    best = float(np.min(chi2))
    scale = max(1.0, best / dof)  # the misfit left, per degree of freedom
    noise_sd = difference_sd(trial, best, best, dof) / scale
    # the square root of the rise is linear in the size near a quadratic minimum, so the
    # interpolated crossing is exact there (a linear rise would understate the width)
    root = np.sqrt(np.maximum(chi2 - best, 0.0) / scale)
    profile = {float(t): (float(r), None) for t, r in zip(logs, root, strict=True)}
    (lo, hi), _ = profile_interval(profile, math.sqrt(profile_threshold(noise_sd)))
    spanned = logs[:-1][accepted]
    if spanned.size:
        lo, hi = min(lo, float(spanned.min())), max(hi, float(spanned.max()))
    return 10.0 ** logs[int(np.argmin(chi2))], 10.0**lo, 10.0**hi


def profiled_misfits(trial: Trial, points, dof: int) -> tuple[np.ndarray, np.ndarray]:
    """χ² (K,) of the data rows at each profiled point ``points`` (K, P) on the fresh
    realisations, and whether the misfit's simulated null accepts each (p ≥
    :data:`ACCEPT_P`; all False when the trial simulates no null)."""
    fresh = fresh_features(trial, points)
    chi2 = np.array([final_chi2(trial, z, f)[0] for z, f in zip(points, fresh, strict=True)])
    if trial.null_y0 is None:
        return chi2, np.zeros(len(points), dtype=bool)
    p = misfit_ps(trial, points, chi2, dof, fresh)  # every point's null in one batch
    return chi2, np.isfinite(chi2) & (p >= ACCEPT_P)


def size_intervals(trial: Trial, name: str, z_fit, chi2_fit: float) -> dict[str, tuple]:
    """:func:`size_interval` of the first field of each effect in ``name`` (one, or two
    joined by ``+``): key (:func:`~rattlefit.diagnosis.trial.field_key`) →
    (estimate, lower, upper)."""
    out = {}
    for effect in effects_of(name):
        i = trial.candidates[effect][0]
        floor = relevance_floor(effect)
        out[field_key(trial, name, i)] = size_interval(trial, name, i, z_fit, chi2_fit, floor)
    return out


def interval_caveat(outcome, significance: float, dof: int) -> str:
    """Why the size intervals of ``outcome`` (an
    :class:`~rattlefit.diagnosis.outcome.EffectOutcome` whose fit has ``dof`` degrees of
    freedom left) are not 95 % intervals of the size, or empty when they are: its
    ``p_after`` is below the family-wise ``significance``, a significant misfit left."""
    if not outcome.intervals or outcome.p_after >= significance:
        return ""
    return (
        f"a significant misfit remains with it (χ² {outcome.chi2_with:.1f} on {dof} dof, "
        f"p = {outcome.p_after:.2g}): the interval is the precision of a model known to miss, "
        "not a 95 % interval of the size"
    )


def relevant(intervals: dict[str, tuple[float, float]], name: str, trial: Trial) -> bool:
    """Every sized field of ``name`` (one effect, or two joined by ``+``) has the lower end of
    its interval (``intervals``, key → (lower, upper) as :func:`size_intervals` keys them) at
    or above its effect's :func:`relevance_floor`."""
    for effect in effects_of(name):
        key = field_key(trial, name, trial.candidates[effect][0])
        if key in intervals and intervals[key][0] < relevance_floor(effect):
            return False
    return True
