"""Identify a, T_b and the effective viscosity from recordings: the fit's orchestration.

The paper tuned the oil-film half-length ``a`` by comparing measured and simulated FFT spectra
by eye; :func:`identify` does it by least squares on log band PSDs of Δθ*, over ``a``, the
drag torque and the viscosity (a factor on the catalogue viscosity at each recording's
temperature), with the nuisances a real rig needs (mesh-stiffness scale, ``h_min``, each
recording's backlash) fitted under their priors. Each parameter is fitted in an unconstrained
coordinate ``z`` (:mod:`~rattlefit.problem.parameters`).

The stages, each a function of its own module:

1. the problem and its seeded realisations (:func:`~rattlefit.problem.problem.problem_from`);
2. the search: seeded starts (:mod:`~rattlefit.inference.starts`; across lubrications also
   where each lubrication's own search ends, :mod:`~rattlefit.inference.across`), screened,
   then Levenberg–Marquardt from the best
   (:func:`~rattlefit.inference.least_squares.refine_starts`);
3. the noise model and Laplace covariance at the optimum
   (:func:`~rattlefit.inference.laplace.laplace_at`);
4. the free parameters' profile intervals
   (:func:`~rattlefit.inference.profile.profile_stage`), and each boundary film's
   squeeze-film group's (:mod:`~rattlefit.inference.group`);
5. the result (:mod:`~rattlefit.inference.result`).

The method's rationale is in ``docs/identification.md``.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence

import numpy as np

from ..confidence import Z95_ONE_SIDED
from ..io.recording import Recording
from ..likelihood.synthetic import SyntheticLikelihood
from ..problem.options import FitOptions
from ..problem.problem import Problem, problem_from, release_states
from ..reproducibility import platform_info
from ..util import stamped
from .across import lubrication_starts
from .group import group_estimates
from .laplace import Laplace, laplace_at
from .learned import identify_learned
from .least_squares import Refined, refine_starts
from .outcome import search_end
from .profile import (
    ProfileStage,
    film_valley,
    profile_interval,
    profile_stage,
    span_profile_points,
)
from .result import (
    Estimates,
    FitResult,
    FittedState,
    Statistics,
    estimates_of,
    map_params_of,
    profiles_in_si,
    provenance_of,
    spectra_of,
    with_groups,
)
from .starts import starting_points


@dataclasses.dataclass(frozen=True)
class Uncertainty:
    """The covariance and profile stages' result at the final optimum ``z``, after
    ``recentred`` re-centrings on the profiles' minimum."""

    laplace: Laplace
    profiles: ProfileStage
    z: np.ndarray
    recentred: int


def degrees_of_freedom(problem: Problem) -> int:
    """Data rows minus free parameters (those without a prior), at least 1."""
    n_free = sum(1 for s in problem.specs if s.log_sd is None)
    return max(int(np.asarray(problem.data).size) - n_free, 1)


def uncertainty(refined: Refined, y0, options: FitOptions, rng, say) -> Uncertainty:
    """The Laplace and profile stages at the search's optimum; with
    ``recentre_rounds`` they start again from a profile point clearly below it."""
    problem, z = refined.problem, refined.optimum
    valley = film_valley(problem) if options.profile_valley else None
    dof = degrees_of_freedom(problem)
    dof_rec = dof / problem.n_rec  # each recording's share
    rounds = options.recentre_rounds
    recentred = 0
    for recentre in range(rounds + 1):
        say("re-estimating the spread at the optimum and the Laplace covariance …")
        lap = laplace_at(problem, z, y0, options, dof_rec)
        problem = lap.problem
        say(f"χ² = {lap.chi2:.1f} on {dof} dof (band correlations included)")
        stage = profile_stage(
            lap,
            z,
            refined.contenders,
            y0,
            options,
            valley=valley,
            dof_rec=dof_rec,
            rng=rng,
            say=say,
        )
        if stage.lower is None:
            break
        dc_min, z_min = stage.lower
        if recentre == rounds:
            say(f"  the profiles reach {dc_min:.1f} below the optimum's cost (not re-centred)")
            break
        say(
            f"the profiles reach {dc_min:.1f} below the optimum's cost (Monte Carlo allowance "
            f"{Z95_ONE_SIDED * stage.noise_sd:.1f}): the Laplace and profile stages start again "
            "from there"
        )
        z = np.asarray(z_min, dtype=float)
        recentred += 1
    return Uncertainty(lap, stage, z, recentred)


def interval_ends(unc: Uncertainty, options: FitOptions) -> tuple[np.ndarray, np.ndarray]:
    """Each parameter's 95 % interval in z: the free parameters' from their profiles, the
    others' from the Laplace covariance (widened to span rivals and, with continuation,
    every profile point inside the threshold)."""
    stage = unc.profiles
    z_lo, z_hi = np.array(stage.z_lo), np.array(stage.z_hi)
    for i, prof in stage.profiles.items():
        z_lo[i], z_hi[i] = profile_interval(prof, stage.threshold)[0]
    if options.profile_continuation:
        span_profile_points(stage.profiles, stage.threshold, z_lo, z_hi, unc.laplace.problem.specs)
    return z_lo, z_hi


