"""The learned likelihood checked against the exact simulator.

At a few points (the optimum, the interval ends) fresh simulations are run and compared with
what the emulator predicts there, on the scale that matters to a fit: one recording's
run-to-run spread. Three numbers per point and recording:

* ``z_rms``: the rms over simulations and features of each simulation's deviation from the
  learned mean over the learned sd (chaotic spread and emulator error together). It is 1
  where the learned Gaussian describes a recording made at that point, below 1 where the
  learned spread is too wide (conservative intervals), above 1 where it is too narrow.
* ``mean_error``: the rms over features of the learned mean's error over the predicted
  chaotic sd, the simulations' own Monte Carlo noise subtracted
  (``√max(mean(d²/σ²) − 1/n, 0)``).
* ``spread_ratio``: the median over features of the simulations' sd over the predicted
  chaotic sd.

The learned spread is that of single simulations at neighbouring parameters, so where the
features' mean is rough at the scale the networks resolve, it holds that roughness too:
``spread_ratio`` and ``mean_error`` then depart from 1 and 0 in step, and ``z_rms`` is what
decides. A point passes while ``z_rms`` is within a factor :data:`MAX_Z_FACTOR` of 1.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..inference.problem import Problem
from .design import simulate_design, unit_of_z
from .model import LearnedLikelihood

#: A point passes while its ``z_rms`` is within this factor of 1.
MAX_Z_FACTOR = 1.5


@dataclasses.dataclass(frozen=True)
class PointCheck:
    """One point's check: its label, the recording, ``z_rms``, the learned mean's error and
    the spread ratio (module docstring), and the number of simulations."""

    label: str
    recording: int
    z_rms: float
    mean_error: float
    spread_ratio: float
    simulations: int

    @property
    def passed(self) -> bool:
        return 1 / MAX_Z_FACTOR <= self.z_rms <= MAX_Z_FACTOR

    def as_dict(self) -> dict:
        return {**dataclasses.asdict(self), "passed": self.passed}


def check_point(
    problem: Problem,
    like: LearnedLikelihood,
    z,
    label: str,
    n: int,
    seed: np.random.SeedSequence,
) -> list[PointCheck]:
    """:class:`PointCheck` of every recording at ``z`` (P,) from ``n`` fresh simulations."""
    u = np.repeat(unit_of_z(np.asarray(z, float))[None], n, axis=0)
    out = []
    for r, child in enumerate(seed.spawn(problem.n_rec)):
        sims = simulate_design(problem, u, r, child)
        mean, chaotic, error = (np.asarray(x) for x in like.emulators[r].moments(jnp.asarray(u[0])))
        sd = np.sqrt(np.diag(chaotic))
        z_rms = float(np.sqrt(np.mean((sims - mean) ** 2 / np.diag(chaotic + error))))
        z2 = ((sims.mean(axis=0) - mean) / sd) ** 2
        mean_error = float(np.sqrt(max(np.mean(z2) - 1 / n, 0.0)))
        ratio = float(np.median(sims.std(axis=0, ddof=1) / sd))
        out.append(PointCheck(label, r, z_rms, mean_error, ratio, n))
    return out


def check_points(
    problem: Problem,
    like: LearnedLikelihood,
    points: dict[str, np.ndarray],
    n: int,
    seed: np.random.SeedSequence,
) -> list[PointCheck]:
    """:func:`check_point` at each labelled point of ``points`` (label → z)."""
    seeds = seed.spawn(len(points))
    return [
        c
        for (label, z), s in zip(points.items(), seeds, strict=True)
        for c in check_point(problem, like, z, label, n, s)
    ]
