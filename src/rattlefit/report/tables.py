"""The text tables of an identification, a posterior and a diagnosis: what a person reads
first in a terminal."""

from __future__ import annotations

import numpy as np

from ..diagnosis.policy import MISSED_Z
from ..diagnosis.result import Diagnosis
from ..inference.posterior import Posterior
from ..inference.result import FitResult, below_optimum
from ..quantities import DRAG_TORQUE, FILM, VISCOSITY_SCALE, display
from .explain import below_optimum_sentence, parameter_rows
from .wording import (
    caveat_sentence,
    finding_size,
    profile_sentence,
    search_sentence,
    skipped_sentence,
    verdict_sentence,
)


#: The parameters the table shows first: the films, the drag torque, the viscosity and the
#: squeeze momenta; the nuisances follow in a block of their own.
def parameter_lines(parameters: dict[str, dict]) -> list[str]:
    """The fit JSON's ``parameters`` as text columns (:func:`~rattlefit.report.explain.
    parameter_rows`, as the HTML report shows them): the physical parameters, then the
    nuisances."""
    rows = [("parameter", "estimate", "95 % interval", "unit", "status")]
    shown = parameter_rows(parameters)
    for k, r in enumerate(shown):
        if k and not r.physical and shown[k - 1].physical:
            rows.append(("nuisances:", "", "", "", ""))
        rows.append((r.name, r.estimate, r.interval, r.unit, r.status))
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return [line.rstrip() for line in lines]


def format_table(result: FitResult) -> str:
    """The parameters as a readable table (:func:`parameter_lines`), the fit's statistics and
    notes, and what extra data would pin each parameter not identified."""
    parameters = result.estimates.parameters
    lines = parameter_lines({k: v.as_dict() for k, v in parameters.items()})
    advice = [f"to pin {n}: {p.would_pin}" for n, p in parameters.items() if p.would_pin]
    st, pr = result.statistics, result.provenance
    per = ""
    if len(st.chi2_recordings) > 1:
        per = " (" + " + ".join(f"{c:.1f}" for c in st.chi2_recordings) + " by recording)"
    search = "quasi-Newton" if pr.likelihood.get("method") == "learned" else ("Levenberg–Marquardt")
    state = search_sentence(st.search.to_dict())
    lines.append(
        f"χ² = {st.chi2:.1f}{per} on {st.dof} dof (p = {st.p_value:.2g}); "
        f"{search} {state} after {st.n_iterations} steps; seed {pr.seed}; "
        f"{pr.wall_time:.1f} s"
    )
    if "threshold" in result.estimates.profile:
        lines.append(profile_sentence(result.estimates.profile))
    lines += below_optimum_note(result.estimates.profiles)
    lines += advice
    for k, share in enumerate(st.regime_share):
        if share < 0.5:
            which = "the recording"
            if len(pr.recordings) > 1:
                which = pr.recording_names[k]
            lines.append(
                f"note: {which} is in a regime that {share:.0%} of the model's releases reach "
                "at the fitted parameters (the others settle into another); the fit compares it "
                "with that regime (FitOptions.regime), since which one a rig is on is its "
                "history's choice."
            )
    if st.poor_fit:
        which = "this recording"
        widened = f"√(χ²/dof) = {(st.chi2 / st.dof) ** 0.5:.1f}"
        if len(st.chi2_recordings) > 1:
            poor = [pr.recording_names[k] for k in st.poorly_fitted]
            which = ", ".join(poor) if poor else "these recordings together"
            widened = "each recording's own √(χ²/dof)"
        lines.append(
            f"warning: χ² is far above its {st.dof} degrees of freedom "
            f"(p = {st.p_value:.1e}): the model does not explain {which} within "
            f"its run-to-run spread. The intervals are widened by {widened} but may still "
            "miss; look at the spectrum plot (--plot)."
        )
    return "\n".join(lines)


