"""The verdict: which effects the evidence names, decided once from the judged outcomes.

:func:`decide` is a pure function of the effects' outcomes
(:class:`~rattlefit.diagnosis.outcome.EffectOutcome`), the model-free findings
(:class:`~rattlefit.diagnosis.evidence.Finding`) and whether the model without effects misses
the band spectrum and the drive-cycle statistics. Its wording is
:func:`rattlefit.report.verdict_sentence`'s.

The rules: the effects that significant model-free tests point to are named, unless fitting
one to the band spectrum worsens the misfit beyond the Monte Carlo noise (:func:`contradicted`);
a band candidate is named when it is *nameable* (:func:`nameable`), closes the band gap (the
misfit it leaves is consistent with the model's simulated null: ``p_after`` at least the
significance) and no candidate of another mechanism also leaves a misfit consistent with
noise, or one as small within the Monte Carlo noise of a χ² difference (:func:`rivals`): a gap
that several physics close alike is a model-form difference as likely as any of them. When no
candidate closes the gap, the one that comes nearest (:func:`nearest`) is reported, not named;
if it removes at least :data:`~.policy.CLOSES_MOST` of the excess misfit the verdict is a
*model-form difference*: the gap has nearly that effect's form, yet the effect as modelled
leaves a significant rest. The thresholds are :mod:`rattlefit.diagnosis.policy`'s.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from ..physics.effects import mechanism_of
from .evidence import Finding
from .outcome import EffectOutcome
from .policy import CLOSES_MOST, FOUND_ONLY, is_pair, pair_name


@dataclasses.dataclass(frozen=True)
class Evidence:
    """What every candidate is judged against.

    findings : the model-free tests of every recording.
    band_gap : the model without extra effects misses the band spectrum significantly.
    cycle_missed : it misses the drive-cycle statistics beyond their family-wise threshold.
    significance : the family-wise level (a candidate leaves noise when its ``p_after`` is
        at least this).
    """

    findings: tuple[Finding, ...] = ()
    band_gap: bool = False
    cycle_missed: bool = False
    significance: float = 0.01

    @property
    def seen(self) -> frozenset[str]:
        """The effects that significant model-free tests point to."""
        return frozenset(f.effect for f in self.findings if f.significant)


#: The verdict kinds that name no effect: what a recording without a missing effect should get.
NAMES_NOTHING = ("none", "unexplained", "model_form")


@dataclasses.dataclass(frozen=True)
class Verdict:
    """The diagnosis' conclusion.

    kind : ``"none"`` (no significant gap in any domain), ``"model_form"`` (a significant band
        gap that the :attr:`nearest` candidate nearly closes, removing at least
        :data:`~.policy.CLOSES_MOST` of it, but not to noise), ``"unexplained"`` (a
        significant gap, in the band spectrum or the drive-cycle statistics, that no
        candidate explains nor nearly closes), ``"effect"`` or ``"effects"`` (one or two
        named).
    effects : the named effects, model-free findings first.
    found : the most significant finding of each effect the model-free tests name.
    explaining : the band candidate that explains the band gap, or None.
    contradicted : effects a significant finding points to that are not named, because
        fitting them worsens the band misfit (:func:`contradicted`).
    indistinguishable : when candidates of different mechanisms close the gap alike, the one
        that closes it best and each other one that leaves noise, the least misfit first.
    band_gap, cycle_missed : as in :class:`Evidence`.
    nearest : when a band gap is left that no candidate closes and none are indistinguishable,
        the nameable candidate that leaves the least misfit (:func:`nearest`), or None. It is
        reported with how much of the gap it closes, never named.
    """

    kind: str
    effects: tuple[str, ...]
    found: tuple[Finding, ...]
    explaining: EffectOutcome | None
    indistinguishable: tuple[EffectOutcome, ...]
    band_gap: bool
    cycle_missed: bool
    contradicted: tuple[str, ...] = ()
    nearest: EffectOutcome | None = None

    @property
    def label(self) -> str:
        """One of :data:`NAMES_NOTHING`, or the named effects joined by ``+``."""
        return pair_name(*self.effects) if self.effects else self.kind

    @property
    def band_gap_explained(self) -> bool:
        """A band candidate closes the band gap."""
        return self.explaining is not None


def found_effects(findings: Sequence[Finding]) -> list[tuple[str, Finding]]:
    """The effects that significant findings name, each with its most significant finding."""
    best: dict[str, Finding] = {}
    for f in sorted(findings, key=lambda f: f.test.p_value):
        if f.significant and f.effect not in best:
            best[f.effect] = f
    return list(best.items())


def contradicted(name: str, outcomes: Sequence[EffectOutcome]) -> bool:
    """Fitting effect ``name`` alone to the band spectrum made the misfit worse by more than
    the Monte Carlo noise of a χ² difference: the band spectrum speaks against it."""
    return any(
        o.name == name and not o.failure and -o.delta_chi2 > o.noise_threshold for o in outcomes
    )


def seen_in_bands(outcomes: Sequence[EffectOutcome], evidence: Evidence) -> frozenset[str]:
    """The effects the model-free tests found that were also fitted to the band spectrum
    (and whose fit did not fail, nor worsened the misfit: :func:`contradicted`): the encoders
    show them present, so a band explanation must hold them."""
    fitted = {
        o.name
        for o in outcomes
        if not o.failure and not is_pair(o.name) and not contradicted(o.name, outcomes)
    }
    return evidence.seen & fitted


def nameable(o: EffectOutcome, outcomes: Sequence[EffectOutcome], evidence: Evidence) -> bool:
    """``o`` could be named: supported; of a relevant size (``o.relevant``: its interval, once
    profiled, stays above its relevance floor); for an effect with a model-free test
    (:data:`~.policy.FOUND_ONLY`), found by that test too; holding every
    effect of :func:`seen_in_bands` (another effect is named beside a seen one only when the
    two together close clearly more than the seen one alone); two effects together only when
    they close clearly more than the better alone (``beyond_single``)."""
    return (
        o.supported
        and o.relevant
        and all(n not in FOUND_ONLY or n in evidence.seen for n in o.effects)
        and seen_in_bands(outcomes, evidence) <= set(o.effects)
        and (len(o.effects) == 1 or o.beyond_single)
    )


def within_noise(o: EffectOutcome, outcomes: Sequence[EffectOutcome], evidence: Evidence) -> bool:
    """``o`` is nameable and leaves a misfit consistent with noise."""
    return nameable(o, outcomes, evidence) and not o.failure and o.p_after >= evidence.significance


def closing(outcomes: Sequence[EffectOutcome], evidence: Evidence) -> EffectOutcome | None:
    """The band candidate that closes the band gap best: nameable and leaving a misfit
    consistent with noise (:func:`within_noise`), the least misfit first; None when there is
    no band gap or no candidate closes it."""
    if not evidence.band_gap:
        return None
    closes = [o for o in outcomes if within_noise(o, outcomes, evidence)]
    return min(closes, key=lambda o: o.chi2_with) if closes else None


def nearest(outcomes: Sequence[EffectOutcome], evidence: Evidence) -> EffectOutcome | None:
    """Where a band gap is left that no candidate closes (:func:`closing` None): the
    nameable candidate that leaves the least misfit, or None."""
    if not evidence.band_gap or closing(outcomes, evidence) is not None:
        return None
    near = [o for o in outcomes if not o.failure and nameable(o, outcomes, evidence)]
    return min(near, key=lambda o: o.chi2_with) if near else None


def alike(o: EffectOutcome, best: EffectOutcome) -> bool:
    """``o`` holds none of ``best``'s effects and leaves a misfit larger than ``best``'s by
    no more than the Monte Carlo noise of a χ² difference (``best.noise_threshold``): it
    closes the band gap as well, supported or not."""
    return (
        not o.failure
        and not set(o.effects) & set(best.effects)
        and o.chi2_with - best.chi2_with <= best.noise_threshold
    )


def as_good(
    o: EffectOutcome, best: EffectOutcome, outcomes: Sequence[EffectOutcome], evidence: Evidence
) -> bool:
    """``o`` (not ``best``) closes the band gap as well as ``best``: it leaves a misfit
    consistent with noise (:func:`within_noise`) or :func:`alike` ``best``'s."""
    return o is not best and (within_noise(o, outcomes, evidence) or alike(o, best))


