"""A diagnosis in words: its findings, the sizes of what it names, its verdict in one
sentence. The decisions are :func:`rattlefit.diagnosis.verdict.decide`'s; this module only
words them."""

from __future__ import annotations

from ..confidence import CHI2_1_95, Z95_ONE_SIDED
from ..diagnosis.evidence import Finding
from ..diagnosis.outcome import EffectOutcome
from ..diagnosis.policy import Skipped
from ..diagnosis.result import Caveat, Diagnosis
from ..features.orders import AngleTest
from ..inference.least_squares import LM_REJECTIONS
from ..inference.outcome import SearchOutcome
from ..physics.effects import effect_class, mechanism_of
from ..problem.options import unfinished_fit_advice


def finding_size(t: AngleTest) -> str:
    """A model-free test's size: a drift's change, a drive ripple's acceleration amplitude
    and order, or a pattern's gap error in µm with its standard error."""
    if t.name == "drift":
        return f"{t.detail.get('statistic')} changes by {t.amplitude:+.3g}"
    if t.name == "drive_order":
        return f"{t.amplitude:.3g} rad/s² at order {t.detail.get('order')}"
    return f"{1e6 * t.amplitude:.1f} ± {1e6 * t.amplitude_sd:.1f} µm"


def finding_phrase(f: Finding) -> str:
    """One finding in words, e.g. ``runout (runout.secondary: 40.2 ± 2.7 µm, p = 4e-192)``."""
    return f"{f.effect} ({f.test.name}: {finding_size(f.test)}, p = {f.test.p_value:.2g})"


def typical_phrase(effect: str, value: float) -> str:
    """``value`` of ``effect``'s size against its typical size (``Effect.typical``), e.g.
    ``3.2 × the typical 0.05 [a mean friction coefficient …]``; empty without one."""
    typical = effect_class(effect).typical
    if typical is None:
        return ""
    size, source = typical
    return f", {value / size:.2g} × the typical {size:.3g} [{source}]"


def interval_label(caveat: bool) -> str:
    """What a size's interval is called: ``95 %``, or with an ``interval_caveat`` the fit's
    precision."""
    return "the fit's precision, not a 95 % interval" if caveat else "95 %"


def size_phrase(o: EffectOutcome) -> str:
    """The fitted sizes of ``o`` that have an interval, each against its typical size, e.g.
    ``coefficient 0.16 (95 %: 0.05–0.4), 3.2 × the typical 0.05 […]`` (lengths in
    µm); with an ``interval_caveat`` the interval is called the fit's precision."""
    parts = []
    for key, value in o.values.items():
        if key not in o.intervals:
            continue
        lo, hi = o.intervals[key]
        unit, scale = ("µm", 1e6) if o.units[key] == "m" else (o.units[key], 1.0)
        unit = "" if unit == "1" else f" {unit}"
        effect = key.split(".", 1)[0] if "." in key else o.name
        span = interval_label(bool(o.interval_caveat))
        parts.append(
            f"{key} {scale * value:.3g}{unit} ({span}: {scale * lo:.3g}–{scale * hi:.3g})"
            + typical_phrase(effect, value)
        )
    return "; ".join(parts)


def too_small_words(diag: Diagnosis) -> str:
    """The clause on the candidates that close the band gap only at a size the band
    spectrum cannot tell from none (their interval reaches below the relevance floor), or
    empty."""
    small = [o for o in diag.outcomes if o.intervals and not o.relevant]
    if not small:
        return ""
    return "; " + "; ".join(
        f"{o.name} closes it only at a size that cannot be told from none ({size_phrase(o)})"
        for o in small
    )


def fit_words(diag: Diagnosis) -> str:
    """The band fit of the model without effects, e.g. ``χ² 56.2 on 28 dof, p = 0.0012``."""
    chi2, dof, p = diag.gap_chi2
    return f"χ² {chi2:.1f} on {dof} dof, p = {p:.2g}"


def cycle_words(diag: Diagnosis) -> str:
    """Where the drive-cycle statistics miss, or empty when they do not."""
    if not diag.cycle_missed:
        return ""
    return (
        f"the drive-cycle statistics miss: {diag.drive_cycle.phrase()} "
        f"(p = {diag.drive_cycle.p_value:.2g})"
    )


def unexplained_gap(diag: Diagnosis) -> str:
    """The sentence, without its full stop, of a significant band gap that no candidate is
    named for: candidates of different mechanisms close it alike, or none closes it (the
    least misfit any leaves is given)."""
    cycle = f"; {cycle_words(diag)}" if diag.cycle_missed else ""
    alike = diag.verdict.indistinguishable
    if alike:
        names = ", ".join(o.name for o in alike[:-1]) + f" and {alike[-1].name}"
        left = ", ".join(f"{o.chi2_with:.1f}" for o in alike)
        return (
            f"A significant gap that candidates of different mechanisms close alike: "
            f"{fit_words(diag)}; {names} each leave a misfit within the noise, or as small as "
            f"the least within the Monte Carlo noise (χ² {left}), so the band spectrum cannot "
            f"tell them apart, nor from a model-form difference{cycle}"
        )
    judged = [o for o in diag.outcomes if not o.failure]
    best = min(judged, key=lambda o: o.chi2_with, default=None)
    tried = (
        ""
        if best is None
        else f"; the candidate that leaves the least misfit, {best.name}, leaves "
        f"χ² {best.chi2_with:.1f} (p = {best.p_after:.2g})"
    )
    return (
        f"A significant gap that no candidate explains: {fit_words(diag)}{tried}"
        f"{too_small_words(diag)}{cycle}"
    )


