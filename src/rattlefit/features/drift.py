"""A drift test over a recording: do the rattle's statistics trend from its start to its end?

A rig whose oil warms, or whose drag settles, rattles differently at the end of a recording
than at its start; the model's parameters are constant. :func:`drift_evidence` cuts the
recording into windows of whole revolutions of the driven wheel, computes a few model-free
statistics in each (the rattle's velocity level, the power in three broad bands, the share
of time near each flank) and tests each for a linear trend against the window-to-window
scatter (allowing for its autocorrelation); the largest
|t| over the statistics decides, with a Šidák correction.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal, stats

from ..io.recording import Recording
from .orders import AngleTest

#: Shortest window, s (and at least :data:`MIN_CYCLES` drive cycles).
MIN_WINDOW_S = 0.25
MIN_CYCLES = 2
#: Broad bands of the window statistics, Hz.
DRIFT_BANDS_HZ = ((10.0, 100.0), (100.0, 1000.0), (1000.0, 5000.0))


def window_length(recording: Recording) -> int:
    """Samples per window: the fewest whole revolutions of the driven (slower) wheel that
    last at least :data:`MIN_WINDOW_S` and :data:`MIN_CYCLES` drive cycles, so that run-out
    and tooth patterns average out within each window instead of aliasing into a trend."""
    f_drive = recording.operating.drive_frequency_hz
    f_driven = recording.operating.drive_mean_speed_rad_s / (2 * math.pi) / recording.gear_ratio
    shortest = max(MIN_WINDOW_S, MIN_CYCLES / f_drive)
    revolutions = max(1, math.ceil(shortest * f_driven - 1e-9))
    return round(revolutions / f_driven * recording.sample_rate_hz)


def window_statistics(recording: Recording) -> tuple[np.ndarray, tuple[str, ...]]:
    """(W, S) statistics of each window and their names: log10 RMS of dΔθ*/dt, log10 power
    in each of :data:`DRIFT_BANDS_HZ`, and the share of samples in the outer fifth of the
    play at each flank."""
    d = recording.relative_motion
    fs = recording.sample_rate_hz
    n = window_length(recording)
    lo, hi = np.percentile(d, [0.1, 99.9])
    margin = 0.2 * (hi - lo)
    rows = []
    for start in range(0, d.size - n + 1, n):
        x = d[start : start + n]
        f, p = signal.periodogram(x - x.mean(), fs=fs, window="hann")
        bands = [np.log10(np.sum(p[(f >= a) & (f < b)]) + 1e-300) for a, b in DRIFT_BANDS_HZ]
        rms = np.log10(np.sqrt(np.mean(np.diff(x) ** 2)) * fs + 1e-300)
        rows.append([rms, *bands, np.mean(x > hi - margin), np.mean(x < lo + margin)])
    names = ("velocity", *(f"band_{a:g}_{b:g}_hz" for a, b in DRIFT_BANDS_HZ), "upper", "lower")
    return np.asarray(rows), names


def ar1_factor(residuals: np.ndarray) -> float:
    """Variance factor (1 + ρ)/(1 − ρ) of a trend's slope for residuals with lag-one
    autocorrelation ρ ≥ 0 (ρ capped at 0.9): a slow, smooth wander of the statistic (a
    quasi-periodic beat in a mild regime) then counts as noise, not as drift."""
    r = residuals - residuals.mean()
    denom = float(r @ r)
    rho = float(r[1:] @ r[:-1]) / denom if denom > 0 else 0.0
    rho = min(max(rho, 0.0), 0.9)
    return (1 + rho) / (1 - rho)


def drift_evidence(recording: Recording) -> AngleTest:
    """The drift test (module docstring) as an :class:`~rattlefit.features.orders.AngleTest`
    named ``"drift"``: its χ² is the largest squared t of a trend, ``amplitude`` that
    statistic's change from the first to the last window (in its own units) and ``detail``
    the statistic, the windows and every t."""
    values, names = window_statistics(recording)
    w = values.shape[0]
    if w < 4:
        return AngleTest("drift", 0.0, 1, 1.0, 0.0, 0.0, {"windows": w})
    x = np.arange(w) - (w - 1) / 2
    t = np.zeros(len(names))
    slope = np.zeros(len(names))
    slope_sd = np.zeros(len(names))
    for j in range(len(names)):
        res = stats.linregress(x, values[:, j])
        slope[j] = res.slope
        slope_sd[j] = res.stderr * math.sqrt(
            ar1_factor(values[:, j] - res.intercept - res.slope * x)
        )
        t[j] = res.slope / slope_sd[j] if slope_sd[j] > 0 else 0.0
    worst = int(np.argmax(np.abs(t)))
    p_one = 2 * stats.t.sf(abs(t[worst]), w - 2)
    return AngleTest(
        name="drift",
        chi2=float(t[worst] ** 2),
        dof=1,
        p_value=float(1 - (1 - p_one) ** len(names)),
        amplitude=float(slope[worst] * (w - 1)),
        amplitude_sd=float(slope_sd[worst] * (w - 1)),
        detail={
            "statistic": names[worst],
            "windows": w,
            "t": dict(zip(names, t.tolist(), strict=True)),
        },
    )
