"""Where the learned likelihood's simulations are spent, and simulating them.

A design point is a vector ``u`` of the fit's parameters in the unit box: each parameter's
log value as a fraction of its range, ``u = sigmoid(z)`` in the fit's unconstrained
coordinate ``z`` (:class:`~rattlefit.problem.parameters.ParameterSpec`). The first round
fills the prior box with a scrambled Sobol' sequence; later rounds draw from the current
posterior, tempered so that its tails are covered too (:mod:`rattlefit.likelihood.learn`).
Each design point is simulated once, with its own release state and encoder count phases and
no dither: the learned model, not an average, smooths over the chaos.
"""

from __future__ import annotations

import numpy as np
from scipy.special import expit, logit
from scipy.stats import qmc

from ..problem.forward import evaluate_rows
from ..problem.problem import Problem
from ..quantities import DRAG_TORQUE

#: A parameter with a prior is designed over its prior's central ± this many sd (in log),
#: clipped to its range; one without (a film half-length, the drag torque) over its range.
PRIOR_SDS = 3.5

#: The unit-box margin kept from the ends of a range (z = ±9.2): the simulator is defined
#: there, and the coordinate map stays finite.
EDGE = 1e-4


def prior_box(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """The first round's box in ``u``, (P,) lower and upper ends (see :data:`PRIOR_SDS`)."""
    lo, hi = [], []
    for s in problem.specs:
        if s.log_sd is None:
            lo.append(EDGE)
            hi.append(1 - EDGE)
            continue
        c = (np.log(s.center) - np.log(s.lower)) / s.log_range
        w = PRIOR_SDS * s.log_sd / s.log_range
        lo.append(max(c - w, EDGE))
        hi.append(min(c + w, 1 - EDGE))
    return np.asarray(lo), np.asarray(hi)


def sobol_design(n: int, lower, upper, seed: np.random.SeedSequence) -> np.ndarray:
    """``n`` points of a scrambled Sobol' sequence (seeded by ``seed``) in the box
    ``[lower, upper]``: (n, P)."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    sampler = qmc.Sobol(d=lower.size, scramble=True, seed=np.random.default_rng(seed))
    m = int(np.ceil(np.log2(max(n, 2))))
    return (lower + (upper - lower) * sampler.random_base2(m))[:n]


def z_of_unit(u) -> np.ndarray:
    """The fit's unconstrained coordinate of unit-box points ``u``."""
    return logit(np.clip(np.asarray(u, float), EDGE, 1 - EDGE))


def unit_of_z(z) -> np.ndarray:
    """The unit-box point of the fit's unconstrained coordinate ``z``."""
    return expit(np.asarray(z, float))


def simulate_design(
    problem: Problem, u, recording: int, seed: np.random.SeedSequence
) -> np.ndarray:
    """Features (N, F) of recording ``recording``'s rig at each design point ``u`` (N, P),
    one simulation each, with release states (at rest, uniform across ±90 % of the point's
    backlash) and encoder count phases drawn from ``seed``, and no dither.

    Only the point's parameters that this recording's model reads matter; the rows are
    simulated in the order of their drag torque, which sets their cost (see
    :func:`~rattlefit.problem.forward.evaluate`).
    """
    u = np.atleast_2d(np.asarray(u, float))
    z = z_of_unit(u)
    n = z.shape[0]
    rng = np.random.default_rng(seed)
    backlash = problem.specs[problem.index(f"backlash[{recording}]")]
    half_gap = 0.5 * backlash.value(z[:, problem.index(f"backlash[{recording}]")])
    y0 = np.zeros((n, 2))
    y0[:, 0] = rng.uniform(-0.9, 0.9, size=n) * half_gap
    phase = rng.uniform(size=(n, 2))
    order = np.argsort(z[:, problem.index(DRAG_TORQUE)], kind="stable")
    rows = (
        z[order],
        np.full(n, recording),
        y0[order],
        np.zeros_like(z),
        phase[order],
    )
    out = np.empty((n, problem.data.shape[-1]))
    out[order] = evaluate_rows(problem, rows)
    return out
