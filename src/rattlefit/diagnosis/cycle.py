"""Where in the drive cycle the model misses: the folded statistics of Δθ* against the
simulated ensemble.

The band spectrum is what the model is fitted to; the drive-cycle-folded statistics
(:mod:`rattlefit.features.folded`: per phase bin, the mean position between the flanks and
each flank's share of the time) are not, so they test the fitted model out of sample. At the
model without effects' point the fresh realisations are simulated once and measured both
ways: the band features pick the realisations in the recording's own regime (as the fit's
mean does), and those give each folded statistic's mean and its run-to-run spread. A
statistic whose standardised residual exceeds the family-wise threshold (Bonferroni over
every statistic of every recording, two-sided) is *missed*: that says where in the cycle,
and on which flank, the model is wrong.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import stats

from ..features.folded import PHASE_BINS, STATISTICS
from ..rig import RigSetup
from .cycle_gap import CycleGap
from .trial import Trial, fresh_features

#: Floor on a folded statistic's spread (a flank share, or a position in units of half the
#: play): a statistic that every realisation gives alike, e.g. a share that is always zero,
#: still has the recording's own sampling error.
CYCLE_SD_FLOOR = 0.02
#: Fewest realisations in the recording's regime for the spread; with fewer, all are used.
MIN_KEPT = 3


def regime_kept(trial: Trial, features: np.ndarray) -> np.ndarray:
    """(R, M) which realisations are in each recording's regime, judged by the band part of
    their ``features`` (R, M, F) as the fit's mean judges them; all when fewer than
    :data:`MIN_KEPT`."""
    w = np.asarray(trial.problem.mean_weights(features)) > 0
    w[w.sum(axis=1) < MIN_KEPT] = True
    return w


def ensemble_spread(per: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and the spread of one recording's statistics (with the Monte Carlo error of the
    mean; floored, :data:`CYCLE_SD_FLOOR`) from realisations ``per`` (M, S): (S,) each."""
    m = per.shape[0]
    spread = per.std(axis=0, ddof=1) * np.sqrt(1.0 + 1.0 / m)
    return per.mean(axis=0), np.sqrt(spread**2 + CYCLE_SD_FLOOR**2)


def cycle_gap(trial: Trial, z, rigs: list[RigSetup], level: float) -> CycleGap:
    """The drive-cycle statistics of ``rigs``' recordings against the model at ``z`` on the
    trial's fresh realisations (:class:`CycleGap`), judged at the family-wise ``level``."""
    problem = dataclasses.replace(trial.problem, statistics="bands+folded")
    per = fresh_features(trial, np.asarray(z)[None], problem=problem)[0]  # (R, M, B + S)
    n_band = problem.n_bands
    kept = regime_kept(trial, per)
    n = dict(problem.static)["n_samples"]
    measured = np.stack([rig.folded(n) for rig in rigs])
    spreads = [ensemble_spread(per[r, kept[r], n_band:]) for r in range(len(rigs))]
    mean, sd = (np.stack(x) for x in zip(*spreads, strict=True))
    family = measured.size
    shape = (len(rigs), len(STATISTICS), PHASE_BINS)
    largest = float(np.max(np.abs((measured - mean) / sd)))
    return CycleGap(
        phases=(np.arange(PHASE_BINS) + 0.5) / PHASE_BINS,
        measured=measured.reshape(shape),
        model=mean.reshape(shape),
        sd=sd.reshape(shape),
        threshold=float(stats.norm.isf(level / (2 * family))),
        p_value=float(min(1.0, 2 * family * stats.norm.sf(largest))),
    )
