"""Least squares: Levenberg–Marquardt (optimistix) from the best of many screened starts.

The Jacobian that each Gauss–Newton step uses is a finite difference of the ensemble-mean
features (:func:`~rattlefit.problem.forward.jacobian_at`), handed to optimistix's solver
through its interactive interface: the solver's own iteration, with the simulation outside
its compiled step.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..likelihood.synthetic import band_sigma, ensemble_features
from ..problem import forward
from ..problem.options import FitOptions
from ..problem.problem import Problem
from .starts import prior_centre

#: Levenberg–Marquardt steps per start and recording when ``FitOptions.max_iterations`` is
#: None: each recording adds its own rugged cost.
LM_STEPS = 8
#: Consecutive rejected trial steps after which a run stops (:class:`StallingLevenbergMarquardt`):
#: the trust region has shrunk by 4⁻⁴ without a lower cost, so the point is a minimum at the
#: resolution of the simulated cost's noise.
LM_REJECTIONS = 4
#: Starts re-evaluated with all realisations beyond the ``n_refine`` that are refined.
SCREEN_EXTRA = 5
#: Candidates (refined optima, the best start) whose cost is within this many √(2·n_data)
#: (the statistic's own fluctuation scale) of the best are tested against the profile
#: threshold (:func:`~rattlefit.inference.profile.admit_rivals`); the rest are far outside.
RIVAL_SCREEN = 2.0


def linearised_residual(z, args):
    """The residual linearised at the last point simulated, ``args = (r, J, z_eval)``:
    ``r + J (z − z_eval)``, and no auxiliary output (optimistix's solver interface).

    :func:`levenberg_marquardt` evaluates it only where it was linearised (optimistix's
    Gauss–Newton step evaluates its function once a step, at the trial point ``y_eval``,
    and linearises it there), so there it is the fit's residual and Jacobian themselves."""
    r, jac, z_eval = args
    return r + jac @ (z - z_eval), None


@eqx.filter_jit
def lm_step(solver, z, state, args):
    """One optimistix step of ``solver`` on :func:`linearised_residual` (compiled once: the
    simulation is not part of it)."""
    return solver.step(linearised_residual, z, args, {}, state, frozenset())


def levenberg_marquardt(jacobian_at: Callable, solver, z0, max_steps: int):
    """optimistix's ``solver`` (a Gauss–Newton method) from ``z0``, stepped from Python
    through optimistix's interactive interface.

    Before each step, ``jacobian_at(z)`` gives the residual (n,) and its Jacobian (n, P) at
    the step's trial point (in a fit, :func:`~rattlefit.problem.forward.jacobian_at`,
    simulated by the fit's one compiled program), and the step sees them as
    :func:`linearised_residual`. The iteration is optimistix's own: each step linearises the
    residual at ``state.y_eval`` and accepts or rejects that point; the loop, like
    ``optimistix.least_squares``'s, ends once ``solver.terminate`` says so, the iterate is not
    finite, or after ``max_steps``. Keeping the simulation outside the solver's compiled step
    means one compiled simulator (and one set of realisations) for every stage of a fit.

    Returns ``(z, steps, result, state)``: the last accepted point, the steps taken, an
    ``optimistix.RESULTS`` and the solver's final state.
    """
    z = jnp.asarray(z0, dtype=float)
    r, jac = jacobian_at(np.asarray(z))  # the first step's: it is linearised at z0
    n_out = len(r)
    f_struct = jax.ShapeDtypeStruct((n_out,), z.dtype)
    args = (jnp.asarray(r), jnp.asarray(jac), z)
    state = solver.init(linearised_residual, z, args, {}, f_struct, None, frozenset())
    # one static part (the linear operator's jaxpr) for every run, so lm_step compiles once
    static = _LM_STATIC.setdefault(
        (type(solver), n_out, z.shape[0]), eqx.filter(state, eqx.is_array, inverse=True)
    )
    state = eqx.combine(eqx.filter(state, eqx.is_array), static)
    steps = 0
    while True:
        done, result = solver.terminate(linearised_residual, z, args, {}, state, frozenset())
        if not np.all(np.isfinite(np.asarray(z))):
            result = optx.RESULTS.nonfinite
        if bool(done) or result != optx.RESULTS.successful:
            break
        if steps == max_steps:
            result = optx.RESULTS.nonlinear_max_steps_reached
            break
        if steps:
            r, jac = jacobian_at(np.asarray(state.y_eval))
            args = (jnp.asarray(r), jnp.asarray(jac), jnp.asarray(state.y_eval))
        z, state, _ = lm_step(solver, z, state, args)
        steps += 1
    return np.asarray(z), steps, result, state


#: The static part of :func:`levenberg_marquardt`'s initial solver state, by (solver type,
#: residual length, parameters): reused so that :func:`lm_step` is traced once a shape.
_LM_STATIC: dict = {}


def lm_steps(options: FitOptions, n_recordings: int) -> int:
    """Levenberg–Marquardt steps per start: ``options.max_iterations``, or :data:`LM_STEPS` per
    recording when it is None."""
    return options.max_iterations or LM_STEPS * n_recordings


class StallingLevenbergMarquardt(optx.LevenbergMarquardt):
    """optimistix's Levenberg–Marquardt, which also stops once :data:`LM_REJECTIONS` trial
    steps in a row have been rejected: the trust region has then shrunk by 4⁻⁴ (each
    rejection quarters it) without finding a lower cost, so the last accepted point is a
    minimum at the resolution of the simulated cost's noise, and a further step would most
    likely be rejected too. Each trial step costs a finite-difference Jacobian (P + 1 points:
    optimistix linearises the residual wherever it evaluates it), so these are the fit's
    most expensive wasted evaluations. The solve reports success, as at convergence:
    :meth:`stalled` tells the two apart.
    """

    def terminate(self, fn, y, args, options, state, tags):
        done, result = super().terminate(fn, y, args, options, state, tags)
        return done | self.stalled(state), result

    @staticmethod
    def stalled(state):
        """Whether the last :data:`LM_REJECTIONS` trial steps were all rejected."""
        return state.num_steps_since_acceptance >= LM_REJECTIONS


@dataclasses.dataclass(frozen=True)
class Refined:
    """What :func:`refine_starts` hands to the covariance and profile stages."""

    problem: Problem  # with the band spread estimated at the best start
    optimum: np.ndarray  # (P,) the lowest candidate
    contenders: list  # the candidates within RIVAL_SCREEN of it, the optimum first
    n_iter: int  # Levenberg–Marquardt steps over all starts
    converged: bool  # every start converged (or stalled) before its step limit
    stalled: tuple[bool, ...]  # each run: stalled (:class:`StallingLevenbergMarquardt`)


def screen_starts(
    problem: Problem, starts, options: FitOptions, rng, say
) -> tuple[Problem, np.ndarray, np.ndarray]:
    """Rank ``starts`` (N, P): the band spread estimated at the prior centre, the starts
    screened with a few realisations each, the spread re-estimated at the best start and the
    starts re-ranked, the best re-evaluated with all realisations.

    Returns the problem with the spread at the best start, each start's cost (inf where not
    re-evaluated) and the indices of the best ``n_refine`` + :data:`SCREEN_EXTRA`, best first.
    """
    screen = options.screen
    say("estimating the run-to-run spread of the features …")
    ens = ensemble_features(problem, prior_centre(problem.specs), options.n_noise_realisations, rng)
    sigma = band_sigma(problem, options, ens)
    k_screen = min(options.start_realisations, options.n_realisations)
    say(
        f"screening {len(starts)} starting points with {k_screen} realisation(s) each "
        "(compiling the simulator first) …"
    )
    features = forward.evaluate(problem, starts, problem.y0[:, :k_screen])
    problem = eqx.tree_at(lambda q: q.sigma, problem, sigma)
    costs = forward.costs(problem, starts, forward.screen_features(problem, features, screen))
    # the spread at the prior centre can be far from the spread near the data (violent
    # rattle scatters more than mild): the weights are re-estimated at the best start and
    # the starts re-ranked with them (their features are kept, so this costs no simulation)
    say("re-estimating the spread at the best start …")
    best = starts[np.argmin(costs)]
    ens = ensemble_features(problem, best, options.n_noise_realisations, rng)
    problem = eqx.tree_at(lambda q: q.sigma, problem, band_sigma(problem, options, ens))
    costs = forward.costs(problem, starts, forward.screen_features(problem, features, screen))
    order = np.argsort(costs)[: options.n_refine + SCREEN_EXTRA]
    if k_screen < options.n_realisations:
        say(f"re-evaluating the best {len(order)} with {options.n_realisations} realisations …")
        costs = np.full(len(starts), np.inf)
        costs[order] = forward.costs(problem, starts[order])
        order = order[np.argsort(costs[order])]
    say("best start costs: " + ", ".join(f"{costs[i]:.1f}" for i in order[: options.n_refine + 3]))
    return problem, costs, order


def run_from(problem: Problem, start, max_steps: int, say) -> tuple:
    """One Levenberg–Marquardt run from ``start``: ``(z, steps, converged, stalled, cost)``,
    ``converged`` False at the step limit, ``cost`` the squared residual at ``z``."""
    solver = StallingLevenbergMarquardt(rtol=1e-2, atol=1e-2)
    z, steps, result, state = levenberg_marquardt(
        functools.partial(forward.jacobian_at, problem), solver, start, max_steps
    )
    ok = bool(result == optx.RESULTS.successful)
    stalled = ok and bool(StallingLevenbergMarquardt.stalled(state))
    if not ok:
        how = "stopped at the step limit"
    elif stalled:
        how = f"stalled: {LM_REJECTIONS} trial steps in a row rejected"
    else:
        how = "converged"
    say(f"  → {steps} steps ({how})")
    cost = float(np.sum(np.asarray(state.f_info.residual) ** 2))  # at z, the last accepted
    return z, steps, ok, stalled, cost


def refine_starts(problem: Problem, starts, options: FitOptions, rng, say) -> Refined:
    """The search stage of a fit: :func:`screen_starts`, Levenberg–Marquardt from the best
    ``n_refine`` (:func:`run_from`), and the candidates (the optima and the best start)
    compared in one cost."""
    problem, costs, order = screen_starts(problem, starts, options, rng, say)
    max_steps = lm_steps(options, problem.n_rec)
    optima = []
    for rank, i in enumerate(order[: options.n_refine]):
        say(f"Levenberg–Marquardt from start {rank + 1}/{options.n_refine} (cost {costs[i]:.1f}) …")
        optima.append(run_from(problem, starts[i], max_steps, say))
    # the candidates: the optima and the best start, each with its cost from the one compiled
    # program of evaluate (a row's features do not depend on the rows it is simulated with,
    # so these are the costs a batch of the candidates would give, to the last bit)
    candidates = np.stack([o[0] for o in optima] + [starts[order[0]]])
    k_screen = min(options.start_realisations, options.n_realisations)
    if k_screen < options.n_realisations or options.screen == "mean":
        start_cost = costs[order[0]]  # of all n_realisations, in these weights
    else:
        start_cost = forward.costs(problem, starts[order[:1]])[0]
    final = np.array([o[4] for o in optima] + [start_cost])
    rank = np.argsort(final)
    say("candidate costs: " + ", ".join(f"{final[i]:.1f}" for i in rank))
    # the other candidates close enough in this cost to be inside the 95 % region are tested
    # against the profile threshold, in the profiles' own cost, in the profile stage
    tolerance = RIVAL_SCREEN * math.sqrt(2.0 * int(np.prod(problem.data.shape)))
    contenders = [candidates[i] for i in rank if final[i] - final[rank[0]] < tolerance]
    return Refined(
        problem,
        candidates[rank[0]],
        contenders,
        sum(o[1] for o in optima),
        all(o[2] for o in optima),
        tuple(o[3] for o in optima),
    )
