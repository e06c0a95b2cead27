"""The noise model: how the data rows of the residual are weighted.

A recording is one realisation of a chaotic motion, so its features scatter about the
model's mean features even at the true parameters. That scatter is estimated from the
simulated ensemble (a Gaussian synthetic likelihood): each band's run-to-run spread, with
the Monte Carlo error of an M-realisation mean, and the bands' correlations (chaotic
excursions move many bands together). It is fixed at the optimum in a :class:`NoiseModel`,
which the Laplace covariance, the profiles and the posterior all use.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..features import ensemble
from ..features.ensemble import chaotic_part, shrunk_correlation
from ..problem.forward import evaluate
from ..problem.options import FitOptions
from ..problem.problem import Problem, release_states


@dataclasses.dataclass(frozen=True)
class NoiseModel:
    """How the data rows are weighted, fixed at the optimum: the Laplace covariance, the
    profile scan and the posterior (:mod:`rattlefit.inference.posterior`) all use it.

    sigma : (R, F) each feature's standard deviation (log10 for a band): the run-to-run
        spread of one recording's features plus the Monte Carlo error of an M-realisation
        mean, floored. F is B bands, then any folded statistics (``FitOptions.features``).
    whiten : (R·F, R·F) block-diagonal inverse Cholesky factor of each recording's shrunk
        feature correlation (generalised least squares: chaotic excursions move many
        features together).
    row_scale : (R·F,) 1/√(inflation) of each recording's rows, the inflation being that
        recording's reduced χ² where it exceeds one (a Birge ratio per recording).
    chi2_recordings : (R,) each recording's χ² at the optimum, before inflation.
    sigma_dof : degrees of freedom of the spread estimate
        (:func:`~rattlefit.features.ensemble.chaotic_part`).
    regime_share : (R,) the share of the realisations at the optimum that are in the regime
        each recording is compared with (``FitOptions.regime``); below one half the recording
        is in a regime rarer than another that the model reaches there.
    """

    sigma: np.ndarray
    whiten: np.ndarray
    row_scale: np.ndarray
    chi2_recordings: np.ndarray
    sigma_dof: int
    regime_share: np.ndarray | None = None

    def quadratic(self, standardised) -> np.ndarray:
        """Σ (row_scale · whiten · r)² of data rows ``r`` already divided by a band spread;
        ``standardised`` (..., R·B) gives one value per leading index."""
        r = np.asarray(standardised)
        return np.sum((self.row_scale * (r @ self.whiten.T)) ** 2, axis=-1)


def noise_model(problem: Problem, per: np.ndarray, r_data: np.ndarray, dof_rec: float):
    """:class:`NoiseModel` from the realisations ``per`` (R, n, B) at the optimum, whose
    standardised data rows (in units of ``problem.sigma``) are ``r_data`` (R·B,)."""
    n_rec, n_band = np.asarray(problem.data).shape
    kept = np.asarray(problem.mean_weights(per)) > 0
    chaos, nu = chaotic_part(per, problem.dither_offsets(per.shape[1]), kept)
    whiten = np.zeros((n_rec * n_band, n_rec * n_band))
    for k in range(n_rec):
        chol = np.linalg.cholesky(shrunk_correlation(chaos[k, kept[k]]))
        sl = slice(k * n_band, (k + 1) * n_band)
        whiten[sl, sl] = np.linalg.inv(chol)
    chi2_rec = np.sum((whiten @ r_data).reshape(n_rec, n_band) ** 2, axis=1)
    row_scale = np.repeat(1.0 / np.sqrt(np.maximum(1.0, chi2_rec / dof_rec)), n_band)
    return NoiseModel(
        np.asarray(problem.sigma), whiten, row_scale, chi2_rec, int(nu.min()), kept.mean(axis=1)
    )


def ensemble_features(problem: Problem, z, n: int, rng) -> np.ndarray:
    """Features of ``n`` extra seeded realisations at ``z``: (R, n, B)."""
    return evaluate(problem, np.asarray(z)[None], release_states(problem, z, n, rng))[0]


def band_sigma(problem: Problem, options: FitOptions, ens) -> np.ndarray:
    """The band spread (R, B) of one recording's features from the realisations ``ens``
    (R, n, B) (:func:`~rattlefit.features.ensemble.band_sigma` with the fit's options)."""
    return ensemble.band_sigma(
        ens,
        options.n_realisations,
        options.sigma_floor,
        np.asarray(problem.floors),
        options.floor_uncertainty,
        options.model_discrepancy,
        offsets=problem.dither_offsets(ens.shape[1]),
        threshold=problem.regime_threshold,
        target=problem.regime_target(),
        n_bands=problem.n_bands,
    )


def synthetic_cost(problem: Problem, options: FitOptions, noise: NoiseModel, per, z) -> float:
    """The profile stage's cost at ``z`` from its realisations ``per`` (R, n, F): a Gaussian
    synthetic likelihood (Wood 2010) with the point's own band spread ``s``,
    ``noise.quadratic((d − mean) / s) + 2 Σ log s + prior rows²``, so that a value where rattle
    wanders between attractors is neither favoured by a spread estimated elsewhere nor excused
    by a wide one (the log-determinant term).

    Features after the bands (the drive-cycle-folded statistics) keep the noise model's
    spread and add no log-determinant: they are bounded shares and positions whose spread,
    re-estimated at each point from its realisations, would be the largest part of a profile's
    noise.
    """
    nb = problem.n_bands
    sig = np.array(band_sigma(problem, options, per))
    sig[:, nb:] = np.asarray(noise.sigma)[:, nb:]
    r = ((np.asarray(problem.data) - np.asarray(problem.mean_of(per))) / sig).reshape(-1)
    prior = problem.prior_rows(np.asarray(z))
    return float(noise.quadratic(r) + 2 * np.sum(np.log(sig[:, :nb])) + np.sum(prior**2))
