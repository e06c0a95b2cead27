"""A drift test over a recording: do the rattle's statistics trend from its start to its end?

A rig whose oil warms, or whose drag settles, rattles differently at the end of a recording
than at its start; the model's parameters are constant. :func:`drift_evidence` cuts the
recording into windows of whole revolutions of the driven wheel, computes a few model-free
statistics in each (the rattle's velocity level, the power in three broad bands, the share
of time near each flank) and tests each for a linear trend against the window-to-window
scatter (allowing for its autocorrelation); the largest
|t| over the statistics decides, with a Šidák correction.

The trend is taken beyond what the drive explains (:func:`trend_t`): each statistic is
regressed on time and on the driving wheel's mean speed in each window
(:func:`window_drive_speed`). The rattle is locked to the drive, and a window that does not
hold whole drive cycles samples it at a phase that moves from window to window: a slow beat
that looks like a trend, and that the drive's own window means show too; a drive that
settles (a speed loop after its start) moves both as well. The oil's viscosity does not move
the drive, whose motion the model takes as measured.
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


def window_starts(recording: Recording) -> np.ndarray:
    """First sample of each whole window of :func:`window_length` samples."""
    n = window_length(recording)
    return np.arange(0, recording.n_samples - n + 1, n)


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
    for start in window_starts(recording):
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


#: Fewest windows for which the trend is taken beyond the drive's speed: the regressor costs
#: a degree of freedom, and with fewer than five left that costs more power than it buys.
CONDITIONED_WINDOWS = 8


def window_drive_speed(recording: Recording) -> np.ndarray:
    """(W,) mean speed of the driving wheel over each window of :func:`window_statistics`,
    rad/s: its angle's change from the window's first sample to its last over that time."""
    theta = recording.theta_primary
    n = window_length(recording)
    starts = window_starts(recording)
    return (theta[starts + n - 1] - theta[starts]) * recording.sample_rate_hz / (n - 1)


def trend_t(
    values: np.ndarray, drive: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Each column of ``values`` (W, S) regressed on the window index and, from
    :data:`CONDITIONED_WINDOWS` windows on and when it varies, on the (W,) ``drive`` speeds:
    the slopes per window, their standard errors (widened by :func:`ar1_factor`), their t
    and the residual degrees of freedom."""
    w = values.shape[0]
    x = np.arange(w) - (w - 1) / 2
    columns = [np.ones(w), x]
    spread = drive - drive.mean()
    if w >= CONDITIONED_WINDOWS and np.ptp(spread) > 1e-9 * max(abs(drive.mean()), 1.0):
        columns.append(spread / np.ptp(spread))
    design = np.column_stack(columns)
    dof = w - design.shape[1]
    unscaled = np.linalg.inv(design.T @ design)[1, 1]
    coef, *_ = np.linalg.lstsq(design, values, rcond=None)
    residuals = values - design @ coef
    slope = coef[1]
    slope_sd = np.array(
        [math.sqrt(float(r @ r) / dof * unscaled * ar1_factor(r)) for r in residuals.T]
    )
    t = np.divide(slope, slope_sd, out=np.zeros_like(slope), where=slope_sd > 0)
    return slope, slope_sd, t, dof


def drift_evidence(recording: Recording) -> AngleTest:
    """The drift test (module docstring) as an :class:`~rattlefit.features.orders.AngleTest`
    named ``"drift"``: its χ² is the largest squared t of a trend beyond the drive
    (:func:`trend_t`), ``amplitude`` that statistic's change from the first to the last
    window (in its own units) and ``detail`` the statistic, the windows, whether the drive's
    speed was a regressor and every t."""
    values, names = window_statistics(recording)
    w = values.shape[0]
    if w < 4:
        return AngleTest("drift", 0.0, 1, 1.0, 0.0, 0.0, {"windows": w})
    slope, slope_sd, t, dof = trend_t(values, window_drive_speed(recording))
    worst = int(np.argmax(np.abs(t)))
    p_one = 2 * stats.t.sf(abs(t[worst]), dof)
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
            "drive_regressor": dof == w - 3,
            "t": dict(zip(names, t.tolist(), strict=True)),
        },
    )
