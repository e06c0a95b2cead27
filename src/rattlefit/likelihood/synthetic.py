"""The synthetic likelihood: the recordings' features scored against the simulated ensemble.

A recording is one realisation of a chaotic motion, so its features scatter about the
model's mean features even at the true parameters. That scatter is estimated from the
simulated ensemble (a Gaussian synthetic likelihood): each band's run-to-run spread, with
the Monte Carlo error of an M-realisation mean, and the bands' correlations (chaotic
excursions move many bands together). It is fixed at the optimum in a :class:`NoiseModel`,
which the Laplace covariance, the profiles and the posterior all use.
:class:`SyntheticLikelihood` is that likelihood behind the
:class:`~rattlefit.likelihood.protocol.Likelihood` contract.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import ClassVar

import h5py
import numpy as np

from ..errors import RattlefitError
from ..features import ensemble
from ..features.ensemble import chaotic_part, shrunk_correlation
from ..problem.forward import evaluate
from ..problem.options import FitOptions
from ..problem.problem import Problem, redrawn, release_states
from .information import SIMULATED_REALISATIONS, SIMULATED_STEP, simulated_information
from .noise import NoiseModel


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


@dataclasses.dataclass(frozen=True)
class SyntheticLikelihood:
    """The Gaussian synthetic likelihood of a problem's recordings with the noise model fixed
    at the optimum: ``log p(d | z) = −½ noise.quadratic((d − mean(z)) / sigma)``, ``mean(z)``
    the simulated mean features (a :class:`~rattlefit.likelihood.protocol.Likelihood`).

    noise : the :class:`~rattlefit.likelihood.noise.NoiseModel` at the optimum.
    problem : the :class:`~rattlefit.problem.problem.Problem` whose data and simulator it
        scores; None until :meth:`bind` gives one (a fit read back from its document).
    sigma_floor : the band spread's floor (log10) of the fit, which the simulated information
        floors each band's spread at.
    dither : the fit's dither (:attr:`~rattlefit.problem.options.FitOptions.dither`), which
        the simulated information's realisations are drawn with.
    """

    kind: ClassVar[str] = "synthetic"
    noise: NoiseModel
    problem: Problem | None = dataclasses.field(default=None, repr=False, compare=False)
    sigma_floor: float = 0.0
    dither: float = 0.0

    @classmethod
    def of_fit(cls, noise: NoiseModel, problem: Problem | None, options: FitOptions):
        """The synthetic likelihood of a fit with ``options`` (its floor and dither)."""
        return cls(noise, problem, options.sigma_floor, options.dither)

    def bind(self, problem: Problem) -> SyntheticLikelihood:
        """This likelihood on ``problem``'s recordings and simulator."""
        return dataclasses.replace(self, problem=problem)

    def bound(self) -> Problem:
        """The problem scored; raises :class:`~rattlefit.errors.RattlefitError` when none is
        bound."""
        if self.problem is None:
            raise RattlefitError("the synthetic likelihood has no problem: bind() one first")
        return self.problem

    def log_density(self, zs) -> np.ndarray:
        """log p(d | z) up to a constant at each point of ``zs`` (K, P): (K,)."""
        problem = self.bound()
        zs = np.atleast_2d(np.asarray(zs, dtype=float))
        return self.noise.log_density(problem.data, problem.mean_of(evaluate(problem, zs)))

    def information(self, z, names: Sequence[str], *, rng: np.random.Generator) -> np.ndarray:
        """The recordings' Fisher information (P, P) about ``names`` at ``z``, per unit log,
        simulated (:func:`~rattlefit.likelihood.information.simulated_information`) from
        :data:`~rattlefit.likelihood.information.SIMULATED_REALISATIONS` realisations drawn
        afresh from ``rng``."""
        problem = redrawn(self.bound(), self.dither, rng, SIMULATED_REALISATIONS)
        return simulated_information(
            problem,
            z,
            names,
            n=SIMULATED_REALISATIONS,
            step=SIMULATED_STEP,
            floor=self.sigma_floor,
            rng=rng,
        )

    def save(self, g: h5py.Group) -> None:
        """Write the noise model, the floor and the dither into the HDF5 group ``g``."""
        g.attrs.update(sigma_floor=self.sigma_floor, dither=self.dither)
        self.noise.save(g)

    @classmethod
    def load(cls, g: h5py.Group, problem: Problem, where: str) -> SyntheticLikelihood:
        """The likelihood :meth:`save` wrote into ``g``, bound to ``problem``."""
        floor, dither = (float(g.attrs.get(k, 0.0)) for k in ("sigma_floor", "dither"))
        return cls(NoiseModel.load(g, where), problem, floor, dither)
