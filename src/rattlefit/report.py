"""Plots and tables of an identification, a posterior and a diagnosis: where a person would
rather look than read."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .diagnosis.result import MISSED_Z, Diagnosis
from .features.spectra import welch_psd
from .inference.posterior import Posterior
from .inference.profile import CHI2_1_95
from .inference.result import IDENTIFIED_RATIO, FitResult
from .inference.rig import setup
from .io.recording import Recording
from .simulation.solve import absolute_tolerances, simulate
from .util import atomic_write


def _pyplot():
    """``matplotlib.pyplot``, imported on first use (0.7 s: a table or JSON output, every
    ``rattlefit identify`` without ``--plot``, does without it). The figures are written to
    files: the Agg backend is chosen unless pyplot is already in use (a notebook keeps its
    own)."""
    if "matplotlib.pyplot" not in sys.modules:
        import matplotlib

        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: Display units of the parameters: (SI multiplier, label).
DISPLAY = {"m": (1e3, "mm"), "N m": (1.0, "N m"), "Pa s": (1.0, "Pa s"), "1": (1.0, "")}


def format_table(result: FitResult) -> str:
    """The parameters as a readable table (estimate, 95 % interval, unit, identified)."""
    rows = [("parameter", "estimate", "95 % interval", "unit", "identified")]
    for name, p in result.parameters.items():
        mult, unit = DISPLAY.get(p.unit, (1.0, p.unit))
        if p.identified:
            est = f"{p.estimate * mult:.4g}"
            ci = f"[{p.lower * mult:.4g}, {p.upper * mult:.4g}]"
            ident = "yes"
        elif p.bound == "lower":
            est, ci, ident = f"≥ {p.lower * mult:.4g}", "(bound)", "no: lower bound only"
        elif p.bound == "upper":
            est, ci, ident = f"≤ {p.upper * mult:.4g}", "(bound)", "no: upper bound only"
        elif p.bound in ("interval", "prior"):
            est = "—"
            ci = f"[{p.lower * mult:.4g}, {p.upper * mult:.4g}]"
            ident = (
                f"no: interval too wide (×{p.upper / p.lower:.2f} > ×{IDENTIFIED_RATIO})"
                if p.bound == "interval"
                else "no: prior-dominated"
            )
        else:
            est, ci, ident = "—", f"[{p.lower * mult:.4g}, {p.upper * mult:.4g}]", "no"
        rows.append((name, est, ci, unit, ident))
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    per = ""
    if len(result.chi2_recordings) > 1:
        per = " (" + " + ".join(f"{c:.1f}" for c in result.chi2_recordings) + " by recording)"
    lines.append(
        f"χ² = {result.chi2:.1f}{per} on {result.dof} dof; {result.n_iterations} "
        f"Levenberg–Marquardt steps; seed {result.seed}; {result.wall_time:.1f} s"
    )
    if "threshold" in result.profile:
        lines.append(_profile_line(result.profile))
    for k, share in enumerate(result.regime_share):
        if share < 0.5:
            which = "the recording"
            if len(result.recordings) > 1:
                which = Path(result.recordings[k]).name
            lines.append(
                f"note: {which} is in a regime that {share:.0%} of the model's releases reach "
                "at the fitted parameters (the others settle into another); the fit compares it "
                "with that regime (FitOptions.regime), since which one a rig is on is its "
                "history's choice."
            )
    if result.poor_fit:
        which = "this recording"
        widened = f"√(χ²/dof) = {(result.chi2 / result.dof) ** 0.5:.1f}"
        if len(result.chi2_recordings) > 1:
            poor = [Path(result.recordings[k]).name for k in result.poorly_fitted]
            which = ", ".join(poor) if poor else "these recordings together"
            widened = "each recording's own √(χ²/dof)"
        lines.append(
            f"warning: χ² is far above its {result.dof} degrees of freedom "
            f"(p = {result.p_value:.1e}): the model does not explain {which} within "
            f"its run-to-run spread. The intervals are widened by {widened} but may still "
            "miss; look at the spectrum plot (--plot)."
        )
    return "\n".join(lines)


def _profile_line(profile: dict) -> str:
    """How the 95 % intervals' profile threshold was set: χ²₁'s 3.84 plus an allowance."""
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
        f"optimum's (χ²₁ {CHI2_1_95:.2f} + 1.645 × {sd:.1f}, {source})"
    )


def _save(fig, path: Path) -> Path:
    def write(tmp: Path) -> None:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")

    atomic_write(path, write)
    _pyplot().close(fig)
    return path


def plot_fit(result: FitResult, recordings: list[Recording], directory: str | Path) -> list[Path]:
    """Measured vs fitted spectra and time histories, and the parameter correlations."""
    directory = Path(directory)
    out = []
    for k, rec in enumerate(recordings):
        rig = setup(rec, drive=result.options.drive)
        sol = simulate(
            rig.model,
            result.rattle_params(k),
            rig.drive,
            duration=rec.duration,
            sample_rate=rec.sample_rate_hz,
            rtol=result.options.rtol,
            atol=absolute_tolerances(
                result.options.rtol, [r.operating.lubrication for r in recordings]
            ),
        )
        fig, (ax1, ax2) = _pyplot().subplots(2, 1, figsize=(9, 8))
        f = rig.bands.frequencies
        measured = np.asarray(
            welch_psd(rec.relative_motion, rig.sample_rate, rig.bands.segment_length)
        )
        simulated = (
            np.asarray(welch_psd(sol.relative_motion, rig.sample_rate, rig.bands.segment_length))
            + rig.noise_floor
        )
        ax1.loglog(f[1:], measured[1:], color="0.6", lw=0.8, label="measured (Welch PSD)")
        ax1.loglog(
            f[1:], simulated[1:], color="C1", lw=0.8, alpha=0.7, label="one fitted realisation"
        )
        c = result.band_centers
        err = 2 * result.sigma[k]
        ax1.errorbar(
            c,
            10 ** result.measured_features[k],
            yerr=[
                10 ** result.measured_features[k] * (1 - 10**-err),
                10 ** result.measured_features[k] * (10**err - 1),
            ],
            fmt="o",
            ms=3,
            color="k",
            label="measured bands ±2σ",
        )
        ax1.plot(
            c,
            10 ** result.fitted_features[k],
            "s-",
            ms=3,
            color="C0",
            label="fitted mean of realisations",
        )
        ax1.axhline(
            rig.noise_floor, color="0.3", ls=":", lw=0.8, label="encoder quantisation floor"
        )
        ax1.set_xlabel("frequency (Hz)")
        ax1.set_ylabel("PSD of Δθ* (rad²/Hz)")
        ax1.set_title(Path(rec.path or f"recording {k}").name)
        ax1.legend(fontsize=8)
        t = rec.time
        n = min(len(t), int(0.5 * rec.sample_rate_hz))
        ax2.plot(t[:n], rec.relative_motion[:n] * 1e3, color="k", lw=0.8, label="measured")
        sim = np.asarray(sol.relative_motion)
        ax2.plot(
            t[:n],
            (sim[:n] - np.median(sim)) * 1e3,
            color="C1",
            lw=0.8,
            alpha=0.8,
            label="fitted model (one realisation: rattle is chaotic, compare character, not phase)",
        )
        ax2.set_xlabel("time (s)")
        ax2.set_ylabel("Δθ* (mrad)")
        ax2.legend(fontsize=8, loc="lower right")
        out.append(_save(fig, directory / f"fit_{k}_{Path(rec.path or 'recording').stem}.png"))
    names = result.names
    fig, ax = _pyplot().subplots(figsize=(1.0 + 0.6 * len(names), 0.8 + 0.6 * len(names)))
    im = ax.imshow(result.correlation, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(len(names)), names, rotation=45, ha="right")
    ax.set_yticks(range(len(names)), names)
    for i in range(len(names)):
        for j in range(len(names)):
            ax.text(j, i, f"{result.correlation[i, j]:.2f}", ha="center", va="center", fontsize=7)
    fig.colorbar(im, ax=ax, label="correlation")
    ax.set_title("parameter correlations (Laplace)")
    out.append(_save(fig, directory / "correlation.png"))
    return out


def format_posterior(post: Posterior) -> str:
    """Credible intervals (median, 95 %), effective sample sizes and the chain's diagnostics."""
    rows = [("parameter", "median", "95 % credible interval", "unit", "ESS", "τ (steps)")]
    for (name, (med, lo, hi)), unit, ess, tau in zip(
        post.intervals().items(), post.units, post.ess, post.autocorr_time, strict=True
    ):
        mult, shown = DISPLAY.get(unit, (1.0, unit))
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


