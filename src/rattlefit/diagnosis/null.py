"""The encoder tests' null from the fitted model: what the flanks show without any effect.

An encoder test (run-out, the mesh order, a tooth) compares a flank pattern with what chance
leaves. Its decoy inflation (:func:`~rattlefit.features.orders.inflation`) measures chance at
orders where no pattern is, and misses a pattern that the rattle itself makes: when the drive
cycle is close to a multiple of a wheel's revolution, impacts that repeat with the drive
repeat with the wheel too, and the largest of many tooth offsets has a heavier tail than the
decoys hold. The null here is that of the fitted model without effects:
:data:`NULL_REALISATIONS` recordings of it on the recording's own rig (its drive as the fit
reconstructs it, read through the encoders;
:func:`~rattlefit.inference.realisation.fitted_recordings`), the size of each test's pattern
measured on each exactly as on the recording
(:func:`~rattlefit.features.orders.encoder_statistics`).
The null covers a finding when the recording's pattern is no larger than the model without
effects makes it commonly: a one-sided p of at least :data:`~.policy.COVERED_P`, the null's
logarithm taken as normal with a robust centre and spread (:func:`null_p`). A covered finding is not
named, whatever its decoy test says: a pattern that the model without effects makes as
strongly is no evidence of an effect. The null only takes findings away; it names none.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy import stats

from ..features.orders import encoder_statistics
from ..inference.realisation import fitted_recordings
from ..inference.result import FitResult
from ..io.recording import Recording
from .evidence import Finding, kind_of
from .policy import COVERED_P, FLANK_PATTERN_TESTS

#: Recordings of the fitted model behind each recording's null.
NULL_REALISATIONS = 50
#: Least spread of the null's logarithm (:func:`null_p`): a factor e^0.1 between realisations.
LOG_SPREAD_FLOOR = 0.1


def null_statistics(
    recording: Recording, result: FitResult, k: int, n: int, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """The size of each encoder test's pattern
    (:func:`~rattlefit.features.orders.encoder_statistics`, m) on ``n`` recordings of the
    fitted model of recording ``k`` of ``result``, without effects: test name → (n,)
    values."""
    again = fitted_recordings(result, recording, k, n, rng=rng)
    values = [encoder_statistics(r) for r in again]
    return {name: np.array([v[name] for v in values]) for name in values[0]}


def null_p(observed: float, null: np.ndarray) -> float:
    """One-sided p of ``observed`` under the ``null`` values, with the null's logarithm taken
    as normal: its median and its spread from the median absolute deviation (×1.4826,
    floored at :data:`LOG_SPREAD_FLOOR`). Robust to a few extreme null values (a realisation
    that locks into a periodic regime at that wheel order), which a count of the null values
    beyond the observed one is not."""
    logs = np.log(np.maximum(null, 1e-300))
    centre = float(np.median(logs))
    spread = max(1.4826 * float(np.median(np.abs(logs - centre))), LOG_SPREAD_FLOOR)
    return float(stats.norm.sf((math.log(max(observed, 1e-300)) - centre) / spread))


def rejudged(f: Finding, observed: float, null: np.ndarray) -> Finding:
    """``f`` with its pattern's size ``observed`` set against the ``null`` sizes: ``detail``
    gains ``null_p`` (:func:`null_p`), ``null_exceeding`` (how many null values reach the
    observed one), ``null_median`` and ``null_realisations``; the finding stays significant
    only when the null does not cover it (``null_p`` below :data:`~.policy.COVERED_P`)."""
    p = null_p(observed, null)
    detail = f.test.detail | {
        "null_p": p,
        "null_exceeding": int(np.sum(null >= observed)),
        "null_median": float(np.median(null)),
        "null_realisations": int(null.size),
    }
    test = dataclasses.replace(f.test, detail=detail)
    return dataclasses.replace(f, test=test, significant=f.significant and p < COVERED_P)


def with_simulated_null(
    found: Sequence[Finding],
    recordings: Sequence[Recording],
    result: FitResult,
    *,
    n: int = NULL_REALISATIONS,
    seed: np.random.SeedSequence,
    say: Callable[[str], None] = lambda message: None,
) -> list[Finding]:
    """``found`` with the encoder findings (:data:`~.policy.FLANK_PATTERN_TESTS`) of every
    recording where one of them is significant set against the fitted model's null
    (:func:`null_statistics`, ``n`` recordings from child k of ``seed`` for recording k;
    :func:`rejudged`); the others as they were. ``n`` = 0 leaves ``found`` unchanged."""
    suspects = sorted(
        {f.recording for f in found if f.significant and kind_of(f.test) in FLANK_PATTERN_TESTS}
    )
    if n == 0 or not suspects:
        return list(found)
    children = seed.spawn(len(recordings))
    nulls = {}
    for k in suspects:
        say(
            f"simulating the encoder tests' null of recording {k}: {n} recordings of the "
            "fitted model without effects …"
        )
        nulls[k] = null_statistics(recordings[k], result, k, n, np.random.default_rng(children[k]))
    # a finding's amplitude is the size encoder_statistics measures on the null recordings
    return [
        rejudged(f, f.test.amplitude, nulls[f.recording][f.test.name])
        if f.recording in nulls and kind_of(f.test) in FLANK_PATTERN_TESTS
        else f
        for f in found
    ]
