"""The learned likelihood checked against the exact simulator.

At a few points (the optimum, the interval ends) fresh simulations are run and compared with
what the emulator predicts there, on the scale that matters to a fit: one recording's
run-to-run spread. Two numbers per point and recording:

* ``mean_error``: the rms over features of the emulator's mean error in units of the
  predicted chaotic sd, the simulations' own Monte Carlo noise subtracted
  (``√max(mean(d²/σ²) − 1/n, 0)``). An error ``e`` adds about ``e²`` to the data's variance in
  each feature, so 0.5 widens the likelihood's spread by about 12 %.
* ``spread_ratio``: the median over features of the simulations' sd over the predicted
  chaotic sd.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..inference.problem import Problem
from .design import simulate_design, unit_of_z
from .model import LearnedLikelihood

#: A point passes while the emulator's mean error is at most this share of the spread...
MAX_MEAN_ERROR = 0.5
#: ...and the simulations' spread is within this factor of the predicted one.
MAX_SPREAD_FACTOR = 1.5


@dataclasses.dataclass(frozen=True)
class PointCheck:
    """One point's check: its label, the recording, the emulator's mean error and the
    spread ratio (module docstring), and the number of simulations."""

    label: str
    recording: int
    mean_error: float
    spread_ratio: float
    simulations: int

    @property
    def passed(self) -> bool:
        return (
            self.mean_error <= MAX_MEAN_ERROR
            and 1 / MAX_SPREAD_FACTOR <= self.spread_ratio <= MAX_SPREAD_FACTOR
        )

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
        mean, chaotic, _ = (np.asarray(x) for x in like.emulators[r].moments(jnp.asarray(u[0])))
        sd = np.sqrt(np.diag(chaotic))
        z2 = ((sims.mean(axis=0) - mean) / sd) ** 2
        error = float(np.sqrt(max(np.mean(z2) - 1 / n, 0.0)))
        ratio = float(np.median(sims.std(axis=0, ddof=1) / sd))
        out.append(PointCheck(label, r, error, ratio, n))
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
