"""Learning the likelihood in rounds: a space-filling start over the priors, then rounds
drawn from the current posterior.

Round 0 simulates a scrambled Sobol' design over the prior box
(:func:`~rattlefit.likelihood.design.prior_box`) and trains each recording's feature density on it.
Each later round draws its design points from the current learned posterior, tempered
(the likelihood raised to :attr:`LearningOptions.tempering`) so that its tails are covered,
simulates them and retrains on everything simulated so far. Every random choice
descends from one seed by :class:`numpy.random.SeedSequence` spawning, so the same seed gives
the same design, simulations and networks.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import emcee
import jax
import jax.numpy as jnp
import numpy as np

from ..problem.problem import Problem
from .density import DensityOptions, fit_density
from .design import prior_box, simulate_design, sobol_design, unit_of_z, z_of_unit
from .model import LearnedLikelihood, batch_cost, batch_log_density


@dataclasses.dataclass(frozen=True)
class LearningOptions:
    """The simulation budget and its rounds.

    ``initial``: simulations per recording of the space-filling round 0.
    ``rounds``: later rounds, each of ``per_round`` simulations per recording drawn from the
    current posterior with the likelihood raised to ``tempering`` (0.5 widens a Gaussian
    posterior by √2). ``walkers`` and ``steps``: the ensemble sampler that draws them (half the
    steps discarded). ``density``: the flow and its training.
    """

    initial: int = 1024
    rounds: int = 3
    per_round: int = 512
    tempering: float = 0.5
    walkers: int = 64
    steps: int = 400
    density: DensityOptions = dataclasses.field(default_factory=DensityOptions)

    def __post_init__(self):
        if self.initial < 16 or self.per_round < 1 or self.rounds < 0:
            raise ValueError("LearningOptions: initial ≥ 16, per_round ≥ 1, rounds ≥ 0 needed")
        if not 0 < self.tempering <= 1:
            raise ValueError(f"LearningOptions.tempering: need 0 < t ≤ 1, got {self.tempering}")

    @property
    def budget(self) -> int:
        """Simulations per recording."""
        return self.initial + self.rounds * self.per_round


@dataclasses.dataclass(frozen=True)
class RoundRecord:
    """What one round cost and did: simulations per recording, wall times (s) of simulating
    and training, simulations per second per core, and each density's best validation loss."""

    simulations: int
    simulate_seconds: float
    train_seconds: float
    per_second_per_core: float
    losses: tuple[float, ...]


@dataclasses.dataclass(frozen=True)
class Design:
    """Everything simulated: design points ``u`` (N, P) and each recording's features
    (R, N, F). With the seed it reproduces the learned likelihood."""

    u: np.ndarray
    features: np.ndarray

    def extended(self, u, features) -> Design:
        return Design(np.concatenate([self.u, u]), np.concatenate([self.features, features], 1))


def recording_columns(problem: Problem, r: int) -> tuple[int, ...]:
    """The parameter indices recording ``r``'s simulation reads: its film half-length, the
    shared parameters, its own backlash and any effect's fields."""
    names = [s.name for s in problem.specs]
    other_films = set(problem.films) - {problem.films[r]}
    other_backlash = {f"backlash[{k}]" for k in range(problem.n_rec) if k != r}
    return tuple(i for i, n in enumerate(names) if n not in other_films | other_backlash)


def simulate_round(problem: Problem, u, seed: np.random.SeedSequence) -> np.ndarray:
    """Features (R, N, F) of every recording at design points ``u`` (N, P)."""
    seeds = seed.spawn(problem.n_rec)
    return np.stack([simulate_design(problem, u, r, seeds[r]) for r in range(problem.n_rec)])