def rivals(outcomes: Sequence[EffectOutcome], evidence: Evidence) -> list[EffectOutcome]:
    """Candidates of another mechanism than :func:`closing`'s
    (:func:`~rattlefit.physics.effects.mechanism_of`) that close the band gap as well
    (:func:`as_good`): the band spectrum cannot tell them from it."""
    best = closing(outcomes, evidence)
    if best is None:
        return []
    held = {mechanism_of(n) for n in best.effects}
    return [
        o
        for o in outcomes
        if as_good(o, best, outcomes, evidence) and not {mechanism_of(n) for n in o.effects} <= held
    ]


def indistinguishable(
    outcomes: Sequence[EffectOutcome], evidence: Evidence
) -> tuple[EffectOutcome, ...]:
    """When there are :func:`rivals`: the candidate that closes the band gap and every other
    one that closes it as well (:func:`as_good`), the least misfit first (empty
    otherwise)."""
    if not rivals(outcomes, evidence):
        return ()
    best = closing(outcomes, evidence)
    others = [o for o in outcomes if as_good(o, best, outcomes, evidence)]
    return (best, *sorted(others, key=lambda o: o.chi2_with))


def decide(outcomes: Sequence[EffectOutcome], evidence: Evidence) -> Verdict:
    """The :class:`Verdict` of ``outcomes`` against ``evidence``: the effects named by
    significant model-free findings, then the band candidate that explains the band gap
    (:func:`closing`, unless it has :func:`rivals`), else the one that comes nearest
    (:func:`nearest`)."""
    found = found_effects(evidence.findings)
    against = tuple(name for name, _ in found if contradicted(name, outcomes))
    found = [(name, f) for name, f in found if name not in against]
    alike = indistinguishable(outcomes, evidence)
    explaining = None if alike else closing(outcomes, evidence)
    near = None if alike else nearest(outcomes, evidence)
    names = [name for name, _ in found]
    if explaining is not None:
        names += [n for n in explaining.effects if n not in names]
    if names:
        kind = "effect" if len(names) == 1 else "effects"
    elif near is not None and near.gap_closed >= CLOSES_MOST:
        kind = "model_form"
    elif evidence.band_gap or evidence.cycle_missed:
        kind = "unexplained"
    else:
        kind = "none"
    return Verdict(
        kind=kind,
        effects=tuple(names),
        found=tuple(f for _, f in found),
        explaining=explaining,
        indistinguishable=alike,
        band_gap=evidence.band_gap,
        cycle_missed=evidence.cycle_missed,
        contradicted=against,
        nearest=near,
    )