def plot_posterior(
    post: Posterior, directory: str | Path, recordings: list[Recording] | None = None
) -> list[Path]:
    """Trace of every walker (burn-in shaded), the pairwise marginals of the kept draws and,
    given the recordings, a posterior predictive check of the band spectrum (8 draws)."""
    directory = Path(directory)
    names, p = post.names, len(post.names)
    scale = [DISPLAY.get(u, (1.0, u)) for u in post.units]
    fig, axes = _pyplot().subplots(p, 1, figsize=(9, 1.6 * p), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(post.chain[:, :, i] * scale[i][0], color="k", lw=0.4, alpha=0.35)
        ax.axvspan(0, post.discard, color="0.85", lw=0)
        ax.set_ylabel(f"{names[i]}\n({scale[i][1]})" if scale[i][1] else names[i], fontsize=8)
    axes[-1, 0].set_xlabel("step (shaded: burn-in, discarded)")
    out = [_save(fig, directory / "posterior_trace.png")]
    kept = post.kept * np.array([m for m, _ in scale])
    fig, axes = _pyplot().subplots(p, p, figsize=(1.9 * p, 1.9 * p), squeeze=False)
    for i in range(p):
        for j in range(p):
            ax = axes[i, j]
            if j > i:
                ax.axis("off")
                continue
            if i == j:
                ax.hist(kept[:, i], bins=40, color="C0", histtype="stepfilled", alpha=0.7)
                lo, hi = np.percentile(kept[:, i], [2.5, 97.5])
                for x in (lo, hi):
                    ax.axvline(x, color="k", ls=":", lw=0.8)
                ax.set_yticks([])
            else:
                ax.hist2d(kept[:, j], kept[:, i], bins=40, cmap="Blues")
            if i == p - 1:
                ax.set_xlabel(names[j], fontsize=8)
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(names[i], fontsize=8)
            ax.tick_params(labelsize=6)
    fig.suptitle("posterior: pairwise marginals (dotted: 95 % credible interval)")
    out.append(_save(fig, directory / "posterior_pairs.png"))
    if recordings:
        draws, data, centres = post.predictive_features(recordings)
        for k, rec in enumerate(recordings):
            fig, ax = _pyplot().subplots(figsize=(9, 4.5))
            for i, d in enumerate(draws[:, k]):
                label = "mean of the realisations at posterior draws" if i == 0 else None
                ax.loglog(centres, 10**d, color="C0", lw=0.8, alpha=0.5, label=label)
            ax.loglog(centres, 10 ** data[k], "o", ms=3, color="k", label="measured bands")
            ax.set_xlabel("frequency (Hz)")
            ax.set_ylabel("band PSD of Δθ* (rad²/Hz)")
            ax.set_title(f"posterior predictive: {Path(rec.path or f'recording {k}').name}")
            ax.legend(fontsize=8)
            name = f"posterior_predictive_{k}_{Path(rec.path or 'recording').stem}.png"
            out.append(_save(fig, directory / name))
    return out


def _si(value: float, unit: str) -> str:
    mult, shown = DISPLAY.get(unit, (1.0, unit))
    return f"{value * mult:.3g} {shown}".rstrip()


def format_diagnosis(diag: Diagnosis) -> str:
    """Where the model misses, each effect's χ² without and with it, and the verdict."""
    lines = []
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
        lines.append(
            f"no band misses by more than {MISSED_Z:g} σ (χ² = {diag.baseline.chi2:.1f} on "
            f"{diag.baseline.dof} dof, p = {diag.baseline.p_value:.2g})"
        )
    rows = [("effect", "χ² without → with", "gap closed", "p", "supported", "fitted size")]
    for o in diag.outcomes:
        size = ", ".join(f"{k} {_si(v, o.units[k])}" for k, v in o.values.items())
        rows.append(
            (
                o.name,
                f"{o.chi2_without:.1f} → {o.chi2_with:.1f}",
                f"{100 * o.gap_closed:.0f} %",
                f"{o.p_value:.2g}",
                "yes" if o.supported else "no",
                size,
            )
        )
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    table = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    table.insert(1, "  ".join("-" * w for w in widths))
    lines += ["", *table, ""]
    best = diag.verdict
    if best is None:
        lines.append(
            "verdict: no effect is supported — none lowers χ² by more than its Monte Carlo "
            "noise with an F-test p below the family-wise level over the effects tried."
        )
    else:
        lines.append(
            f"verdict: {best.name} — χ² {best.chi2_without:.1f} → {best.chi2_with:.1f}, "
            f"{100 * best.gap_closed:.0f} % of the excess misfit removed (p = {best.p_value:.2g})."
        )
    lines += [f"warning: {w}" for w in diag.warnings]
    lines.append(f"seed {diag.seed}; {diag.wall_time:.0f} s")
    return "\n".join(lines)


def plot_diagnosis(diag: Diagnosis, directory: str | Path, *, top: int = 3) -> list[Path]:
    """Each recording's standardised band residuals without extra effects and with each of
    the ``top`` effects that remove most misfit, over the χ² of every effect tried."""
    directory = Path(directory)
    n_rec = diag.residuals.shape[0]
    fig, axes = _pyplot().subplots(n_rec + 1, 1, figsize=(9, 3.2 * (n_rec + 1)), squeeze=False)
    centres = diag.band_centers
    for k in range(n_rec):
        ax = axes[k, 0]
        ax.axhspan(-MISSED_Z, MISSED_Z, color="0.92", lw=0)
        ax.semilogx(centres, diag.residuals[k], "ko-", ms=3, lw=0.8, label="fitted model")
        for i, o in enumerate(diag.outcomes[:top]):
            ax.semilogx(
                centres, o.residuals[k], "s--", ms=3, lw=0.7, color=f"C{i}", label=f"+ {o.name}"
            )
        ax.axhline(0, color="0.4", lw=0.6)
        ax.set_ylabel("(measured − model)/σ")
        ax.set_xlabel("band centre (Hz)")
        name = Path(diag.baseline.recordings[k]).name
        ax.set_title(f"{name}: band residuals (shaded: within ±{MISSED_Z:g} σ)")
        ax.legend(fontsize=8)
    ax = axes[-1, 0]
    names = [o.name for o in diag.outcomes]
    x = np.arange(len(names))
    ax.bar(x - 0.2, [o.chi2_without for o in diag.outcomes], 0.4, color="0.6", label="without")
    ax.bar(
        x + 0.2,
        [o.chi2_with for o in diag.outcomes],
        0.4,
        color=["C2" if o.supported else "C0" for o in diag.outcomes],
        label="with the effect (green: supported)",
    )
    ax.axhline(diag.baseline.dof, color="k", ls=":", lw=0.8, label="dof")
    ax.set_xticks(x, names, rotation=20, ha="right")
    ax.set_ylabel("χ²")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return [_save(fig, directory / "diagnosis.png")]