def assemble_result(
    unc: Uncertainty,
    refined: Refined,
    rigs,
    options: FitOptions,
    *,
    wall: float,
    platform,
    groups: dict | None = None,
) -> FitResult:
    """The :class:`FitResult` of the stages' outputs; ``groups`` are the squeeze-film groups'
    estimates (:func:`~rattlefit.inference.group.group_estimates`), listed after the
    viscosity."""
    lap, z = unc.laplace, unc.z
    problem = lap.problem
    cov = lap.covariance
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    corr = cov / np.outer(np.maximum(sd, 1e-300), np.maximum(sd, 1e-300))
    z_lo, z_hi = interval_ends(unc, options)
    estimates = Estimates(
        parameters=with_groups(
            estimates_of(problem, z, z_lo, z_hi, [r.recording.operating.lubrication for r in rigs]),
            groups or {},
        ),
        names=[s.name for s in problem.specs],
        correlation=corr,
        map_params=map_params_of(problem, z),
        profile=unc.profiles.info,
        profiles=profiles_in_si(problem, unc.profiles.profiles),
    )
    statistics = Statistics(
        chi2=lap.chi2,
        dof=degrees_of_freedom(problem),
        chi2_recordings=[float(c) for c in lap.noise.chi2_recordings],
        regime_share=[float(x) for x in lap.noise.regime_share],
        n_iterations=refined.n_iter,
        search=search_end(refined.converged, refined.stalled, unc.recentred),
    )
    spectra = spectra_of(problem, lap.mean, problem.sigma)
    provenance = provenance_of(rigs, options, wall, platform)
    likelihood = SyntheticLikelihood.of_fit(lap.noise, problem, options)
    state = FittedState(options, z, cov, likelihood=likelihood, problem=problem)
    return FitResult(estimates, statistics, spectra, provenance, state)


def identify_synthetic(
    recordings: Sequence[Recording],
    options: FitOptions,
    *,
    progress: Callable[[str], None] | None = None,
) -> FitResult:
    """:func:`identify` on the synthetic likelihood (the module docstring's stages)."""
    t_start = time.perf_counter()
    say = stamped(progress, t_start)  # progress, stamped with the time since the start
    platform = platform_info()
    problem, rigs, rng = problem_from(recordings, options)
    say(
        f"{len(rigs)} recording(s), {len(problem.specs)} parameters, "
        f"{options.n_realisations} realisations per evaluation (seed {options.seed})"
    )
    starts = starting_points(
        problem, options.n_starts, rng, nuisance_starts=options.nuisance_starts
    )
    # a fit across lubrications also starts where each lubrication's own search ends
    starts = np.concatenate([lubrication_starts(recordings, problem, options, say), starts])
    refined = refine_starts(problem, starts, options, rng, say)
    # the covariance uses more realisations than the search, released from fresh states
    y0 = release_states(refined.problem, refined.optimum, options.n_covariance_realisations, rng)
    unc = uncertainty(refined, y0, options, rng, say)
    groups = {}
    if options.profile_group:
        groups = group_estimates(
            unc.laplace,
            unc.z,
            y0,
            [r.recording.operating.lubrication for r in rigs],
            options,
            dof_rec=degrees_of_freedom(unc.laplace.problem) / unc.laplace.problem.n_rec,
            rng=rng,
            say=say,
        )
    wall = time.perf_counter() - t_start
    say(f"done in {wall:.1f} s")
    return assemble_result(unc, refined, rigs, options, wall=wall, platform=platform, groups=groups)


#: The fit of each ``FitOptions.likelihood``.
FITS = {"synthetic": identify_synthetic, "learned": identify_learned}


def identify(
    recordings: Sequence[Recording],
    options: FitOptions | None = None,
    *,
    progress: Callable[[str], None] | None = None,
) -> FitResult:
    """Identify ``a``, ``drag_torque`` and the viscosity from one or more recordings.

    Several recordings of one gear pair are fitted jointly: they share ``a``,
    ``drag_torque``, the viscosity factor, the stiffness scale and ``h_min`` (e.g. a backlash
    sweep as in the paper's Figs. 10–12); each has its own backlash. Recordings under
    different lubrications each get their lubrication's film half-length (``a[boundary]``,
    ``a[oil_jet]``, …) and share the rest: under oil jet the squeeze force saturates in ``a``
    and pins the oil's viscosity, which a boundary recording alone cannot separate from ``a``
    and ``h_min``.

    ``options`` defaults to ``FitOptions()``; ``options.likelihood`` chooses the fit of
    :data:`FITS`: on the synthetic likelihood (:func:`identify_synthetic`), or on a likelihood
    learned from simulations (:func:`~rattlefit.inference.learned.identify_learned`); the
    result's state holds that :class:`~rattlefit.likelihood.protocol.Likelihood`.
    ``progress`` receives one-line
    messages while the fit works. Raises :class:`~rattlefit.errors.RattlefitError` when the
    recordings cannot be fitted jointly or an option names a parameter the fit does not have.
    """
    options = options or FitOptions()
    return FITS[options.likelihood](recordings, options, progress=progress)
