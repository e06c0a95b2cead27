"""The encoder tests' null from the fitted model: what the flanks show without any effect.

An encoder test (run-out, the mesh order, a tooth) compares a flank pattern with what chance
leaves. Its decoy inflation (:func:`~rattlefit.features.orders.inflation`) measures chance at
orders where no pattern is, and misses a pattern that the rattle itself makes: when the drive
cycle is close to a multiple of a wheel's revolution, impacts that repeat with the drive
repeat with the wheel too, and the largest of many tooth offsets has a heavier tail than the
decoys hold. The null here is that of the fitted model without effects:
:data:`NULL_REALISATIONS` recordings of it on the recording's own rig (its drive as the fit
reconstructs it, read through the encoders;
:func:`~rattlefit.inference.realisation.fitted_recordings`), each test's statistic computed
on each exactly as on the recording (:func:`~rattlefit.features.orders.encoder_statistics`).
A finding stands outside that null when the recording's statistic exceeds every one of them
(a chance of at most 1/(n + 1) where the model without effects is right); only then, and
when its own test is significant, is it named. A pattern that the model without effects makes
as strongly is no evidence of an effect.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from ..features.orders import encoder_statistics
from ..inference.realisation import fitted_recordings
from ..inference.result import FitResult
from ..io.recording import Recording
from .evidence import Finding, kind_of

#: Recordings of the fitted model behind each recording's null.
NULL_REALISATIONS = 50
#: The test families whose null is simulated (the drive-order test's null is the recording's
#: own smooth drive through its encoder already, and drift has no flank pattern).
SIMULATED = ("runout", "mesh_order", "tooth")


def null_statistics(
    recording: Recording, result: FitResult, k: int, n: int, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """Each encoder test's statistic (:func:`~rattlefit.features.orders.encoder_statistics`)
    on ``n`` recordings of the fitted model of recording ``k`` of ``result``, without
    effects: test name → (n,) values."""
    again = fitted_recordings(result, recording, k, n, rng=rng)
    values = [encoder_statistics(r) for r in again]
    return {name: np.array([v[name] for v in values]) for name in values[0]}


def rejudged(f: Finding, observed: float, null: np.ndarray) -> Finding:
    """``f`` with its statistic ``observed`` set against the ``null`` values: ``detail``
    gains ``null_exceeding`` (how many null values reach the observed one), ``null_p``
    ((1 + that) / (n + 1)), ``null_median`` and ``null_realisations``; the finding stays
    significant only when no null value reaches it."""
    exceeding = int(np.sum(null >= observed))
    detail = f.test.detail | {
        "null_exceeding": exceeding,
        "null_p": (1 + exceeding) / (null.size + 1),
        "null_median": float(np.median(null)),
        "null_realisations": int(null.size),
    }
    test = dataclasses.replace(f.test, detail=detail)
    return dataclasses.replace(f, test=test, significant=f.significant and exceeding == 0)


def with_simulated_null(
    found: Sequence[Finding],
    recordings: Sequence[Recording],
    result: FitResult,
    *,
    n: int = NULL_REALISATIONS,
    seed: np.random.SeedSequence,
    say: Callable[[str], None] = lambda message: None,
) -> list[Finding]:
    """``found`` with the encoder findings (:data:`SIMULATED`) of every recording where one
    of them is significant set against the fitted model's null (:func:`null_statistics`,
    ``n`` recordings from child k of ``seed`` for recording k; :func:`rejudged`); the others
    as they were. ``n`` = 0 leaves ``found`` unchanged."""
    suspects = sorted(
        {f.recording for f in found if f.significant and kind_of(f.test) in SIMULATED}
    )
    if n == 0 or not suspects:
        return list(found)
    children = seed.spawn(len(recordings))
    observed, nulls = {}, {}
    for k in suspects:
        say(
            f"simulating the encoder tests' null of recording {k}: {n} recordings of the "
            "fitted model without effects …"
        )
        observed[k] = encoder_statistics(recordings[k])
        nulls[k] = null_statistics(recordings[k], result, k, n, np.random.default_rng(children[k]))
    out = []
    for f in found:
        if f.recording in nulls and kind_of(f.test) in SIMULATED:
            name = f.test.name
            f = rejudged(f, observed[f.recording][name], nulls[f.recording][name])
        out.append(f)
    return out
