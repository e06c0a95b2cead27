"""The profile stage of a fit: the free parameters' 95 % intervals from their cost profiles.

Given the Laplace stage at the optimum (:func:`~rattlefit.inference.laplace.laplace_at`),
:func:`profile_stage` sets the threshold (χ²₁ plus the Monte Carlo noise of a Δcost, widened
to the cost's measured roughness near the optimum), scans each free parameter's profile,
admits rival candidates that lie inside the threshold, bisects the interval ends,
re-optimises the other parameters at the values that decide them and follows the profiles
past their ends (:mod:`rattlefit.inference.profile.curves`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence

import numpy as np

from ...confidence import Z95, Z95_ONE_SIDED
from ...likelihood.synthetic import synthetic_cost
from ...problem.forward import chunk_size, evaluate, residuals
from ...problem.options import FitOptions
from ...problem.parameters import Z_END
from ...problem.problem import Problem, redrawn, release_states
from ..laplace import Laplace
from .curves import (
    CONTINUATION_LOG_STEP,
    PROFILE_JITTER,
    SCAN_SAME,
    ProfileCosts,
    Valley,
    admit_rivals,
    bisect_profile_ends,
    continue_profiles,
    jitter_noise,
    keep_lower,
    lower_profile_point,
    polish_profile,
    profile_interval,
    profile_scan,
    profile_threshold,
)

#: The damping values λ of each polish iteration's trial steps (:func:`polish_profile`, whose
#: default adds 3.0): two trials and the default fill one compiled evaluation.
POLISH_DAMPING = (0.03, 0.3)
#: One-sided 95 % quantile of the standard normal: the Monte Carlo allowance for a profile's
#: lowest point below the optimum (:func:`~rattlefit.inference.profile.lower_profile_point`).


@dataclasses.dataclass(frozen=True)
class ProfileStage:
    """What :func:`profile_stage` found.

    profiles : parameter index → profile ``{t: (Δcost, z)}`` (:func:`profile_interval`).
    threshold : the Δcost above the optimum's that ends an interval.
    info : what set the threshold (``threshold``, ``monte_carlo_sd`` and, with the roughness
        allowance, ``roughness_rms``, ``realisation_sets``, ``roughness_sd``).
    z_lo, z_hi : (P,) Laplace interval ends in z, widened to span admitted rivals.
    noise_sd : standard deviation of the Monte Carlo noise of a Δcost.
    lower : ``(Δcost, z)`` of a profile point below the optimum by more than its Monte
        Carlo allowance, or None.
    """

    profiles: dict
    threshold: float
    info: dict
    z_lo: np.ndarray
    z_hi: np.ndarray
    noise_sd: float
    lower: tuple | None


def monte_carlo_sd(lap: Laplace, n_cov: int, dof_rec: float) -> float:
    """Standard deviation of the Monte Carlo noise of a difference of two costs of ``n_cov``
    realisations: each cost varies by ≈ 4χ²/(n+1) from the mean features (in the inflated
    units) and ≈ 2B/ν from the log-spread term of the R·B bands (ν the spread's degrees of
    freedom; :func:`~rattlefit.likelihood.synthetic.synthetic_cost`)."""
    chi2_rec = lap.noise.chi2_recordings
    inflation = np.maximum(1.0, chi2_rec / dof_rec)
    var_cost = np.sum(4.0 * np.maximum(chi2_rec, dof_rec) / (n_cov + 1) / inflation**2)
    var_cost += 2.0 * lap.problem.n_rec * lap.problem.n_bands / lap.noise.sigma_dof
    return math.sqrt(2.0 * var_cost)


def jitter_points(problem: Problem, z, only: Sequence[int] | None = None) -> np.ndarray:
    """Points :data:`PROFILE_JITTER` away from ``z`` in each free parameter (1–2 %; of
    ``only``, when given), where the cost's smooth part is negligible and its spread is the
    noise of a profile's Δcost."""
    p = len(problem.specs)
    free = [
        i for i, s in enumerate(problem.specs) if not s.nuisance and (only is None or i in only)
    ]
    jitter = np.stack([z + h * np.eye(p)[i] for i in free for h in PROFILE_JITTER])
    return np.clip(jitter, -Z_END, Z_END)


