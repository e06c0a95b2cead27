"""The HTML report's figures, drawn from the JSON documents, the recordings and an ArviZ
``InferenceData``, each returned as PNG bytes (nothing is written to disk)."""

from __future__ import annotations

import io
import warnings

import numpy as np

from .plots import (
    DPI,
    SPREAD_LABEL,
    centred,
    draw_drive_cycle,
    draw_flanks,
    igr_figure,
    profile_figure,
    pyplot,
)

#: Seconds of the recording's Δθ* shown as a time history.
TIME_HISTORY_S = 0.3


def png(fig) -> bytes:
    """``fig`` as PNG bytes; the figure is closed."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight")
    pyplot().close(fig)
    return buf.getvalue()


def spectrum(spectra: dict, k: int, title: str) -> bytes:
    """Recording ``k``'s measured band PSDs against the fitted model's mean and its ±2σ band
    (the fit JSON's ``spectra``: log10 PSD of Δθ*, rad²/Hz; σ in log10 units)."""
    centres = np.asarray(spectra["band_centers_hz"], dtype=float)
    measured = np.asarray(spectra["measured"][k], dtype=float)
    fitted = np.asarray(spectra["fitted"][k], dtype=float)
    sigma = np.asarray(spectra["sigma"][k], dtype=float)
    fig, ax = pyplot().subplots(figsize=(8, 3.8))
    ax.fill_between(
        centres,
        10 ** (fitted - 2 * sigma),
        10 ** (fitted + 2 * sigma),
        color="C0",
        alpha=0.2,
        lw=0,
        label=SPREAD_LABEL,
    )
    ax.plot(centres, 10**fitted, "-", color="C0", lw=1.2, label="fitted model (mean)")
    ax.plot(centres, 10**measured, "o", ms=4, color="k", label="measured")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("band centre (Hz)")
    ax.set_ylabel("band PSD of Δθ* (rad²/Hz)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="major", color="0.9", lw=0.6)
    return png(fig)


def time_history(time_s, relative_motion_rad, backlash_rad: float, title: str) -> bytes:
    """The first :data:`TIME_HISTORY_S` s of the measured Δθ* (mrad) about the middle of its
    range (:func:`~rattlefit.report.plots.centred`), the backlash's extent as dotted lines."""
    t = np.asarray(time_s, dtype=float)
    x = centred(relative_motion_rad)
    n = int(np.searchsorted(t, t[0] + TIME_HISTORY_S))
    fig, ax = pyplot().subplots(figsize=(8, 2.8))
    ax.plot(t[:n], x[:n] * 1e3, color="k", lw=0.7)
    for s in (-0.5, 0.5):
        ax.axhline(s * backlash_rad * 1e3, color="0.5", ls=":", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("Δθ* about its middle (mrad)")
    ax.set_title(f"{title}: measured relative motion (dotted: backlash)", fontsize=10)
    return png(fig)


def profiles(curves: dict, threshold: float | None, parameters: dict) -> bytes:
    """:func:`profile_figure` as PNG."""
    return png(profile_figure(curves, threshold, parameters))


def igr(entries: list[dict], names: list[str]) -> bytes:
    """:func:`~rattlefit.report.plots.igr_figure` as PNG."""
    return png(igr_figure(entries, names))


def trace(idata) -> bytes:
    """ArviZ's trace plot of the posterior (each walker a chain)."""
    import arviz as az

    n = len(idata.posterior.data_vars)
    with warnings.catch_warnings():  # a short chain's flat walkers: its KDE warns, still drawn
        warnings.simplefilter("ignore", UserWarning)
        axes = az.plot_trace(idata, figsize=(10, 1.7 * n), compact=True)
    fig = np.ravel(axes)[0].figure
    fig.tight_layout()
    return png(fig)


def pairs(idata) -> bytes:
    """ArviZ's pair plot of the posterior's kept draws, with the marginals."""
    import arviz as az

    n = len(idata.posterior.data_vars)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        axes = az.plot_pair(
            idata,
            kind="scatter",
            marginals=True,
            figsize=(1.9 * n, 1.9 * n),
            scatter_kwargs={"alpha": 0.3, "s": 3},
            textsize=8,
        )
    return png(np.ravel(axes)[0].figure)


def predictive(idata, k: int, title: str) -> bytes:
    """Recording ``k``'s measured band PSDs against the mean features at the posterior
    predictive draws (the ``observed_data`` and ``posterior_predictive`` groups)."""
    draws = np.asarray(idata.posterior_predictive["log10_psd"], dtype=float)
    draws = draws.reshape(-1, *draws.shape[-2:])[:, k]
    data = np.asarray(idata.observed_data["log10_psd"], dtype=float)[k]
    centres = np.asarray(idata.observed_data["band"], dtype=float)
    fig, ax = pyplot().subplots(figsize=(8, 3.8))
    for i, d in enumerate(draws):
        label = "model mean at a posterior draw" if i == 0 else None
        ax.plot(centres, 10**d, color="C0", lw=0.8, alpha=0.5, label=label)
    ax.plot(centres, 10**data, "o", ms=4, color="k", label="measured")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("band centre (Hz)")
    ax.set_ylabel("band PSD of Δθ* (rad²/Hz)")
    ax.set_title(f"posterior predictive: {title}", fontsize=10)
    ax.legend(fontsize=8)
    return png(fig)


def residuals(diagnosis: dict, names: list[str], missed_z: float) -> bytes:
    """Each recording's standardised band residuals of the identification and with the
    verdict's effect (or the effect that left the least misfit), from the diagnosis JSON."""
    centres = np.asarray(diagnosis["band_centers_hz"], dtype=float)
    base = np.asarray(diagnosis["residuals"], dtype=float)
    effects = diagnosis.get("effects") or []
    named = diagnosis.get("verdict_effects") or [diagnosis.get("verdict")]
    best = next((e for e in effects if e["name"] in named), None)
    best = best or (effects[0] if effects else None)
    fig, axes = pyplot().subplots(len(base), 1, figsize=(8, 3.0 * len(base)), squeeze=False)
    for k, ax in enumerate(axes[:, 0]):
        ax.axhspan(-missed_z, missed_z, color="0.92", lw=0)
        ax.semilogx(centres, base[k], "ko-", ms=3, lw=0.8, label="fitted model")
        if best is not None:
            r = np.asarray(best["residuals"], dtype=float)[k]
            ax.semilogx(centres, r, "s--", ms=3, lw=0.8, color="C2", label=f"+ {best['name']}")
        ax.axhline(0, color="0.4", lw=0.6)
        ax.set_ylabel("(measured − model)/σ")
        ax.set_xlabel("band centre (Hz)")
        ax.set_title(f"{names[k]}: band residuals (shaded: within ±{missed_z:g} σ)", fontsize=10)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return png(fig)


def drive_cycle(cycle: dict, names: list[str]) -> bytes:
    """Each recording's drive-cycle statistics against the model without effects
    (:func:`~rattlefit.report.plots.draw_drive_cycle`), from the diagnosis JSON's
    ``drive_cycle``."""
    return png(draw_drive_cycle(cycle, names))


def flanks(recording, title: str) -> bytes:
    """The flank contacts of ``recording`` against each wheel's angle
    (:func:`~rattlefit.report.plots.draw_flanks`)."""
    fig, axes = pyplot().subplots(1, 2, figsize=(11, 3.6))
    draw_flanks(axes, recording)
    fig.suptitle(f"{title}: flank contacts against wheel angle", fontsize=10)
    fig.tight_layout()
    return png(fig)
