"""Realisations of the fitted model: one per recording to draw beside the measurement, or
many, read through the rig's encoders, as recordings of the fitted model."""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from ..io.recording import Recording
from ..rig import setup
from ..simulation.solve import (
    absolute_tolerances,
    broadcast_params,
    raise_if_failed,
    simulate,
    simulate_batch,
)
from ..simulation.synthetic import recording_from_trajectory
from .result import FitResult


def fitted_realisations(result: FitResult, recordings: Sequence[Recording]) -> list[np.ndarray]:
    """Δθ* (rad, one array of each recording's length) of one simulation at ``result``'s
    fitted parameters on each recording's rig, with the fit's tolerances. Rattle is chaotic:
    compare its character with the measurement's, not its phase."""
    lubrications = [r.operating.lubrication for r in recordings]
    out = []
    for k, rec in enumerate(recordings):
        rig = setup(rec, drive=result.state.options.drive)
        sol = simulate(
            rig.model,
            result.estimates.rattle_params(k),
            rig.drive,
            duration=rec.duration,
            sample_rate=rec.sample_rate_hz,
            rtol=result.state.options.rtol,
            atol=absolute_tolerances(result.state.options.rtol, lubrications),
        )
        out.append(np.asarray(sol.relative_motion))
    return out


def fitted_recordings(
    result: FitResult,
    recording: Recording,
    k: int,
    n: int,
    *,
    rng: np.random.Generator,
    lubrications: Sequence[str] = ("dry",),
    rtol: float | None = None,
) -> list[Recording]:
    """``n`` recordings that the rig of ``recording`` (the fit's recording ``k``: its drive
    as the fit reconstructs it, its duration and sample rate) would give at ``result``'s
    fitted parameters of recording ``k``, without any effect: each released from rest at a
    point drawn uniformly across the gap, and read through the two encoders with their zeros
    drawn uniformly over a revolution, all from ``rng``. ``rtol`` (default the fit's) and the
    absolute tolerances of ``lubrications`` (default the dry ones, the tightest, so that
    every lubrication runs one compiled program) set the solver's accuracy. Raises
    :class:`~rattlefit.errors.SolverError` when a simulation fails."""
    rtol = result.state.options.rtol if rtol is None else rtol
    rig = setup(recording, drive=result.state.options.drive)
    params = result.estimates.rattle_params(k)
    c = 0.5 * float(params.backlash)
    y0 = np.stack([rng.uniform(-c, c, size=n), np.zeros(n)], axis=1)
    zeros = rng.integers(0, recording.counts_per_rev, size=(n, 2))
    sols = raise_if_failed(
        simulate_batch(
            rig.model,
            broadcast_params(params, n),
            rig.drive,
            y0=jnp.asarray(y0),
            duration=recording.duration,
            sample_rate=recording.sample_rate_hz,
            rtol=rtol,
            atol=absolute_tolerances(rtol, tuple(lubrications)),
        )
    )
    return [
        recording_from_trajectory(
            rig.geometry,
            recording.operating,
            sols.theta1,
            sols.q[i],
            oil=recording.oil,
            sample_rate=recording.sample_rate_hz,
            counts_per_rev=recording.counts_per_rev,
            zeros=tuple(int(z) for z in zeros[i]),
        )
        for i in range(n)
    ]


def fitted_igr(
    result: FitResult, recordings: Sequence[Recording], n: int, *, seed: int
) -> list[list[float]]:
    """Per recording, the IGR (rad·Hz, the seed paper's eq. 10) of ``n`` recordings of the
    fitted model (:func:`fitted_recordings`, seeded by ``seed`` and the recording's index), at
    the fit's relative tolerance and the absolute tolerances of a dry fit (the tightest), so
    that every lubrication runs one compiled program. Raises
    :class:`~rattlefit.errors.SolverError` when a simulation fails."""
    from ..features.spectra import rattle_index

    out = []
    for k, rec in enumerate(recordings):
        rng = np.random.default_rng([seed, k])
        again = fitted_recordings(result, rec, k, n, rng=rng)
        out.append([float(rattle_index(r.relative_motion, rec.sample_rate_hz)) for r in again])
    return out
