"""The Laplace (Gauss–Newton) covariance at the optimum, and the noise model fixed there.

At the optimum, more realisations than the search uses (released from fresh states) give
the band spread and correlations (:class:`~rattlefit.likelihood.noise.NoiseModel`) and a
central-difference Jacobian of the ensemble-mean features at a wider step, which averages
over the small-scale ruggedness of a chaotic statistic. Each Jacobian column is a
difference of two noisy means; its expected noise is removed from ``JᵀJ`` so that noise does
not pass for information (:func:`debiased_information`).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import numpy as np

from ..likelihood.noise import NoiseModel
from ..likelihood.synthetic import band_sigma, noise_model
from ..problem.forward import evaluate, fd_jacobian, fd_points
from ..problem.options import FitOptions
from ..problem.problem import Problem

#: Floor on the eigenvalues of the information matrix (a standard deviation of 1000 in z).
MIN_INFORMATION = 1e-6
#: The covariance's finite-difference step, in multiples of the search's steps.
COVARIANCE_STEP_SCALE = 1.5


@dataclasses.dataclass(frozen=True)
class Laplace:
    """The Laplace stage's result at a point ``z``.

    problem : the problem with its band spread re-estimated at ``z``.
    noise : the noise model fixed at ``z``.
    chi2 : χ² of the data rows at ``z``, band correlations included, before inflation.
    covariance : (P, P) Laplace covariance in z (inflated per recording, debiased).
    mean : (R, B) mean features at ``z``.
    """

    problem: Problem
    noise: NoiseModel
    chi2: float
    covariance: np.ndarray
    mean: np.ndarray


def central_jacobian(problem: Problem, z, *, scale: float, y0):
    """Residual, its central-difference Jacobian at ``scale`` × the fitting steps, the
    features of every realisation at ``z``, and the Monte Carlo noise of the Jacobian.

    Used for the covariance, with the realisations released from ``y0`` (R, n, 2): more of
    them than the fit uses, and a wider, symmetric difference that averages over the
    small-scale ruggedness that a chaotic statistic has.

    Each column is still a difference of two means of n chaotic realisations, so it carries
    noise that ``JᵀJ`` would count as information. With common random numbers, realisation k
    at ``z + h`` and at ``z − h`` share their release and dither, so the noise of column j is
    estimated from the spread of the n paired differences: the returned ``noise`` (P, N, N)
    holds the covariance of each column's data rows (N = R·B), in residual units.
    """
    z = np.asarray(z, dtype=float)
    p = z.shape[0]
    h = problem.fd_steps(z) * scale
    per = evaluate(problem, fd_points(z, h, central=True), y0)  # (K, R, n, B)
    r, jac = fd_jacobian(problem, z, h, problem.mean_of(per), central=True)
    h_np, sigma = np.asarray(h), np.asarray(problem.sigma)
    paired = (per[1 : p + 1] - per[p + 1 :]) / (2 * h_np[:, None, None, None])
    paired = paired / sigma[None, :, None, :]  # (P, R, n, B)
    n = paired.shape[2]
    cols = np.moveaxis(paired, 2, 1).reshape(p, n, -1)  # (P, n, R·B)
    noise = np.stack([np.cov(c, rowvar=False, ddof=1) / n for c in cols])
    return np.asarray(r), np.asarray(jac), per[0], noise


def debiased_information(j_data: np.ndarray, noise: np.ndarray, j_prior: np.ndarray):
    """``JᵀJ`` with the expected contribution of the Jacobian's noise removed.

    A noisy column j adds ``noise[j]`` (the trace of its whitened noise covariance) to
    ``(JᵀJ)_jj`` on average, while the noises of different columns (different points) are
    independent. Left in, it overstates the curvature, and the intervals come out too narrow.
    The correction applies to the data rows; eigenvalues it drives below
    :data:`MIN_INFORMATION` are raised to it (no information from the data in that
    direction); the prior rows, which are exact, are added afterwards.
    """
    info = j_data.T @ j_data - np.diag(noise)
    vals, vecs = np.linalg.eigh(0.5 * (info + info.T))
    info = (vecs * np.clip(vals, MIN_INFORMATION, None)) @ vecs.T
    return info + j_prior.T @ j_prior


def laplace_at(problem: Problem, z, y0, options: FitOptions, dof_rec: float) -> Laplace:
    """The noise model and Laplace covariance at ``z``, from realisations released at ``y0``
    (R, n, 2); ``dof_rec`` is each recording's share of the degrees of freedom (for the
    per-recording inflation). The residual and Jacobian are re-expressed in the units of the
    band spread estimated here."""
    r, jac, per, jac_noise = central_jacobian(problem, z, scale=COVARIANCE_STEP_SCALE, y0=y0)
    n_data = int(np.prod(np.asarray(problem.data).shape))
    old = np.asarray(problem.sigma)
    sigma = band_sigma(problem, options, per)
    problem = eqx.tree_at(lambda q: q.sigma, problem, sigma)
    ratio = (old / np.asarray(sigma)).reshape(-1)
    r = np.concatenate([r[:n_data] * ratio, r[n_data:]])
    jac = np.concatenate([jac[:n_data] * ratio[:, None], jac[n_data:]])
    jac_noise = jac_noise * np.outer(ratio, ratio)[None]
    noise = noise_model(problem, per, r[:n_data], dof_rec)
    r_w = noise.whiten @ r[:n_data]
    dw = noise.row_scale[:, None] * noise.whiten
    j_w = dw @ jac[:n_data]
    noise_w = np.asarray([np.trace(dw @ c @ dw.T) for c in jac_noise])
    info = debiased_information(j_w, noise_w, jac[n_data:])
    return Laplace(
        problem,
        noise,
        float(np.sum(r_w**2)),
        np.linalg.inv(info),
        np.asarray(problem.mean_of(per)),
    )