def below_optimum_note(profiles: dict) -> list[str]:
    """The table's line saying how far the profiles reach below the optimum's cost
    (:func:`~rattlefit.inference.result.below_optimum`); none when they do not."""
    low = below_optimum(profiles)
    return [f"note: {below_optimum_sentence(low)}"] if low else []


def format_posterior(post: Posterior) -> str:
    """Credible intervals (median, 95 %), effective sample sizes and the chain's diagnostics."""
    rows = [("parameter", "median", "95 % credible interval", "unit", "ESS", "τ (steps)")]
    for (name, (med, lo, hi)), unit, ess, tau in zip(
        post.intervals().items(), post.units, post.ess, post.autocorr_time, strict=True
    ):
        mult, shown = display(name, unit)
        rows.append(
            (
                name,
                f"{med * mult:.4g}",
                f"[{lo * mult:.4g}, {hi * mult:.4g}]",
                shown,
                f"{ess:.0f}",
                f"{tau:.1f}",
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    lines = [line.rstrip() for line in lines]
    steps, walkers = post.chain.shape[:2]
    lines.append(
        f"{walkers} walkers × {steps} steps (first {post.discard} discarded); acceptance "
        f"{np.mean(post.acceptance):.2f}; {post.n_evaluations} points simulated; seed "
        f"{post.seed}; {post.wall_time:.1f} s"
    )
    if not post.reliable:
        lines.append(
            "note: the kept chain is shorter than 50 autocorrelation times, so τ and the ESS "
            "are rough; continue the chain (same --backend, more --steps) to firm them up."
        )
    return "\n".join(lines)


def _si(value: float, name: str, unit: str) -> str:
    mult, shown = display(name, unit)
    return f"{value * mult:.3g} {shown}".rstrip()


def _size_cell(o, key: str) -> str:
    """One fitted field of outcome ``o`` with its unit, and its interval where it has one."""
    unit = o.units[key]
    text = f"{key} {_si(o.values[key], key, unit)}"
    if key in o.intervals:
        lo, hi = o.intervals[key]
        mark = "*" if o.interval_caveat else ""  # the fit's precision, not a 95 % interval
        text += f" [{_si(lo, key, unit)} – {_si(hi, key, unit)}]{mark}"
    return text


def _level(diag: Diagnosis) -> float:
    return diag.findings[0].level if diag.findings else diag.significance


def cycle_lines(diag: Diagnosis) -> list[str]:
    """Where the model without effects misses the drive-cycle statistics, one line each."""
    cycle = diag.drive_cycle
    if cycle is None:
        return []
    if not cycle.significant:
        return [
            f"the drive-cycle statistics fit (largest |z| below {cycle.threshold:.2f}, "
            f"p = {cycle.p_value:.2g})"
        ]
    lines = [
        f"where in the drive cycle it misses (|z| > {cycle.threshold:.2f}, phase 0 = fastest):"
    ]
    for m in cycle.missed():
        lines.append(
            f"  recording {m['recording']}: {m['statistic']:12s} phase {m['phase']:.2f}  "
            f"z = {m['z']:+.1f}"
        )
    return lines


def format_diagnosis(diag: Diagnosis) -> str:
    """The verdict in one sentence, then the model-free findings, where the model misses the
    bands and the drive cycle, and each effect's χ² without and with it."""
    lines = [f"verdict: {diag.verdict.label} — {verdict_sentence(diag)}", ""]
    lines.append(f"model-free tests (counted below p = {_level(diag):.2g} and the size floor):")
    for f in diag.findings:
        t = f.test
        mark = "  ← " + f.effect if f.significant else ""
        lines.append(
            f"  recording {f.recording}: {t.name:18s} {finding_size(t):30s} "
            f"p = {t.p_value:.2g}{mark}"
        )
    lines.append("")
    missed = diag.missed_bands
    if missed:
        lines.append(f"where the fitted model misses the data (|z| > {MISSED_Z:g}):")
        for m in missed:
            lo, hi = m["band_hz"]
            more = "more" if m["z"] > 0 else "less"
            lines.append(
                f"  recording {m['recording']}: {lo:7.1f}–{hi:7.1f} Hz  z = {m['z']:+.1f} "
                f"(the recording has {more} power)"
            )
    else:
        base = diag.baseline.statistics
        lines.append(
            f"no band misses by more than {MISSED_Z:g} σ (χ² = {base.chi2:.1f} on "
            f"{base.dof} dof, p = {base.p_value:.2g})"
        )
    lines += cycle_lines(diag)
    rows = [
        ("effect", "χ² without → with", "gap closed", "p", "p after", "supported", "fitted size")
    ]
    for o in diag.outcomes:
        size = ", ".join(_size_cell(o, k) for k in o.values)
        if o.failure:
            rows.append((o.name, f"{o.chi2_without:.1f} → failed", "—", "—", "—", "no", size))
            continue
        rows.append(
            (
                o.name,
                f"{o.chi2_without:.1f} → {o.chi2_with:.1f}",
                f"{100 * o.gap_closed:.0f} %",
                f"{o.p_value:.2g}",
                f"{o.p_after:.2g}",
                "yes" if o.supported else "no",
                size,
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    table = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    table.insert(1, "  ".join("-" * w for w in widths))
    lines += ["", *table, ""]
    lines += [f"failed: {o.name} ({o.failure})" for o in diag.outcomes if o.failure]
    lines += [f"* {o.name}'s size: {o.interval_caveat}" for o in diag.outcomes if o.interval_caveat]
    lines += [
        f"not fitted: {name} ({skipped_sentence(name, why)})" for name, why in diag.skipped.items()
    ]
    refit = dict(zip(("cost_identified", "cost"), diag.refit_costs, strict=True))
    options = diag.baseline.state.options.to_dict()
    lines += [f"warning: {caveat_sentence(c, refit, options)}" for c in diag.warnings]
    lines.append(f"seed {diag.seed}; {diag.wall_time:.0f} s")
    return "\n".join(lines)


#: Columns of :func:`suggestion_table`: the films first, then the drag torque and the
#: viscosity, the parameters a test is planned for.
PLANNED_COLUMNS = (DRAG_TORQUE, VISCOSITY_SCALE)


def suggestion_table(plan: dict) -> list[tuple[str, ...]]:
    """The header and rows, as text cells, of a fit document's ``suggest``
    (:func:`~rattlefit.inference.design.plan_document`): each candidate's predicted 95 %
    factor of each film half-length, the drag torque and the viscosity; "—" unbounded."""
    rows = plan["candidates"]
    cols = [*(k for k in rows[0]["factors"] if k.startswith(f"{FILM}[")), *PLANNED_COLUMNS]
    table = [("with one more recording", *(c.replace("_scale", "") for c in cols))]
    for r in rows:
        factors = [r["factors"].get(c) for c in cols]
        cells = ["—" if f is None or f > 1e3 else f"×{f:.2f}" for f in factors]
        label = "(this fit alone)" if r["recording"] == "now" else f"+ {r['recording']}"
        table.append((label, *cells))
    return table


def suggestion_note(plan: dict) -> str:
    """What :func:`suggestion_table`'s factors are, with the seed and realisations used."""
    return (
        "predicted 95 % interval factors at the fitted point (Fisher information of "
        f"{plan['realisations']} simulated realisations per point, seed {plan['seed']}; local "
        "and Gaussian, so a fit's profile intervals can be wider); — : not bounded"
    )


def format_suggestions(plan: dict) -> str:
    """:func:`suggestion_table` as aligned text, with :func:`suggestion_note` below."""
    table = suggestion_table(plan)
    widths = [max(len(row[i]) for row in table) for i in range(len(table[0]))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)) for row in table]
    lines.insert(1, "  ".join("-" * w for w in widths))
    lines = [line.rstrip() for line in lines]
    return "\n".join([*lines, suggestion_note(plan)])