def explaining_phrase(diag: Diagnosis) -> str:
    """The band candidate the verdict names, its size and the share of the misfit it
    closes."""
    o = diag.verdict.explaining
    size = f"{size_phrase(o)}; " if o.intervals else ""
    who = " and ".join(o.effects) + (" together" if len(o.effects) > 1 else "")
    return (
        f"{who} ({size}closes {100 * o.gap_closed:.0f} % of the band misfit: "
        f"χ² {o.chi2_without:.1f} → {o.chi2_with:.1f})"
    )


def fitted_sizes(o: EffectOutcome) -> str:
    """The fitted values of ``o`` in words, e.g. ``coefficient 0.227`` (lengths in µm)."""
    parts = []
    for key, value in o.values.items():
        unit, scale = ("µm", 1e6) if o.units.get(key) == "m" else (o.units.get(key, "1"), 1.0)
        parts.append(f"{key} {scale * value:.3g}" + ("" if unit == "1" else f" {unit}"))
    return ", ".join(parts)


def model_form_gap(diag: Diagnosis) -> str:
    """The sentence, without its full stop, of a model-form difference: the gap, the
    catalogue effect that comes nearest, how much of it that closes and what it leaves."""
    o = diag.verdict.nearest
    who = " and ".join(o.effects) + (" together" if len(o.effects) > 1 else "")
    kinds = sorted({mechanism_of(n) for n in o.effects} - set(o.effects))
    who += f" ({', '.join(kinds)})" if kinds else ""
    size = f" at {fitted_sizes(o)}" if o.values else ""
    cycle = f"; {cycle_words(diag)}" if diag.cycle_missed else ""
    return (
        f"A model-form difference: the model without extra effects misses the band spectrum "
        f"({fit_words(diag)}); the nearest effect in the catalogue, {who}{size}, closes "
        f"{100 * o.gap_closed:.0f} % of the excess misfit (χ² {o.chi2_without:.1f} → "
        f"{o.chi2_with:.1f}) but leaves a significant rest (p = {o.p_after:.2g}), so it is not "
        f"named as the cause{cycle}"
    )


def contradicted_words(diag: Diagnosis) -> str:
    """The clause on the encoder findings the verdict does not name because fitting them
    worsens the band misfit, or empty."""
    names = diag.verdict.contradicted
    if not names:
        return ""
    return (
        f"; {' and '.join(names)}, which the model-free tests point to, is not named: "
        "fitting it worsens the band misfit"
    )


def verdict_sentence(diag: Diagnosis) -> str:
    """The verdict of ``diag`` (:attr:`~rattlefit.diagnosis.result.Diagnosis.verdict`) in one
    plain sentence."""
    v = diag.verdict
    if v.kind == "none" and v.contradicted:
        return (
            f"No significant gap: the model without extra effects fits the band spectrum "
            f"({fit_words(diag)}) and its drive-cycle statistics{contradicted_words(diag)}."
        )
    if v.kind == "none":
        return (
            f"No significant gap: the model without extra effects fits the band spectrum "
            f"({fit_words(diag)}), its drive-cycle statistics, and no angle- or time-domain "
            "test stands out."
        )
    if v.kind == "unexplained" and not v.band_gap:
        return (
            f"A gap that no candidate explains: the band spectrum fits ({fit_words(diag)}), "
            f"but {cycle_words(diag)}{contradicted_words(diag)}."
        )
    if v.kind == "unexplained":
        return unexplained_gap(diag) + contradicted_words(diag) + "."
    if v.kind == "model_form":
        return model_form_gap(diag) + contradicted_words(diag) + "."
    parts = [finding_phrase(f) for f in v.found]
    found = {f.effect for f in v.found}
    if v.explaining is not None and not set(v.explaining.effects) <= found:
        parts.append(explaining_phrase(diag))
    sentence = "Found " + " and ".join(parts)
    if v.band_gap and v.explaining is None:
        sentence += f"; the band misfit ({fit_words(diag)}) remains unexplained"
    return sentence + contradicted_words(diag) + "."