def roughness_costs(lap: Laplace, options: FitOptions, points, first_dcosts, y0, rng) -> np.ndarray:
    """The Δcosts of the jitter ``points`` (the optimum first) over ``roughness_sets``
    independent realisation sets, the first given (sets × points): what repeats from set to
    set is the cost's structure, what does not is its noise."""
    out = first_dcosts[None]
    z = points[0]
    for child in rng.spawn(options.roughness_sets - 1):
        per = evaluate(
            redrawn(lap.problem, options.dither, child),
            points,
            release_states(lap.problem, z, y0.shape[1], child),
        )
        c = np.array(
            [
                synthetic_cost(lap.problem, options, lap.noise, per[k], points[k])
                for k in range(len(points))
            ]
        )
        out = np.concatenate([out, (c[1:] - c[0])[None]])
    return out


def roughness_threshold(jitter_costs, noise_sd: float, info: dict, say) -> float:
    """The threshold widened to the jitter Δcosts' noise (:func:`profile_threshold`);
    records the roughness in ``info``."""
    threshold = profile_threshold(noise_sd, jitter_costs)
    rms = jitter_noise(jitter_costs[0])
    spread = ""
    info.update(roughness_rms=float(rms), realisation_sets=len(jitter_costs))
    if len(jitter_costs) > 1:
        sd_sets = jitter_noise(jitter_costs)
        spread = f", sd {sd_sets:.1f} over {len(jitter_costs)} realisation sets"
        info["roughness_sd"] = float(sd_sets)
    say(
        f"  profile roughness: Δcost rms {rms:.1f}{spread} within 1–2 % of the "
        f"optimum (Monte Carlo alone: {noise_sd:.1f}); threshold {threshold:.1f}"
    )
    return threshold


def polish_points(problem: Problem, options: FitOptions, starts, fixed) -> np.ndarray:
    """The other parameters re-optimised at each of ``starts`` (K, P), parameter ``fixed[k]``
    held (:func:`polish_profile` on the fit's residual)."""
    steps = np.stack([problem.fd_steps(zk) for zk in starts])
    return polish_profile(
        lambda pts: residuals(problem, pts),
        starts,
        fixed,
        steps,
        iterations=options.polish_iterations,
        damping=POLISH_DAMPING,
    )


@dataclasses.dataclass(frozen=True)
class ProfileWork:
    """What the refinements of the profiles share: the optimum and its covariance, the
    threshold, the costs and the hooks."""

    z: np.ndarray
    cov: np.ndarray
    threshold: float
    costs: ProfileCosts
    polish: Callable
    valley: Valley | None
    options: FitOptions
    say: Callable[[str], None]


def bisect_ends(work: ProfileWork, profiles: dict) -> None:
    """Bisect the brackets of the interval ends, then complete the ends' costs."""
    n = bisect_profile_ends(
        profiles,
        work.threshold,
        work.z,
        work.cov,
        work.costs,
        rounds=work.options.profile_bisections,
        valley=work.valley,
    )
    work.costs.complete_ends(profiles, work.threshold)
    if n:
        work.say(f"  bisected the profile intervals' ends ({n} points)")


def polish_rounds(work: ProfileWork, profiles: dict) -> None:
    """Re-optimise the other parameters at the scanned values just outside each interval
    (a profile likelihood), and once more if that moved an end outwards."""
    polished: set[tuple[int, float]] = set()
    for _ in range(work.options.profile_rounds):
        todo = [
            (i, t_out)
            for i, prof in profiles.items()
            for _, t_out in profile_interval(prof, work.threshold)[1]
            if (i, t_out) not in polished
        ]
        if not todo:
            break
        work.say(f"re-optimising the other parameters at {len(todo)} profile value(s) …")
        ends = work.polish(np.stack([profiles[i][t][1] for i, t in todo]), [i for i, _ in todo])
        for (i, t), zk, dc in zip(todo, ends, work.costs(ends), strict=True):
            polished.add((i, t))
            keep_lower(profiles[i], t, float(dc), zk)
        # a polished value that fell inside leaves a wide bracket behind it
        bisect_ends(work, profiles)


def continue_ends(work: ProfileWork, profiles: dict, specs) -> None:
    """Follow the profiles past their ends by continuation, then bisect the new ends."""
    work.say("following the profiles past their ends …")
    n_cont = continue_profiles(
        profiles,
        work.threshold,
        work.costs,
        work.polish,
        lambda i, t: CONTINUATION_LOG_STEP / float(specs[i].dlog_dz(t)),
        rounds=work.options.profile_continuation,
        valley=work.valley,
    )
    work.say(f"  {n_cont} continuation point(s)")
    bisect_ends(work, profiles)


