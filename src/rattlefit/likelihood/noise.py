"""The noise model: how the data rows of a residual are weighted, fixed at the optimum."""

from __future__ import annotations

import dataclasses

import h5py
import numpy as np

from ..errors import RattlefitError


@dataclasses.dataclass(frozen=True)
class NoiseModel:
    """How the data rows are weighted, fixed at the optimum: the Laplace covariance, the
    profile scan and the posterior all use it.

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

    def log_density(self, data, mean) -> np.ndarray:
        """The Gaussian log density up to a constant of ``data`` (R, F) about each of the
        means ``mean`` (K, R, F), weighted by this model: (K,)."""
        mean = np.asarray(mean)
        r = ((np.asarray(data) - mean) / self.sigma).reshape(len(mean), -1)
        return -0.5 * self.quadratic(r)

    def save(self, g: h5py.Group) -> None:
        """Write the arrays and ``sigma_dof`` into the HDF5 group ``g``."""
        g.attrs["sigma_dof"] = self.sigma_dof
        for name in ARRAYS:
            g.create_dataset(name, data=np.asarray(getattr(self, name), dtype=float))

    @classmethod
    def load(cls, g: h5py.Group, where: str) -> NoiseModel:
        """The noise model :meth:`save` wrote into ``g``; ``where`` names the file and group
        in the :class:`~rattlefit.errors.RattlefitError` raised for a missing field."""
        missing = [k for k in ARRAYS if k not in g] + (
            [] if "sigma_dof" in g.attrs else ["@sigma_dof"]
        )
        if missing:
            raise RattlefitError(f"{where}/{missing[0]}: missing; not a stored noise model")
        arrays = {k: np.asarray(g[k], dtype=float) for k in ARRAYS}
        return cls(**arrays, sigma_dof=int(g.attrs["sigma_dof"]))


#: The arrays :meth:`NoiseModel.save` stores.
ARRAYS = ("sigma", "whiten", "row_scale", "chi2_recordings")
