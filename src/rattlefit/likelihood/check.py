"""The learned likelihood checked against the exact simulator.

At a few points (the optimum, the interval ends) fresh simulations are run, with the
density's variance floor added as noise, and mapped through the learned flow to their
whitened residuals, which are standard normal where the flow has learned the simulator's
distribution there. Three numbers per point and recording:

* ``z_rms``: the rms of the residuals over simulations and features. It is 1 where the
  learned density describes a recording made at that point, below 1 where it is too wide
  (conservative intervals), above 1 where it is too narrow.
* ``mean_error``: the rms over features of the residuals' mean, the simulations' own Monte
  Carlo noise subtracted (``√max(mean(r̄²) − 1/n, 0)``): the learned location's error in
  units of the learned spread.
* ``spread_ratio``: the median over features of the residuals' sd: the simulations' spread
  over the learned spread.

A point passes while ``z_rms`` is within a factor :data:`MAX_Z_FACTOR` of 1.
"""

from __future__ import annotations

import dataclasses

import jax
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
        s_sim, s_noise = child.spawn(2)
        density = like.densities[r]
        sims = simulate_design(problem, u, r, s_sim)
        sims = sims + np.sqrt(np.asarray(density.floor)) * np.random.default_rng(s_noise).normal(
            size=sims.shape
        )
        res = np.asarray(jax.vmap(density.residual)(jnp.asarray(sims), jnp.asarray(u)))
        z_rms = float(np.sqrt(np.mean(res**2)))
        mean_error = float(np.sqrt(max(np.mean(res.mean(axis=0) ** 2) - 1 / n, 0.0)))
        ratio = float(np.median(res.std(axis=0, ddof=1)))
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
