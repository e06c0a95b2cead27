"""Plots of an identification, a posterior and a diagnosis written as PNG files (``--plot``):
where a person would rather look than read."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..diagnosis.policy import MISSED_Z
from ..diagnosis.result import Diagnosis
from ..features.orders import (
    contact_events,
    flank_regression,
    pitch_radius_driving,
    wheel_terms,
)
from ..features.spectra import welch_psd
from ..inference.posterior import Posterior
from ..inference.result import FitResult, reported_name
from ..io.recording import Recording
from ..quantities import axis_label, display
from ..rig import setup
from ..util import atomic_write
from .wording import profile_thresholds


def pyplot():
    """``matplotlib.pyplot``, imported on first use (0.7 s: a table or JSON output, every
    ``rattlefit identify`` without ``--plot``, does without it). The figures are written to
    files: the Agg backend is chosen unless pyplot is already in use (a notebook keeps its
    own)."""
    if "matplotlib.pyplot" not in sys.modules:
        import matplotlib

        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: Resolution of every PNG figure, dots per inch (sharp in print).
DPI = 150
#: The one label of the model's ±2σ band, wherever it is drawn.
SPREAD_LABEL = "model ±2σ (run-to-run spread)"


def centred(x):
    """Δθ* about the middle of its range, the one offset convention of every time history
    (the flanks then sit at ± half the backlash, measured or simulated alike)."""
    x = np.asarray(x, dtype=float)
    return x - 0.5 * (x.max() + x.min())


def _save(fig, path: Path) -> Path:
    def write(tmp: Path) -> None:
        fig.savefig(tmp, format="png", dpi=DPI, bbox_inches="tight")

    atomic_write(path, write)
    pyplot().close(fig)
    return path


def plot_fit(
    result: FitResult,
    recordings: list[Recording],
    directory: str | Path,
    realisations: Sequence[np.ndarray],
) -> list[Path]:
    """Measured vs fitted spectra and time histories, the parameter correlations and the
    profiles (``profiles.png``, :func:`profile_figure`, as in the HTML report).

    ``realisations``: one simulated Δθ* (rad) at the fitted parameters per recording
    (:func:`rattlefit.inference.realisation.fitted_realisations`), drawn beside the
    measurement. Returns the PNG files written in ``directory``."""
    directory = Path(directory)
    out = []
    for k, (rec, motion) in enumerate(zip(recordings, realisations, strict=True)):
        rig = setup(rec, drive=result.state.options.drive)
        fig, (ax1, ax2) = pyplot().subplots(2, 1, figsize=(9, 8))
        f = rig.bands.frequencies
        measured = np.asarray(
            welch_psd(rec.relative_motion, rig.sample_rate, rig.bands.segment_length)
        )
        simulated = (
            np.asarray(welch_psd(motion, rig.sample_rate, rig.bands.segment_length))
            + rig.noise_floor
        )
        ax1.loglog(f[1:], measured[1:], color="0.6", lw=0.8, label="measured (Welch PSD)")
        ax1.loglog(
            f[1:], simulated[1:], color="C1", lw=0.8, alpha=0.7, label="one fitted realisation"
        )
        c = result.spectra.band_centers
        err = 2 * np.asarray(result.spectra.bands_of(result.spectra.sigma[k]))
        fitted = np.asarray(result.spectra.bands_of(result.spectra.fitted[k]))
        ax1.fill_between(
            c,
            10 ** (fitted - err),
            10 ** (fitted + err),
            color="C0",
            alpha=0.2,
            lw=0,
            label=SPREAD_LABEL,
        )
        ax1.plot(c, 10**fitted, "s-", ms=3, color="C0", label="fitted model (mean)")
        measured_bands = 10 ** np.asarray(result.spectra.bands_of(result.spectra.measured[k]))
        ax1.plot(c, measured_bands, "o", ms=4, color="k", label="measured bands")
        ax1.axhline(
            rig.noise_floor, color="0.3", ls=":", lw=0.8, label="encoder quantisation floor"
        )
        ax1.set_xlabel("frequency (Hz)")
        ax1.set_ylabel("PSD of Δθ* (rad²/Hz)")
        ax1.set_title(Path(rec.path or f"recording {k}").name)
        ax1.legend(fontsize=8)
        t = rec.time
        n = min(len(t), int(0.5 * rec.sample_rate_hz))
        ax2.plot(t[:n], centred(rec.relative_motion)[:n] * 1e3, color="k", lw=0.8, label="measured")
        ax2.plot(
            t[:n],
            centred(motion)[:n] * 1e3,
            color="C1",
            lw=0.8,
            alpha=0.8,
            label="fitted model (one realisation: compare character, not phase)",
        )
        ax2.set_xlabel("time (s)")
        ax2.set_ylabel("Δθ* about the middle of its range (mrad)")
        fig.subplots_adjust(hspace=0.45)  # room for the lower legend under the upper axis
        ax2.legend(fontsize=8, loc="lower left", bbox_to_anchor=(0, 1.0), ncol=2, frameon=False)
        out.append(_save(fig, directory / f"fit_{k}_{Path(rec.path or 'recording').stem}.png"))
    names = [reported_name(n) for n in result.estimates.names]
    fig, ax = pyplot().subplots(figsize=(1.0 + 0.6 * len(names), 0.8 + 0.6 * len(names)))
    im = ax.imshow(result.estimates.correlation, vmin=-1, vmax=1, cmap="RdBu_r")
    ax.set_xticks(range(len(names)), names, rotation=45, ha="right")
    ax.set_yticks(range(len(names)), names)
    for i in range(len(names)):
        for j in range(len(names)):
            ax.text(
                j,
                i,
                f"{result.estimates.correlation[i, j]:.2f}",
                ha="center",
                va="center",
                fontsize=7,
            )
    fig.colorbar(im, ax=ax, label="correlation")
    ax.set_title("parameter correlations (Laplace)")
    out.append(_save(fig, directory / "correlation.png"))
    est = result.estimates
    if est.profiles:
        rows = {k: p.as_dict() for k, p in est.parameters.items()}
        fig = profile_figure(est.profiles, profile_thresholds(est.profile), rows)
        out.append(_save(fig, directory / "profiles.png"))
    return out


def profile_figure(curves: dict, threshold: float | dict | None, parameters: dict):
    """Each free parameter's profile against its value in display units: every point's cost
    above the lowest cost found (the optimum's, unless a profile point lies below it, which the
    panel then says), the estimate as a vertical line, the threshold that sets the 95 % interval
    (taken from the optimum, so shifted with the axis) dashed, and the interval the table
    prints shaded (from the axis' edge where its lower end reads 0). The cost is drawn linear up
    to the threshold and logarithmic beyond; the value axis spans the points, the estimate and
    the interval's finite ends. ``curves`` is the fit JSON's ``fit.profiles``, ``parameters``
    its ``parameters``; ``threshold`` one for every panel, or one per name
    (:func:`~rattlefit.report.wording.profile_thresholds`)."""
    names = list(curves)
    fig, axes = pyplot().subplots(1, len(names), figsize=(4.2 * len(names), 3.4), squeeze=False)
    for ax, name in zip(axes[0], names, strict=True):
        profile_panel(ax, name, np.asarray(curves[name], dtype=float).reshape(-1, 2),
                      panel_threshold(threshold, name), parameters.get(name, {}))  # fmt: skip
    fig.suptitle("profiles (shaded: the 95 % interval the table prints)", fontsize=10)
    fig.tight_layout()
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.0), ncol=4, fontsize=8)
    return fig


def panel_threshold(threshold: float | dict | None, name: str) -> float | None:
    """The threshold of ``name``'s panel: its own where ``threshold`` is per name."""
    return threshold.get(name) if isinstance(threshold, dict) else threshold


def value_limits(values: np.ndarray, log: bool) -> tuple[float, float]:
    """Axis limits that hold ``values`` with a margin of 5 % (of the log span when ``log``)."""
    lo, hi = float(values.min()), float(values.max())
    if log:
        pad = (hi / lo) ** 0.05
        return lo / pad, hi * pad
    pad = 0.05 * (hi - lo) or 0.05 * abs(lo) or 1.0
    return lo - pad, hi + pad


def profile_panel(ax, name: str, pts: np.ndarray, threshold: float | None, p: dict) -> None:
    """One parameter's panel of :func:`profile_figure`: ``pts`` (n, 2) value and Δcost above
    the optimum, ``p`` its table row (``estimate``, ``lower``, ``upper``, ``unit``)."""
    from matplotlib.ticker import NullFormatter

    unit = p.get("unit", "1")
    mult = display(name, unit)[0]
    lowest = min(0.0, float(pts[:, 1].min())) if len(pts) else 0.0
    x, y = pts[:, 0] * mult, pts[:, 1] - lowest
    ax.plot(x, y, "o-", ms=3, color="C0", label="profile")
    if threshold is not None:
        ax.axhline(threshold - lowest, color="C3", ls="--", lw=0.9, label="95 % threshold")
        ax.set_yscale("symlog", linthresh=threshold - lowest, linscale=2)
    ax.set_ylim(bottom=0.0)
    ends = [v * mult for v in (p.get("lower"), p.get("upper"), p.get("estimate")) if v]
    shown = np.concatenate([x, ends])
    logx = bool(len(shown)) and shown.min() > 0 and shown.max() > 3 * shown.min()
    if len(shown):
        ax.set_xlim(*value_limits(shown, logx))
    if logx:
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
    if p.get("upper") is not None:
        left = max(p.get("lower") or 0.0, 0.0) * mult
        ax.axvspan(max(left, ax.get_xlim()[0]), p["upper"] * mult, color="C2", alpha=0.12, lw=0)
    if p.get("estimate") is not None:
        ax.axvline(p["estimate"] * mult, color="k", lw=0.9, label="estimate")
    ax.set_xlabel(axis_label(name, unit))
    ax.set_ylabel("cost above the lowest point found")
    if lowest < 0:
        ax.set_title(f"a point lies {-lowest:.3g} below the optimum", fontsize=8)


def igr_figure(igr: list[dict], names: Sequence[str]):
    """The rattle index IGR (rad·Hz, the seed paper's eq. 10) of each recording, measured (a
    black dot) and of the fitted model's re-simulations (open circles, their mean ± sd as a
    bar), the recordings along the axis. ``igr``: the fit JSON's ``fit.igr``."""
    fig, ax = pyplot().subplots(figsize=(max(4.5, 1.6 + 1.4 * len(names)), 3.4))
    for k, entry in enumerate(igr):
        model = np.asarray(entry["model"], dtype=float)
        ax.plot(np.full(model.size, k + 0.12), model, "o", mfc="none", color="C0", ms=5,
                label="fitted model, re-simulated" if k == 0 else None)  # fmt: skip
        ax.errorbar(k + 0.12, model.mean(), yerr=model.std(ddof=1) if model.size > 1 else 0,
                    color="C0", capsize=4, lw=1.2)  # fmt: skip
        ax.plot(k - 0.12, entry["measured"], "o", color="k", ms=6,
                label="measured" if k == 0 else None)  # fmt: skip
    ax.set_xticks(range(len(names)), list(names), rotation=15, ha="right", fontsize=8)
    ax.set_xlim(-0.6, len(names) - 0.4)
    top = max(max(e["model"] + [e["measured"]]) for e in igr)
    ax.set_ylim(0.0, 1.15 * top)
    ax.set_ylabel("IGR (rad·Hz, 20–5000 Hz)")
    ax.set_title("rattle index, measured and at the fit", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def plot_igr(doc: dict, directory: str | Path) -> list[Path]:
    """``igr.png`` (:func:`igr_figure`) in ``directory`` when the fit JSON ``doc`` has
    ``fit.igr``; nothing otherwise."""
    igr = doc["fit"].get("igr")
    if not igr:
        return []
    names = [Path(p).stem for p in doc["fit"]["recordings"]]
    return [_save(igr_figure(igr, names), Path(directory) / "igr.png")]


def plot_posterior(
    post: Posterior,
    directory: str | Path,
    recordings: list[Recording] | None = None,
    *,
    predictive: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> list[Path]:
    """Trace of every walker (burn-in shaded), the pairwise marginals of the kept draws and,
    given ``predictive`` (:meth:`~rattlefit.inference.posterior.Posterior.predictive_features`
    of ``recordings``: draws (D, R, B), the measured bands (R, B) and the band centres (B,)
    in Hz), a posterior predictive check of each recording's band spectrum. Draws only: it
    simulates nothing."""
    directory = Path(directory)
    names, p = post.names, len(post.names)
    scale = [display(n, u) for n, u in zip(names, post.units, strict=True)]
    fig, axes = pyplot().subplots(p, 1, figsize=(9, 1.6 * p), sharex=True, squeeze=False)
    for i, ax in enumerate(axes[:, 0]):
        ax.plot(post.chain[:, :, i] * scale[i][0], color="k", lw=0.4, alpha=0.35)
        ax.axvspan(0, post.discard, color="0.85", lw=0)
        ax.set_ylabel(axis_label(names[i], post.units[i]).replace(" (", "\n("), fontsize=8)
    axes[-1, 0].set_xlabel("step (shaded: burn-in, discarded)")
    out = [_save(fig, directory / "posterior_trace.png")]
    kept = post.kept * np.array([m for m, _ in scale])
    fig, axes = pyplot().subplots(p, p, figsize=(1.9 * p, 1.9 * p), squeeze=False)
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
                ax.set_xlabel(axis_label(names[j], post.units[j]), fontsize=8)
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(axis_label(names[i], post.units[i]), fontsize=8)
            ax.tick_params(labelsize=6)
    fig.suptitle("posterior: pairwise marginals (dotted: 95 % credible interval)")
    out.append(_save(fig, directory / "posterior_pairs.png"))
    if recordings and predictive is not None:
        draws, data, centres = predictive
        for k, rec in enumerate(recordings):
            fig, ax = pyplot().subplots(figsize=(9, 4.5))
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


def draw_flanks(axes, recording: Recording) -> None:
    """On two axes, the flank contacts of ``recording`` (µm on the pitch circle) against the
    driving and the driven wheel's angle, with each flank's fitted once-per-revolution
    swing (:func:`~rattlefit.features.orders.flank_regression`): flat lines on a rig
    without run-out, a sinusoid where a wheel runs out."""
    ev = contact_events(recording)
    fit = flank_regression(ev, recording, wheel_terms(ev))
    scale = 1e6 * pitch_radius_driving(recording)
    grid = np.linspace(0, 2 * np.pi, 181)
    coef = dict(zip(fit.columns, fit.coef, strict=True))
    for ax, wheel, label in zip(axes, ("primary", "secondary"), ("driving", "driven"), strict=True):
        angle = np.mod(getattr(ev, f"theta_{wheel}"), 2 * np.pi)
        for flank, tag, color in ((1, "upper", "C0"), (-1, "lower", "C1")):
            on = (ev.flank == flank) & fit.kept
            if f"offset.{tag}" not in coef:
                continue
            ax.plot(angle[on], scale * ev.position[on], ".", ms=2, color=color, alpha=0.4)
            c, s = coef.get(f"{wheel}.{tag}.cos", 0.0), coef.get(f"{wheel}.{tag}.sin", 0.0)
            swing = coef[f"offset.{tag}"] + c * np.cos(grid) + s * np.sin(grid)
            ax.plot(grid, scale * swing, color=color, lw=1.5, label=f"{tag} flank")
        ax.set_xlabel(f"{label} wheel angle (rad, from the encoder's zero)")
        ax.set_ylabel("contact position (µm on the pitch circle)")
        ax.legend(fontsize=8)


#: Titles of the drive-cycle statistics (:data:`rattlefit.features.folded.STATISTICS`).
CYCLE_LABELS = {
    "position": "mean position (−1, +1: the flanks)",
    "upper_flank": "share at the upper flank",
    "lower_flank": "share at the lower flank",
}


def draw_drive_cycle(cycle: dict, names: Sequence[str]):
    """A figure of each recording's drive-cycle statistics (a row each, a panel per
    statistic) against the model without effects, its mean ± 2 spreads, the misses circled;
    ``cycle`` is :meth:`~rattlefit.diagnosis.cycle_gap.CycleGap.as_dict`."""
    phases = np.asarray(cycle["phases"], dtype=float)
    measured, model, sd = (np.asarray(cycle[k], dtype=float) for k in ("measured", "model", "sd"))
    n_rec, n_stat = measured.shape[:2]
    fig, axes = pyplot().subplots(n_rec, n_stat, figsize=(12, 3 * n_rec), squeeze=False)
    for k in range(n_rec):
        for s, name in enumerate(cycle["statistics"]):
            ax = axes[k, s]
            lo, hi = model[k, s] - 2 * sd[k, s], model[k, s] + 2 * sd[k, s]
            ax.fill_between(phases, lo, hi, color="0.88", lw=0, label=SPREAD_LABEL)
            ax.plot(phases, model[k, s], "-", color="C0", lw=1, label="model")
            ax.plot(phases, measured[k, s], "ko", ms=3, label="recording")
            out = np.abs(measured[k, s] - model[k, s]) / sd[k, s] > cycle["threshold"]
            ax.plot(phases[out], measured[k, s][out], "o", mfc="none", mec="C3", ms=9)
            ax.set_title(f"{names[k]}: {CYCLE_LABELS.get(name, name)}", fontsize=9)
            ax.set_xlabel("drive phase (cycles from the fastest point)")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def plot_diagnosis(
    diag: Diagnosis,
    directory: str | Path,
    *,
    top: int = 3,
    recordings: Sequence[Recording] = (),
) -> list[Path]:
    """Each recording's standardised band residuals without extra effects and with each of
    the ``top`` effects that remove most misfit, over the χ² of every effect tried; the
    drive-cycle statistics against the model (:func:`draw_drive_cycle`); and, for each of
    ``recordings``, its flank contacts against each wheel's angle (:func:`draw_flanks`)."""
    directory = Path(directory)
    n_rec = diag.residuals.shape[0]
    fig, axes = pyplot().subplots(n_rec + 1, 1, figsize=(9, 3.2 * (n_rec + 1)), squeeze=False)
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
        name = diag.baseline.provenance.recording_names[k]
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
    ax.axhline(diag.baseline.statistics.dof, color="k", ls=":", lw=0.8, label="dof")
    ax.set_xticks(x, names, rotation=20, ha="right")
    ax.set_ylabel("χ²")
    ax.legend(fontsize=8)
    fig.tight_layout()
    out = [_save(fig, directory / "diagnosis.png")]
    if diag.drive_cycle is not None:
        names = diag.baseline.provenance.recording_names
        fig = draw_drive_cycle(diag.drive_cycle.as_dict(), names)
        out.append(_save(fig, directory / "drive_cycle.png"))
    for k, rec in enumerate(recordings):
        fig, axes = pyplot().subplots(1, 2, figsize=(12, 3.8))
        draw_flanks(axes, rec)
        fig.suptitle(f"{Path(rec.path or 'recording').name}: flank contacts against wheel angle")
        fig.tight_layout()
        out.append(_save(fig, directory / f"flanks_{k}_{Path(rec.path or 'recording').stem}.png"))
    return out
