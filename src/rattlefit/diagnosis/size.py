"""How large a named effect is: a profile of the χ² over its size.

The effect's first field (its size: a run-out amplitude, a friction coefficient, a damping
ratio …) is moved off its fitted value by :data:`SIZE_DECADES`; at each value the film
half-lengths and the drag torque are re-fitted (the size held), and the χ² of the data rows
is measured on the fresh realisations of the diagnosis' comparison. The 95 % interval holds
the sizes whose χ² rise stays below :func:`~rattlefit.inference.profile.profile_threshold`
(χ²₁'s quantile plus the Monte Carlo noise of a difference of two χ²s), after scaling the
rise by the misfit per degree of freedom that remains where it exceeds one (as the F-test
does); the crossing is interpolated in the square root of the rise.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..inference.profile import polish_profile, profile_interval, profile_threshold
from .trial import Trial, chi2s, difference_sd, field_key, refit_steps, residual_rows

#: Where the size is profiled: decades off its fitted value (clipped to its range); close
#: in, since a size the band spectrum pins can be pinned to a few per cent.
SIZE_DECADES = (-1.0, -0.5, -0.2, -0.07, 0.07, 0.2, 0.5, 1.0)


def size_points(trial: Trial, i: int, z_fit) -> tuple[np.ndarray, np.ndarray]:
    """``z_fit`` with the effect field at coordinate ``i`` moved by :data:`SIZE_DECADES`
    (within its range, repeats dropped): the points (K, P) and their log10 sizes (K,)."""
    spec = trial.problem.specs[i]
    fitted = float(spec.value(z_fit[i]))
    sizes = np.unique(np.clip(fitted * 10.0 ** np.asarray(SIZE_DECADES), spec.lower, spec.upper))
    sizes = sizes[~np.isclose(sizes, fitted, rtol=1e-6)]
    points = np.repeat(np.asarray(z_fit, dtype=float)[None], len(sizes), axis=0)
    points[:, i] = [spec.z_of(float(v)) for v in sizes]
    return points, np.log10(sizes)


def size_interval(
    trial: Trial, name: str, i: int, z_fit, chi2_fit: float
) -> tuple[float, float, float]:
    """The estimate and 95 % interval (SI) of the field at coordinate ``i`` of effect
    ``name`` (or of ``"<effect>+<effect>"``), from the fitted point ``z_fit`` whose χ² on the
    fresh realisations is ``chi2_fit``: ``(estimate, lower, upper)``, the estimate the
    profile's least χ² (the fitted value or a profiled one). An end at a range's end or at
    the last value profiled is a bound."""
    spec = trial.problem.specs[i]
    points, logs = size_points(trial, i, z_fit)
    held = [sorted([*trial.held(name), i])] * len(points)
    polished = polish_profile(
        functools.partial(residual_rows, trial),
        points,
        held,
        refit_steps(trial, points),
        iterations=trial.iterations,
    )
    chi2 = np.append(chi2s(trial, polished), chi2_fit)
    chi2 = np.where(np.isfinite(chi2), chi2, np.inf)
    logs = np.append(logs, math.log10(float(spec.value(z_fit[i]))))
    best = float(np.min(chi2))
    dof = max(trial.dof - len(trial.fields(name)), 1)
    scale = max(1.0, best / dof)  # the misfit left, per degree of freedom
    noise_sd = difference_sd(trial, best, best, dof) / scale
    # the square root of the rise is linear in the size near a quadratic minimum, so the
    # interpolated crossing is exact there (a linear rise would understate the width)
    root = np.sqrt(np.maximum(chi2 - best, 0.0) / scale)
    profile = {float(t): (float(r), None) for t, r in zip(logs, root, strict=True)}
    (lo, hi), _ = profile_interval(profile, math.sqrt(profile_threshold(noise_sd)))
    return 10.0 ** logs[int(np.argmin(chi2))], 10.0**lo, 10.0**hi


def size_intervals(trial: Trial, name: str, z_fit, chi2_fit: float) -> dict[str, tuple]:
    """:func:`size_interval` of the first field of each effect in ``name`` (one, or two
    joined by ``+``): key (:func:`~rattlefit.diagnosis.trial.field_key`) →
    (estimate, lower, upper)."""
    out = {}
    for effect in name.split("+"):
        i = trial.candidates[effect][0]
        out[field_key(trial, name, i)] = size_interval(trial, name, i, z_fit, chi2_fit)
    return out