def caveat_sentence(caveat: str, refit: dict, options: dict) -> str:
    """A :class:`~rattlefit.diagnosis.result.Caveat` (or its JSON value) in words, with the
    diagnosis document's ``refit`` costs and the identification's ``options``
    (:meth:`~rattlefit.problem.options.FitOptions.to_dict`) for the advice."""
    if Caveat(caveat) is Caveat.UNFINISHED:
        return (
            "the identification stopped at its step limit, so the model without effects may "
            "fit better than it does here and an effect may be credited with that; "
            + unfinished_fit_advice(options)
            + "."
        )
    return (
        "the identification was far from the model's best fit: re-fitting a and T_b "
        f"without effects lowered its cost from {refit['cost_identified']:.1f} to "
        f"{refit['cost']:.1f}; the effects are judged against the re-fit."
    )


def diagnosis_caveats(doc: dict) -> list[str]:
    """Every caveat of a diagnosis document (:meth:`~rattlefit.diagnosis.result.Diagnosis.
    to_json`) in words."""
    options = doc["baseline"].get("options", {})
    return [caveat_sentence(c, doc["refit"], options) for c in doc.get("warnings", [])]


def skipped_sentence(effect: str, reason: str) -> str:
    """Why ``effect`` was not fitted to the band spectrum, in words, from its
    :class:`~rattlefit.diagnosis.policy.Skipped` ``reason`` (or that reason's JSON value)."""
    reason = Skipped(reason)
    if reason is Skipped.NOT_SEEN:
        return "the encoders show no sign of it"
    if reason is Skipped.NOT_FOUND:
        if effect_class(effect).evidence == "drift":
            return "the recording shows no drift (its trend test finds none)"
        return "its model-free test finds no sign of it"
    return "the model without effects fits the band spectrum within its noise"


def diagnosis_document(diag: Diagnosis) -> dict:
    """The JSON document of ``diag`` (:meth:`~rattlefit.diagnosis.result.Diagnosis.to_json`)
    with its verdict's sentence (:func:`verdict_sentence`): what ``rattlefit diagnose -o``
    writes."""
    doc = diag.to_json()
    return {**doc, "sentence": verdict_sentence(diag)}


def search_sentence(search: dict) -> str:
    """How a fit's search ended, in words, from its JSON form
    (:meth:`rattlefit.inference.outcome.SearchEnd.to_dict`)."""
    outcome = SearchOutcome(search["outcome"])
    runs, stalled = int(search.get("runs", 1)), int(search.get("stalled_runs", 0))
    if outcome is SearchOutcome.STEP_LIMIT:
        text = "stopped at its step limit"
    elif outcome is SearchOutcome.STALLED:
        text = (
            f"converged ({stalled} of {runs} runs stalled at the cost's noise: "
            f"{LM_REJECTIONS} trial steps in a row rejected)"
        )
    else:
        text = "converged"
    recentred = int(search.get("recentred", 0))
    return text + (f"; re-centred {recentred}× on the profiles' minimum" if recentred else "")


def profile_sentence(profile: dict) -> str:
    """How the 95 % intervals' profile thresholds were set (the fit JSON's ``fit.profile``):
    on the learned likelihood, critical values by simulation (χ²₁'s 3.84 without them); on
    the synthetic one, χ²₁'s 3.84 plus an allowance for the cost's Monte Carlo noise."""
    if profile.get("likelihood") == "learned":
        calibration = profile.get("calibration")
        if calibration is None:
            return (
                f"95 % intervals: where the profile cost is within {profile['threshold']:.2f} "
                "of the optimum's (χ²₁; the learned likelihood is smooth and has no Monte "
                "Carlo noise)"
            )
        values = ", ".join(f"{k} {v:.1f}" for k, v in profile["thresholds"].items())
        return (
            "95 % intervals: where the profile cost is within its critical value of the "
            f"optimum's, set so that each holds its truth in 95 % of "
            f"{calibration['simulations']} recordings simulated near the optimum "
            f"(χ²₁: {CHI2_1_95:.2f}): {values}"
        )
    if "monte_carlo_sd" not in profile:
        return (
            f"95 % intervals: where the profile cost is within {profile['threshold']:.1f} of "
            "the optimum's (χ²₁'s 3.84 plus an allowance for the Monte Carlo noise and "
            "roughness of the cost)"
        )
    sd, source = profile["monte_carlo_sd"], "the Monte Carlo noise of a cost difference"
    rough = profile.get("roughness_sd", profile.get("roughness_rms", 0.0))
    if rough > sd:
        sd = rough
        if "roughness_sd" in profile:
            source = (
                "the cost's spread 1–2 % from the optimum over "
                f"{profile['realisation_sets']} realisation sets"
            )
        else:
            source = "the cost's roughness (rms) 1–2 % from the optimum"
    return (
        f"95 % intervals: where the profile cost is within {profile['threshold']:.1f} of the "
        f"optimum's (χ²₁ {CHI2_1_95:.2f} + {Z95_ONE_SIDED} × {sd:.1f}, {source})"
    )


def profile_thresholds(profile: dict) -> float | dict | None:
    """What the profile plot draws as each parameter's 95 % threshold: the critical values by
    name where the fit set them by simulation, else the one threshold (None: none)."""
    return profile.get("thresholds", profile.get("threshold"))
