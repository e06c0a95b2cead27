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
* ``recording_distance``: the rms over features of the recording's distance to the
  simulations' mean, in units of their sd (with the floor): about 1 where the recording could
  have come from this point. The learned likelihood can misjudge a recording far outside what
  it was trained on at a point; an optimum whose simulations lie more than
  :data:`FAR_RECORDING` from the recording is then not where the simulator puts it (or the
  model misses the recording), and identify warns.

A point passes while ``z_rms`` is within a factor :data:`MAX_Z_FACTOR` of 1.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..problem.problem import Problem
from .design import simulate_design, unit_of_z
from .model import LearnedLikelihood

#: A point passes while its ``z_rms`` is within this factor of 1.
MAX_Z_FACTOR = 1.5
#: A recording farther than this (rms sd over the features) from the simulations at the
#: optimum is not where the simulator puts it; at its own parameters it is about 1.
FAR_RECORDING = 3.0


@dataclasses.dataclass(frozen=True)
class PointCheck:
    """One point's check: its label, the recording, ``z_rms``, the learned mean's error, the
    spread ratio and the recording's distance (module docstring), and the number of
    simulations."""

    label: str
    recording: int
    z_rms: float
    mean_error: float
    spread_ratio: float
    simulations: int
    recording_distance: float

    @property
    def passed(self) -> bool:
        return 1 / MAX_Z_FACTOR <= self.z_rms <= MAX_Z_FACTOR

    def as_dict(self) -> dict:
        return {**dataclasses.asdict(self), "passed": self.passed}


def simulations_with_floor(
    problem: Problem,
    like: LearnedLikelihood,
    u,
    recording: int,
    seed: np.random.SeedSequence,
) -> np.ndarray:
    """Features (N, F) of recording ``recording``'s rig at design points ``u`` (N, P), one
    simulation each (:func:`~rattlefit.likelihood.design.simulate_design`), with its
    density's variance floor added as Gaussian noise: recordings as the learned likelihood
    describes them."""
    s_sim, s_noise = seed.spawn(2)
    sims = simulate_design(problem, u, recording, s_sim)
    floor = np.asarray(like.densities[recording].floor)
    return sims + np.sqrt(floor) * np.random.default_rng(s_noise).normal(size=sims.shape)


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
        density = like.densities[r]
        sims = simulations_with_floor(problem, like, u, r, child)
        res = np.asarray(jax.vmap(density.residual)(jnp.asarray(sims), jnp.asarray(u)))
        z_rms = float(np.sqrt(np.mean(res**2)))
        mean_error = float(np.sqrt(max(np.mean(res.mean(axis=0) ** 2) - 1 / n, 0.0)))
        ratio = float(np.median(res.std(axis=0, ddof=1)))
        sd = np.sqrt(np.maximum(sims.var(axis=0, ddof=1), np.asarray(density.floor)))
        distance = float(np.sqrt(np.mean(((np.asarray(like.data[r]) - sims.mean(0)) / sd) ** 2)))
        out.append(PointCheck(label, r, z_rms, mean_error, ratio, n, distance))
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