def profile_stage(
    lap: Laplace,
    z,
    contenders,
    y0,
    options: FitOptions,
    *,
    valley: Valley | None,
    dof_rec: float,
    rng,
    say,
    only: Sequence[int] | None = None,
) -> ProfileStage:
    """The free parameters' profiles about the optimum ``z`` of the Laplace stage ``lap``,
    their threshold and the rival candidates inside it (see the module docstring).

    ``contenders`` are the search's candidates (the optimum first), ``y0`` (R, n, 2) the
    release states of the covariance realisations, ``rng`` seeds further realisation sets;
    ``only`` (indices) profiles those free parameters alone.
    """
    problem, specs = lap.problem, lap.problem.specs
    sd = np.sqrt(np.clip(np.diag(lap.covariance), 0, None))
    z_lo, z_hi = z - Z95 * sd, z + Z95 * sd
    # the Laplace interval is local and Gaussian: the free parameters' intervals come from a
    # scan of their cost profiles over the whole range (a → 0 is dry flanks)
    say("scanning the profiles of the free parameters …")
    noise_sd = monte_carlo_sd(lap, y0.shape[1], dof_rec)
    threshold = profile_threshold(noise_sd)
    info = {"monte_carlo_sd": noise_sd}
    cost_of = functools.partial(synthetic_cost, problem, options, lap.noise)

    # the optimum, the other candidates distinct from it, and with the roughness allowance
    # the points 1–2 % away: one batched evaluation
    others = [zr for zr in contenders if np.max(np.abs(zr - z)) > SCAN_SAME]
    jitter = jitter_points(problem, z, only) if options.profile_roughness else np.empty((0, len(z)))
    near = np.concatenate([z[None], jitter, *(zr[None] for zr in others)])
    per_near = evaluate(problem, near, y0)
    costs_near = np.array([cost_of(per_near[k], near[k]) for k in range(len(near))])
    dcost_near = costs_near[1:] - costs_near[0]
    if len(jitter):
        jitter_costs = roughness_costs(
            lap, options, near[: 1 + len(jitter)], dcost_near[: len(jitter)], y0, rng
        )
        threshold = roughness_threshold(jitter_costs, noise_sd, info, say)
    info["threshold"] = float(threshold)
    costs = ProfileCosts(
        functools.partial(evaluate, problem, y0=y0),
        cost_of,
        per_near[: 1 + len(jitter)],
        near[: 1 + len(jitter)],
        threshold,
        options.profile_screen,
        chunk=chunk_size(),
    )
    if costs.limit is not None:
        say(
            f"  profile values simulated with {options.profile_screen} of {y0.shape[1]} "
            f"realisations first; set aside above Δcost {costs.limit:.0f} "
            f"(Δcost rms {costs.noise:.1f} with {options.profile_screen} near the optimum)"
        )
    profiles = profile_scan(specs, z, lap.covariance, costs, valley=valley, only=only)
    rivals = admit_rivals(profiles, others, dcost_near[len(jitter) :], threshold)
    costs.complete_ends(profiles, threshold)
    if others:
        say(
            f"  {len(rivals)} of {len(others)} other candidate(s) inside the 95 % region "
            f"(Δcost {', '.join(f'{c:.1f}' for c in dcost_near[len(jitter) :])} against "
            f"{threshold:.1f})" + (": the intervals span them" if rivals else "")
        )
    for zr in rivals:
        # a rival's own interval is taken to be as wide as the optimum's: this moves only
        # the nuisances' ends (the free parameters' profiles now hold the rival)
        z_lo, z_hi = np.minimum(z_lo, zr - Z95 * sd), np.maximum(z_hi, zr + Z95 * sd)

    polish = functools.partial(polish_points, problem, options)
    work = ProfileWork(z, lap.covariance, threshold, costs, polish, valley, options, say)
    bisect_ends(work, profiles)
    polish_rounds(work, profiles)
    if options.profile_continuation:
        continue_ends(work, profiles, specs)
    if costs.n_set_aside:
        say(
            f"  {costs.n_set_aside} of {costs.n_screened} screened profile "
            f"points set aside after {options.profile_screen} realisations "
            f"({costs.n_completed} completed later: they end a bracket)"
        )
    # the optimum should be the profiles' minimum (see lower_profile_point)
    lower = lower_profile_point(profiles, Z95_ONE_SIDED * noise_sd)
    return ProfileStage(profiles, threshold, info, z_lo, z_hi, noise_sd, lower)
