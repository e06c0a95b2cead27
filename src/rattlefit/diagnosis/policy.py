"""diagnose's policy: which effects are tried, when one is named, and every threshold that
decides it.

What a recording shows of an effect without any model is declared on the effect
(:class:`~rattlefit.physics.model.Effect`: ``evidence``, ``encoder_visible``,
``named_only_when_found``, ``relevant_size``); the sets below are read from the catalogue
(:data:`~rattlefit.physics.effects.EFFECTS`), so adding an effect is one file of
:mod:`rattlefit.physics.effects`. The rationale is in ``docs/diagnosis.md``.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence

from ..physics.effects import EFFECTS

# -- what a recording shows without a model -------------------------------------------------

#: The effect each model-free test family points to.
POINTS_TO: dict[str, str] = {c.evidence: n for n, c in EFFECTS.items() if c.evidence}
#: Effects that the encoders see directly (a kinematic error moves the flanks, a drive ripple
#: moves the primary shaft): named only when their model-free test finds them, never from the
#: band spectrum alone, where a flexible candidate can absorb a model-form difference; and
#: left out of the compiled program when not found.
ENCODER_VISIBLE: frozenset[str] = frozenset(n for n, c in EFFECTS.items() if c.encoder_visible)
#: Effects named only when their model-free test finds them: those the encoders see, and
#: those that declare it (a drift of the oil's viscosity, which shows as a trend of the
#: rattle's statistics; fitted to the band spectrum alone it is one more dissipation
#: parameter, free to absorb a model-form difference). Unlike those the encoders see, these
#: stay in the compiled program when not found: their absent end costs nothing.
FOUND_ONLY: frozenset[str] = ENCODER_VISIBLE | {
    n for n, c in EFFECTS.items() if c.named_only_when_found
}
#: Smallest flank pattern worth naming, as a gap error on the pitch circle (m), by test
#: family: below about 2 µm of run-out or a tooth's deviation, gear quality classes do not
#: tell gears apart. The drift test has no floor (its statistics are logarithms and shares).
RELEVANT_SIZE_M: dict[str, float] = {
    c.evidence: c.relevant_size
    for c in EFFECTS.values()
    if c.evidence is not None and c.relevant_size is not None
}
#: The test families that measure a flank pattern on the pitch circle: their null is
#: simulated from the fitted model (the drive-order test's null is the recording's own
#: smooth drive through its encoder, and drift has no flank pattern).
FLANK_PATTERN_TESTS: tuple[str, ...] = tuple(RELEVANT_SIZE_M)
#: Smallest drive ripple worth naming, as a share of the speed fluctuation's acceleration
#: amplitude 2π f ΔΩ.
RELEVANT_RIPPLE_SHARE = 0.01
#: A pattern is worth naming when its size, less this many standard errors, still reaches
#: its floor: a one-sided test (about 2.3 % at 2) that the pattern exceeds what is worth
#: naming, not only that it differs from zero.
RELEVANCE_Z = 2.0
#: A finding whose size has at least this one-sided p under the fitted model's null is
#: covered by it.
COVERED_P = 0.05

# -- naming from the band spectrum ----------------------------------------------------------

#: The family-wise level of a diagnosis (``DiagnoseOptions.significance``'s default): the
#: model-free tests and the effects fitted are each held to it over their number
#: (Bonferroni).
SIGNIFICANCE = 0.01
#: When no candidate closes the band gap to noise, the nearest one removing at least this share
#: of the excess misfit makes the verdict a model-form difference (the gap has nearly that
#: effect's form) rather than an unexplained gap; it is never named.
CLOSES_MOST = 0.9
#: An effect named from the band spectrum must have the lower end of its size's 95 %
#: interval at least this share of its typical size (``Effect.typical``).
RELEVANT_SHARE = 0.05
#: How many supported candidates that leave a significant misfit are fitted on until settled.
CONTENDERS = 2
#: How many of the next supported candidates the best one is paired with.
PAIR_PARTNERS = 2
#: A band counts as missed when its standardised residual exceeds this (in σ).
MISSED_Z = 3.0
#: diagnose warns when re-fitting a and T_b without effects lowers the identification's cost
#: below this share of it (the identification had not found the model's best fit).
REFIT_WARN_RATIO = 0.5


def misses(p_value: float, significance: float) -> bool:
    """A χ² with this ``p_value`` is a significant misfit at ``significance``."""
    return bool(p_value < significance)


# -- pairs of effects -------------------------------------------------------------------------

#: What joins the names of effects fitted together.
PAIR_JOIN = "+"


def pair_name(*effects: str) -> str:
    """The name of ``effects`` fitted together (``"runout+flank_friction"``)."""
    return PAIR_JOIN.join(effects)


def effects_of(name: str) -> tuple[str, ...]:
    """The effects a candidate's ``name`` stands for: one, or each of a pair."""
    return tuple(name.split(PAIR_JOIN))


def is_pair(name: str) -> bool:
    """``name`` is a candidate of several effects fitted together."""
    return len(effects_of(name)) > 1


# -- which effects are tried ----------------------------------------------------------------


class Skipped(enum.StrEnum):
    """Why an effect was not fitted to the band spectrum (worded by
    :func:`rattlefit.report.wording.skipped_sentence`)."""

    #: the encoders see it, and its model-free test finds no sign of it
    NOT_SEEN = "not_seen"
    #: it is named only when its model-free test finds it, and the test finds none
    NOT_FOUND = "not_found"
    #: the model without effects fits the band spectrum within its noise
    NO_BAND_GAP = "no_band_gap"


def in_program(effects: Sequence[str], seen, every_effect: bool = False) -> tuple[str, ...]:
    """The candidates the compiled program holds: every one of ``effects`` but those the
    encoders see (:data:`ENCODER_VISIBLE`) and did not (``seen``), unless ``every_effect``."""
    if every_effect:
        return tuple(effects)
    return tuple(n for n in effects if n not in ENCODER_VISIBLE or n in seen)


def effects_to_try(
    effects: Sequence[str], seen, band_gap: bool, every_effect: bool = False
) -> tuple[list[str], dict[str, Skipped]]:
    """The effects fitted to the band spectrum, and why each other one is not: an effect
    named only when found (:data:`FOUND_ONLY`) is tried only when its test found it
    (``seen``), and a band candidate only explains a significant band gap (``band_gap``);
    ``every_effect`` tries all."""
    tried, skipped = [], {}
    for name in effects:
        if every_effect:
            tried.append(name)
        elif name in ENCODER_VISIBLE and name not in seen:
            skipped[name] = Skipped.NOT_SEEN
        elif name in FOUND_ONLY and name not in seen:
            skipped[name] = Skipped.NOT_FOUND
        elif name not in FOUND_ONLY and not band_gap:
            skipped[name] = Skipped.NO_BAND_GAP
        else:
            tried.append(name)
    return tried, skipped
