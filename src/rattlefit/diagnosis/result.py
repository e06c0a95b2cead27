"""What a diagnosis returns: each effect's outcome, the model-free findings, the verdict."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import stats

from ..inference.result import FitResult
from ..physics.effects import mechanism_of
from .cycle_gap import CycleGap
from .evidence import FOUND_ONLY, Finding

#: A band counts as missed when its standardised residual exceeds this (in σ).
MISSED_Z = 3.0
#: diagnose warns when re-fitting a and T_b without effects lowers the identification's cost
#: below this share of it (the identification had not found the model's best fit).
REFIT_WARN_RATIO = 0.5
#: A supported candidate that removes at least this share of the excess band misfit
#: (``gap_closed``) explains the band gap even when what it leaves is still significant: the
#: diagnosis re-fits only a, T_b and the effect's size, with the other parameters held where
#: the identification put them without the effect, so a right effect can leave a remainder.
CLOSES_MOST = 0.9


@dataclasses.dataclass(frozen=True)
class EffectOutcome:
    """One effect tried on top of the identification.

    values : the fitted fields (SI, see ``units``); at the lower end of a range the effect is
        absent.
    chi2_without, chi2_with : χ² of the data rows after re-fitting without and with it.
    delta_chi2 : their difference (positive: the effect explains part of the misfit).
    gap_closed : share of the excess misfit (χ² − dof) removed, in [0, 1] (0 when there is
        no excess).
    p_value : F-test of ``delta_chi2`` against the misfit that remains.
    noise_threshold : Monte Carlo noise of a χ² difference (95 % one-sided).
    supported : ``p_value`` < the significance over the number of effects tried, and
        ``delta_chi2`` > ``noise_threshold``.
    p_after : probability of a χ² at least ``chi2_with`` from noise alone (dof less the
        effect's fields): small when the effect leaves a significant misfit.
    moves : how the free parameters move once the effect is in: name → (without, with), SI.
    residuals : (R, B) standardised band residuals with the effect.
    failure : why the effect could not be judged (its simulation failed at the fitted
        point, so ``chi2_with`` is not finite); empty when it was judged. A failed effect is
        never supported.
    intervals : 95 % intervals (SI) of the effect's size (its first field), from a profile
        of the χ² over it (:mod:`rattlefit.diagnosis.size`): key → (lower, upper); computed
        for the effects a verdict names (whose ``values`` then hold the profile's estimate),
        empty otherwise.

    Two effects fitted together have the name ``"<effect>+<effect>"``, their values keyed
    ``"<effect>.<field>"``, and:

    p_beyond : F-test p of their χ² against their better member's alone.
    beyond_single : ``p_beyond`` below the level and the drop above the Monte Carlo noise:
        the second effect removes a significant part of what the first leaves.
    """

    name: str
    values: dict[str, float]
    units: dict[str, str]
    chi2_without: float
    chi2_with: float
    delta_chi2: float
    gap_closed: float
    p_value: float
    noise_threshold: float
    supported: bool
    residuals: np.ndarray
    wall_time: float
    p_after: float = 1.0
    moves: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    failure: str = ""
    intervals: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    p_beyond: float = float("nan")
    beyond_single: bool = False

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects in this outcome: one, or two fitted together."""
        return tuple(self.name.split("+"))

    def size_phrase(self) -> str:
        """The fitted sizes that have an interval, e.g. ``coefficient 0.16 (95 %: 0.05–0.4)``
        (lengths in µm)."""
        parts = []
        for key, value in self.values.items():
            if key not in self.intervals:
                continue
            lo, hi = self.intervals[key]
            unit, scale = ("µm", 1e6) if self.units[key] == "m" else (self.units[key], 1.0)
            unit = "" if unit == "1" else f" {unit}"
            parts.append(
                f"{key} {scale * value:.3g}{unit} (95 %: {scale * lo:.3g}–{scale * hi:.3g})"
            )
        return "; ".join(parts)

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["parameters"] = {
            k: {"value": v, "unit": self.units[k]} for k, v in d.pop("values").items()
        }
        d.pop("units")
        d["residuals"] = None if self.failure else np.asarray(self.residuals).tolist()
        d["intervals"] = {k: list(v) for k, v in self.intervals.items()}
        for k in ("chi2_with", "delta_chi2", "p_value", "noise_threshold", "p_after", "p_beyond"):
            d[k] = d[k] if np.isfinite(d[k]) else None  # JSON has no NaN; null: not judged
        d["moves"] = {k: {"without": a, "with": b} for k, (a, b) in self.moves.items()}
        return d


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """What :func:`diagnose` returns: the gap and the effects, best first."""

    baseline: FitResult
    residuals: np.ndarray  # (R, B) standardised residuals of the identification
    band_centers: np.ndarray
    band_edges: np.ndarray
    outcomes: list[EffectOutcome]
    seed: int
    wall_time: float
    refit_costs: tuple[float, float]  # cost at the identification, after the re-fit
    warnings: tuple[str, ...] = ()
    #: the model-free tests of every recording (:func:`~rattlefit.diagnosis.evidence.findings`)
    findings: tuple[Finding, ...] = ()
    #: the family-wise level of the diagnosis (:attr:`DiagnoseOptions.significance`)
    significance: float = 0.01
    #: χ² of the model without effects after the re-fit, on the fresh realisations of the
    #: effects' comparison (NaN: not measured; the identification's χ² is used instead)
    chi2_without: float = float("nan")
    #: effects not fitted to the band spectrum, and why
    skipped: dict[str, str] = dataclasses.field(default_factory=dict)
    #: what a seeded result depends on (:func:`~rattlefit.reproducibility.platform_info`),
    #: captured when the diagnosis ran
    platform: dict = dataclasses.field(default_factory=dict, compare=False)
    #: the drive-cycle statistics against the model without effects
    #: (:func:`~rattlefit.diagnosis.cycle.cycle_gap`); None: not compared
    drive_cycle: CycleGap | None = None

    @property
    def cycle_missed(self) -> bool:
        """The drive-cycle statistics miss somewhere beyond their family-wise threshold."""
        return self.drive_cycle is not None and self.drive_cycle.significant

    @property
    def missed_bands(self) -> list[dict]:
        """Bands whose standardised residual exceeds :data:`MISSED_Z`: recording index,
        band edges (Hz) and residual (positive: the recording has more power)."""
        out = []
        for k, row in enumerate(np.asarray(self.residuals)):
            for b in np.flatnonzero(np.abs(row) > MISSED_Z):
                lo, hi = self.band_edges[b], self.band_edges[b + 1]
                out.append({"recording": k, "band_hz": [float(lo), float(hi)], "z": float(row[b])})
        return out

    @property
    def gap_chi2(self) -> tuple[float, int, float]:
        """χ², dof and p of the model without extra effects: after the re-fit, on the fresh
        realisations every effect is judged on (the identification's own when not
        measured)."""
        dof = self.baseline.dof
        if np.isfinite(self.chi2_without):
            return self.chi2_without, dof, float(stats.chi2.sf(self.chi2_without, dof))
        return self.baseline.chi2, dof, self.baseline.p_value

    @property
    def band_gap(self) -> bool:
        """The model without extra effects misses the band spectrum: its χ² (:attr:`gap_chi2`)
        has p below the significance."""
        return bool(self.gap_chi2[2] < self.significance)

    @property
    def seen(self) -> frozenset[str]:
        """The effects that significant model-free tests point to."""
        return frozenset(f.effect for f in self.findings if f.significant)

    @property
    def seen_in_bands(self) -> frozenset[str]:
        """The effects of :attr:`seen` that were also fitted to the band spectrum (and whose
        fit did not fail): the encoders show them present, so a band explanation must hold
        them."""
        fitted = {o.name for o in self.outcomes if not o.failure and "+" not in o.name}
        return self.seen & fitted

    def nameable(self, o: EffectOutcome) -> bool:
        """``o`` could be named: supported; for an effect with a model-free test
        (:data:`~rattlefit.diagnosis.evidence.FOUND_ONLY`), found by that test too; holding
        every effect of :attr:`seen_in_bands` (another effect is named beside a seen one only
        when the two together close clearly more than the seen one alone); two effects
        together only when they close clearly more than the better alone
        (``beyond_single``)."""
        return (
            o.supported
            and all(n not in FOUND_ONLY or n in self.seen for n in o.effects)
            and self.seen_in_bands <= set(o.effects)
            and (len(o.effects) == 1 or o.beyond_single)
        )

    def within_noise(self, o: EffectOutcome) -> bool:
        """``o`` is nameable (:meth:`nameable`) and leaves a misfit consistent with noise."""
        return self.nameable(o) and not o.failure and o.p_after >= self.significance

    def closing(self) -> EffectOutcome | None:
        """The band candidate that closes the band gap best: nameable (:meth:`nameable`),
        leaving a misfit consistent with noise (``p_after`` ≥ significance) or removing at
        least :data:`CLOSES_MOST` of the excess misfit; the least misfit first; None when
        there is no band gap or no candidate closes it."""
        if not self.band_gap:
            return None
        closing = [
            o
            for o in self.outcomes
            if self.nameable(o) and (o.p_after >= self.significance or o.gap_closed >= CLOSES_MOST)
        ]
        return min(closing, key=lambda o: o.chi2_with) if closing else None

    def rivals(self) -> list[EffectOutcome]:
        """Nameable candidates of another mechanism than :meth:`closing`'s
        (:func:`~rattlefit.physics.effects.mechanism_of`) that also leave a misfit consistent
        with noise: the band spectrum cannot tell them from it."""
        best = self.closing()
        if best is None:
            return []
        held = {mechanism_of(n) for n in best.effects}
        return [
            o
            for o in self.outcomes
            if o is not best
            and self.within_noise(o)
            and not {mechanism_of(n) for n in o.effects} <= held
        ]

    def indistinguishable(self) -> list[EffectOutcome]:
        """When there are :meth:`rivals`: the candidate that closes the band gap and every
        other nameable one that leaves a misfit consistent with noise, the least misfit first
        (empty otherwise)."""
        if not self.rivals():
            return []
        best = self.closing()
        alike = [o for o in self.outcomes if o is not best and self.within_noise(o)]
        return [best, *sorted(alike, key=lambda o: o.chi2_with)]

    def explaining(self) -> EffectOutcome | None:
        """The band candidate that explains the band gap: the one that closes it
        (:meth:`closing`) when no candidate of another mechanism also leaves a misfit
        consistent with noise (:meth:`rivals`): a gap that several physics close alike is
        a model-form difference as likely as any of them. None otherwise."""
        return None if self.rivals() else self.closing()

    @property
    def verdict(self) -> Verdict:
        """What the diagnosis concludes (:class:`Verdict`)."""
        return verdict_of(self)

    def to_json(self) -> dict:
        v = self.verdict
        return {
            "verdict": v.label,
            "verdict_kind": v.kind,
            "verdict_effects": list(v.effects),
            "sentence": v.sentence,
            "band_gap": v.band_gap,
            "gap_chi2": dict(zip(("chi2", "dof", "p_value"), self.gap_chi2, strict=True)),
            "band_gap_explained": v.band_gap_explained,
            "indistinguishable": [o.name for o in self.indistinguishable()],
            "significance": self.significance,
            "findings": [f.as_dict() for f in self.findings],
            "skipped": dict(self.skipped),
            "baseline": {
                "chi2": self.baseline.chi2,
                "dof": self.baseline.dof,
                "p_value": self.baseline.p_value,
                "converged": self.baseline.success,
                "parameters": {k: p.as_dict() for k, p in self.baseline.parameters.items()},
            },
            "band_centers_hz": np.asarray(self.band_centers).tolist(),
            "residuals": np.asarray(self.residuals).tolist(),
            "missed_bands": self.missed_bands,
            "drive_cycle": None if self.drive_cycle is None else self.drive_cycle.as_dict(),
            "effects": [o.as_dict() for o in self.outcomes],
            "refit": {"cost_identified": self.refit_costs[0], "cost": self.refit_costs[1]},
            "warnings": list(self.warnings),
            "seed": self.seed,
            "platform": self.platform,  # seeded results depend on it
            "wall_time_s": self.wall_time,
            "recordings": self.baseline.recordings,
        }


def baseline_warnings(converged: bool, cost_identified: float, cost_refit: float) -> list[str]:
    """Why a verdict against this identification may mislead: it stopped at its step limit,
    or re-fitting a and T_b without effects lowered its cost below :data:`REFIT_WARN_RATIO`
    of it. An effect tried against an unfinished identification can be credited with what
    finishing the fit of the model without effects would gain."""
    out = []
    if not converged:
        out.append(
            "the identification stopped at its step limit, so the model without effects may "
            "fit better than it does here and an effect may be credited with that; a full "
            "identification (without --quick) is the safer start."
        )
    if cost_refit < REFIT_WARN_RATIO * cost_identified:
        out.append(
            f"the identification was far from the model's best fit: re-fitting a and T_b "
            f"without effects lowered its cost from {cost_identified:.1f} to {cost_refit:.1f}"
            "; the effects are judged against the re-fit."
        )
    return out


def gap_closed(chi2_without: float, chi2_with: float, dof: int) -> float:
    """Share of the excess misfit χ² − dof that the effect removes, in [0, 1]; 0 when there
    is no excess (the model without the effect already explains the data)."""
    excess = chi2_without - dof
    if excess <= 0:
        return 0.0
    return float(np.clip((chi2_without - chi2_with) / excess, 0.0, 1.0))


@dataclasses.dataclass(frozen=True)
class Verdict:
    """The diagnosis' conclusion.

    kind : ``"none"`` (no significant gap in any domain), ``"unexplained"`` (a significant
        gap, in the band spectrum or the drive-cycle statistics, that no candidate
        explains), ``"effect"`` or ``"effects"`` (one or two named).
    effects : the named effects, model-free findings first.
    band_gap : the band spectrum misses significantly without extra effects.
    band_gap_explained : a band candidate closes that gap.
    sentence : the conclusion in one plain sentence.
    """

    kind: str
    effects: tuple[str, ...]
    band_gap: bool
    band_gap_explained: bool
    sentence: str

    @property
    def label(self) -> str:
        """``"none"``, ``"unexplained"`` or the effects joined by ``+``."""
        return "+".join(self.effects) if self.effects else self.kind


def found_effects(findings) -> list[tuple[str, Finding]]:
    """The effects that significant findings name, each with its most significant finding."""
    best: dict[str, Finding] = {}
    for f in sorted(findings, key=lambda f: f.test.p_value):
        if f.significant and f.effect not in best:
            best[f.effect] = f
    return list(best.items())


def finding_phrase(f: Finding) -> str:
    """One finding in words, e.g. ``runout (runout.secondary: 40.2 ± 2.7 µm, p = 4e-192)``."""
    t = f.test
    if t.name == "drift":
        size = f"{t.detail.get('statistic')} changes by {t.amplitude:+.3g}"
    elif t.name == "drive_order":
        size = f"{t.amplitude:.3g} rad/s² at order {t.detail.get('order')}"
    else:
        size = f"{1e6 * t.amplitude:.1f} ± {1e6 * t.amplitude_sd:.1f} µm"
    return f"{f.effect} ({t.name}: {size}, p = {t.p_value:.2g})"


def unexplained_gap(diag: Diagnosis, fit_words: str, cycle_words: str) -> str:
    """The sentence of a significant band gap that no candidate is named for: candidates of
    different mechanisms close it alike (:meth:`Diagnosis.indistinguishable`), or none
    closes it (the least misfit any leaves is given)."""
    cycle = f"; {cycle_words}" if cycle_words else ""
    alike = diag.indistinguishable()
    if alike:
        names = ", ".join(o.name for o in alike[:-1]) + f" and {alike[-1].name}"
        left = ", ".join(f"{o.chi2_with:.1f}" for o in alike)
        return (
            f"A significant gap that candidates of different mechanisms close alike: "
            f"{fit_words}; {names} each leave a misfit within the noise (χ² {left}), so the "
            f"band spectrum cannot tell them apart, nor from a model-form difference{cycle}."
        )
    judged = [o for o in diag.outcomes if not o.failure]
    best = min(judged, key=lambda o: o.chi2_with, default=None)
    tried = (
        ""
        if best is None
        else f"; the candidate that leaves the least misfit, {best.name}, leaves "
        f"χ² {best.chi2_with:.1f} (p = {best.p_after:.2g})"
    )
    return f"A significant gap that no candidate explains: {fit_words}{tried}{cycle}."


def verdict_of(diag: Diagnosis) -> Verdict:
    """The :class:`Verdict` of ``diag``: effects named by significant model-free findings,
    then the band candidate that explains the band gap (:meth:`Diagnosis.explaining`)."""
    chi2, dof, p = diag.gap_chi2
    found = found_effects(diag.findings)
    closing = diag.explaining()
    names = [name for name, _ in found]
    if closing is not None:
        names += [n for n in closing.effects if n not in names]
    fit_words = f"χ² {chi2:.1f} on {dof} dof, p = {p:.2g}"
    cycle_words = (
        f"the drive-cycle statistics miss: {diag.drive_cycle.phrase()} "
        f"(p = {diag.drive_cycle.p_value:.2g})"
        if diag.cycle_missed
        else ""
    )
    if not names and not diag.band_gap and not cycle_words:
        kind = "none"
        sentence = (
            f"No significant gap: the model without extra effects fits the band spectrum "
            f"({fit_words}), its drive-cycle statistics, and no angle- or time-domain test "
            "stands out."
        )
    elif not names and not diag.band_gap:
        kind = "unexplained"
        sentence = (
            f"A gap that no candidate explains: the band spectrum fits ({fit_words}), but "
            f"{cycle_words}."
        )
    elif not names:
        kind = "unexplained"
        sentence = unexplained_gap(diag, fit_words, cycle_words)
    else:
        kind = "effect" if len(names) == 1 else "effects"
        parts = [finding_phrase(f) for _, f in found]
        if closing is not None and not set(closing.effects) <= set(dict(found)):
            rest = "" if closing.p_after >= diag.significance else ", a significant rest"
            size = f"{closing.size_phrase()}; " if closing.intervals else ""
            who = " and ".join(closing.effects) + (" together" if len(closing.effects) > 1 else "")
            parts.append(
                f"{who} ({size}closes {100 * closing.gap_closed:.0f} % of the band misfit: "
                f"χ² {closing.chi2_without:.1f} → {closing.chi2_with:.1f}{rest})"
            )
        sentence = "Found " + " and ".join(parts)
        if diag.band_gap and closing is None:
            sentence += f"; the band misfit ({fit_words}) remains unexplained"
        sentence += "."
    return Verdict(kind, tuple(names), diag.band_gap, closing is not None, sentence)
