"""Model-free evidence from the angle and time domains, and the effect each test points to.

The band spectrum cannot hold a once-per-revolution change of the play, and an effect fitted
to it can absorb a model-form difference that is no effect at all. The tests here read the
recording alone (:mod:`rattlefit.features.orders`, :mod:`rattlefit.features.drift`): where
the flanks were met against each wheel's angle and tooth, and whether the rattle's
statistics trend over the recording. They need no simulation, so they hold on data from any
rig. Each test points to one effect of the catalogue.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

from ..features.drift import drift_evidence
from ..features.orders import (
    AngleTest,
    contact_events,
    drive_order_evidence,
    mesh_order_evidence,
    runout_evidence,
    tooth_evidence,
)
from ..io.recording import Recording
from .policy import POINTS_TO, RELEVANCE_Z, RELEVANT_RIPPLE_SHARE, RELEVANT_SIZE_M


@dataclasses.dataclass(frozen=True)
class Finding:
    """One model-free test of one recording.

    recording : index of the recording; test : the test
    (:class:`~rattlefit.features.orders.AngleTest`); effect : the effect it points to;
    level : the p-value below which it counts; significant : p below ``level`` and the
    pattern at least :data:`~.policy.RELEVANT_SIZE_M`.
    """

    recording: int
    test: AngleTest
    effect: str
    level: float
    significant: bool

    def as_dict(self) -> dict:
        return {
            "recording": self.recording,
            "effect": self.effect,
            "level": self.level,
            "significant": self.significant,
            **self.test.as_dict(),
        }


def recording_tests(recording: Recording) -> list[AngleTest]:
    """Every model-free test of one recording: run-out of each wheel, the mesh order, a
    local tooth defect on each wheel, drift (not on dry flanks: the effect it points to is a
    change of the oil's viscosity), and a ripple of the primary shaft."""
    events = contact_events(recording)
    dry = recording.operating.lubrication == "dry"
    return [
        *runout_evidence(recording, events),
        mesh_order_evidence(recording, events),
        *tooth_evidence(recording, events),
        *([] if dry else [drift_evidence(recording)]),
        drive_order_evidence(recording),
    ]


def kind_of(test: AngleTest) -> str:
    """The test's family: its name up to the first dot (``"runout.primary"`` → ``"runout"``)."""
    return test.name.split(".", 1)[0]


def relevant(test: AngleTest, recording: Recording) -> bool:
    """The pattern is large enough to name: its size less
    :data:`~.policy.RELEVANCE_Z` standard errors reaches the floor
    (:data:`~.policy.RELEVANT_SIZE_M`,
    :data:`~.policy.RELEVANT_RIPPLE_SHARE`; a test without a floor is
    always relevant)."""
    kind = kind_of(test)
    if kind == "drive_order":
        op = recording.operating
        share = RELEVANT_RIPPLE_SHARE * 2 * math.pi * op.drive_frequency_hz
        floor = share * op.drive_speed_amplitude_rad_s
    else:
        floor = RELEVANT_SIZE_M.get(kind, 0.0)
    if floor <= 0.0:
        return True
    return test.amplitude - RELEVANCE_Z * test.amplitude_sd >= floor


def findings(recordings: Sequence[Recording], significance: float) -> list[Finding]:
    """Every test of every recording, each judged at ``significance`` over the number of
    tests (Bonferroni) and against the size worth naming (:func:`relevant`)."""
    tests = [(k, t) for k, rec in enumerate(recordings) for t in recording_tests(rec)]
    level = significance / max(len(tests), 1)
    out = []
    for k, test in tests:
        named = test.p_value < level and relevant(test, recordings[k])
        out.append(Finding(k, test, POINTS_TO[kind_of(test)], level, bool(named)))
    return out


def candidate_static(found: Sequence[Finding]) -> dict[str, dict]:
    """The static fields of the candidates that the significant findings fix: a drive
    ripple at the order its test found (the most significant one's)."""
    ripples = [f for f in found if f.significant and kind_of(f.test) == "drive_order"]
    if not ripples:
        return {}
    best = min(ripples, key=lambda f: f.test.p_value)
    return {"drive_ripple": {"order": int(best.test.detail["order"])}}