def train(
    problem: Problem,
    design: Design,
    options: LearningOptions,
    seed: np.random.SeedSequence,
    *,
    floor=None,
) -> tuple[LearnedLikelihood, tuple[float, ...]]:
    """The learned likelihood trained on ``design`` with the variance ``floor`` (F,) added to
    the features; and each density's best validation loss."""
    densities, losses = [], []
    for r, child in enumerate(seed.spawn(problem.n_rec)):
        cols = recording_columns(problem, r)
        d, loss = fit_density(
            design.u, design.features[r], cols, options.density, child, floor=floor
        )
        densities.append(d)
        losses.append(loss)
    like = LearnedLikelihood(tuple(densities), jnp.asarray(problem.data), problem.specs)
    return like, tuple(losses)


def posterior_draws(
    like: LearnedLikelihood,
    n: int,
    starts,
    options: LearningOptions,
    seed: np.random.SeedSequence,
    tempering: float,
) -> np.ndarray:
    """``n`` design points (n, P) in ``u`` drawn from the learned posterior with the
    likelihood raised to ``tempering``: an ensemble sampler started at ``starts`` (z, at least
    one), the second half of its chain thinned to ``n`` points."""
    rng = np.random.default_rng(seed)
    starts = np.atleast_2d(starts)
    p0 = starts[rng.integers(len(starts), size=options.walkers)]
    p0 = p0 + 0.05 * rng.normal(size=p0.shape)
    sampler = emcee.EnsembleSampler(
        options.walkers,
        p0.shape[1],
        lambda zs: np.asarray(batch_log_density(like, jnp.asarray(zs), tempering)),
        vectorize=True,
    )
    sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
    sampler.run_mcmc(p0, options.steps)
    chain = sampler.get_chain(discard=options.steps // 2, flat=True)
    keep = rng.choice(len(chain), size=n, replace=len(chain) < n)
    return unit_of_z(chain[keep])


def best_points(like: LearnedLikelihood, u, k: int) -> np.ndarray:
    """The ``k`` design points (z) of lowest learned cost."""
    z = z_of_unit(u)
    costs = np.asarray(batch_cost(like, jnp.asarray(z)))
    costs = np.where(np.isfinite(costs), costs, np.inf)
    return z[np.argsort(costs)[:k]]


def learn_likelihood(
    problem: Problem,
    options: LearningOptions | None = None,
    *,
    seed: int | np.random.SeedSequence = 0,
    start: tuple[LearnedLikelihood, Design] | None = None,
    floor=None,
    progress: Callable[[str], None] | None = None,
) -> tuple[LearnedLikelihood, Design, tuple[RoundRecord, ...]]:
    """Learn the likelihood of ``problem``'s recordings in rounds (module docstring), with
    the variance ``floor`` (F,) added to every simulation's features.

    ``start`` (a likelihood and its design, e.g. a stored one of this test point) replaces
    round 0: only the posterior rounds run, on top of its design. Returns the learned
    likelihood, the design it was trained on, and a record per round.
    """
    options = options or LearningOptions()
    say = progress or (lambda _msg: None)
    root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    design_seed, *round_seeds = root.spawn(options.rounds + 1)
    cores = max(len(jax.local_devices()), 1)
    records = []
    like, design = start if start is not None else (None, None)
    for k in range(options.rounds + 1):
        if k == 0 and start is not None:
            continue
        s_design, s_sim, s_train = (design_seed if k == 0 else round_seeds[k - 1]).spawn(3)
        if k == 0:
            n = options.initial
            u = sobol_design(n, *prior_box(problem), s_design)
        else:
            n = options.per_round
            starts = best_points(like, design.u, 16)
            u = posterior_draws(like, n, starts, options, s_design, options.tempering)
        t0 = time.perf_counter()
        feats = simulate_round(problem, u, s_sim)
        t1 = time.perf_counter()
        design = Design(u, feats) if design is None else design.extended(u, feats)
        like, losses = train(problem, design, options, s_train, floor=floor)
        t2 = time.perf_counter()
        rate = n * problem.n_rec / (t1 - t0) / cores
        records.append(RoundRecord(n, t1 - t0, t2 - t1, rate, losses))
        say(
            f"learning round {k}: {n} simulations per recording in {t1 - t0:.1f} s "
            f"({rate:.1f} per s per core), trained in {t2 - t1:.1f} s"
        )
    return like, design, tuple(records)
