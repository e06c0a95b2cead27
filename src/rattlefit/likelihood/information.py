"""The Fisher information a likelihood holds about the parameters, per unit log of each.

``F = Σ_r D_rᵀ C_r⁻¹ D_r`` over the recordings r, ``D_r`` the derivative of recording r's mean
features per unit log of each parameter, ``C_r`` their covariance. A simulated estimate
(:func:`simulated_information`) takes ``D`` by central differences of realisation means and
``C`` from the chaotic spread, less the bias the Monte Carlo noise of ``D`` adds; a smooth
likelihood's (:func:`moment_information`) takes both from its mean and covariance.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ..features.ensemble import chaotic_part, shrunk_correlation
from ..problem.forward import evaluate
from ..problem.problem import Problem, release_states

#: Realisations per point of a simulated information estimate.
SIMULATED_REALISATIONS = 24
#: Log step of a simulated estimate's central differences.
SIMULATED_STEP = 0.4
#: Log step of a smooth likelihood's central differences (no Monte Carlo noise to beat).
SMOOTH_STEP = 0.02


def fisher_information(derivatives, deviations, dof: int, log_steps, floor: float) -> np.ndarray:
    """The information (P, P) of one recording whose mean features move by ``derivatives``
    (F, P) per unit log of each parameter, estimated by central differences over
    ``log_steps`` (P,) from means of as many realisations as ``deviations`` (n, F) holds
    (their chaotic deviations, with ``dof`` degrees of freedom).

    The covariance is the deviations' spread (floored at ``floor``) with their shrunk
    correlation. The Monte Carlo noise of each mean adds ``2F / (n Δ²)`` to the diagonal of
    ``DᵀC⁻¹D`` on average, which is subtracted; the negative eigenvalues the subtraction
    can leave are set to zero.
    """
    d, dev = np.asarray(derivatives), np.asarray(deviations)
    n, f = dev.shape
    sd = np.maximum(np.sqrt(np.sum(dev**2, axis=0) / max(dof, 1)), floor)
    cov = shrunk_correlation(dev) * np.outer(sd, sd)
    info = d.T @ np.linalg.solve(cov, d)
    info -= np.diag(2.0 * f / (n * np.asarray(log_steps) ** 2))
    value, vector = np.linalg.eigh(info)
    return (vector * np.maximum(value, 0.0)) @ vector.T


def difference_points(specs, z0, names: Sequence[str], step: float):
    """The points of the central differences: ``z0`` (P,) in the coordinates of ``specs``,
    then for each of ``names`` its value times ``e^{+step}`` and ``e^{−step}`` (clipped to its
    range); and each pair's actual log step (P names,)."""
    z0 = np.asarray(z0, dtype=float)
    all_names = [s.name for s in specs]
    points, logs = [z0], []
    for name in names:
        i = all_names.index(name)
        spec = specs[i]
        v = float(spec.value(z0[i]))
        for sign in (1.0, -1.0):
            z = z0.copy()
            z[i] = spec.z_of(min(max(v * math.exp(sign * step), spec.lower), spec.upper))
            points.append(z)
        logs.append(math.log(spec.value(points[-2][i]) / spec.value(points[-1][i])))
    return np.stack(points), np.array(logs)


def simulated_information(
    problem: Problem,
    z0,
    names: Sequence[str],
    *,
    n: int,
    step: float,
    floor: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """The information (P, P) of ``problem``'s recordings about ``names`` at ``z0``,
    simulated from ``n`` realisations released at ``z0`` (the same ones at every point of the
    central differences over ``e^{±step}``); each recording's covariance its chaotic spread,
    floored at ``floor`` (:func:`fisher_information`)."""
    points, logs = difference_points(problem.specs, z0, names, step)
    per = evaluate(problem, points, release_states(problem, z0, n, rng))  # (K, R, n, F)
    mean = np.asarray(problem.mean_of(per))  # (K, R, F)
    d = (mean[1::2] - mean[2::2]) / logs[:, None, None]  # (P, R, F)
    kept = np.asarray(problem.mean_weights(per[0])) > 0  # (R, n)
    dev, dof = chaotic_part(per[0], problem.dither_offsets(n), kept)
    return sum(
        fisher_information(d[:, r].T, dev[r, kept[r]], int(dof[r]), logs, floor)
        for r in range(problem.n_rec)
    )


def moment_information(
    moments: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    specs,
    z0,
    names: Sequence[str],
    *,
    step: float,
) -> np.ndarray:
    """The information (P, P) about ``names`` at ``z0`` of a smooth likelihood whose
    ``moments(z)`` are each recording's mean features (R, F) and their covariance
    (R, F, F), at ``z0`` in the coordinates of ``specs``: ``D`` by central differences over
    ``e^{±step}``, ``C`` the covariance at ``z0``."""
    points, logs = difference_points(specs, z0, names, step)
    means = np.stack([np.asarray(moments(z)[0]) for z in points[1:]])  # (2P, R, F)
    d = np.moveaxis((means[0::2] - means[1::2]) / logs[:, None, None], 0, -1)  # (R, F, P)
    cov = np.asarray(moments(points[0])[1])
    return sum(d[r].T @ np.linalg.solve(cov[r], d[r]) for r in range(len(d)))
