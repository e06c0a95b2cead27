"""Identification on the learned likelihood (``FitOptions(likelihood="learned")``).

The stages: the problem (:func:`~rattlefit.problem.problem.problem_from`, for its
recordings, parameters and simulator); the likelihood learned in rounds
(:func:`~rattlefit.likelihood.learn_likelihood`); the optimum, every parameter's profile and
the Laplace covariance on it (:func:`~rattlefit.inference.smooth.fit_learned`); the
learned likelihood checked against fresh simulations at the optimum and at the drag torque's
and each film's interval ends (:mod:`rattlefit.likelihood.check`); the
:class:`~rattlefit.inference.result.FitResult`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence

import jax.numpy as jnp
import numpy as np

from ..errors import RattlefitError
from ..io.recording import Recording
from ..likelihood import LearningOptions, learn_likelihood
from ..likelihood.check import FAR_RECORDING, check_points
from ..likelihood.learn import best_points
from ..likelihood.store import Learned, learned_noise, read_learned, test_point_key
from ..problem.options import FitOptions
from ..problem.problem import Problem, problem_from
from ..quantities import MIN_FILM, VISCOSITY_SCALE
from ..reproducibility import platform_info
from ..util import stamped
from .critical import CriticalValues, critical_values
from .group import flanks, group_films, group_spec
from .outcome import search_end
from .result import (
    Estimates,
    FitResult,
    FittedState,
    ParameterEstimate,
    Statistics,
    estimate,
    estimates_of,
    map_params_of,
    provenance_of,
    spectra_of,
    with_groups,
)
from .smooth import CHI2_95, LearnedFit, LogMomentum, fit_learned, profile_derived

#: Starts of the quasi-Newton search: the design points of least learned cost.
LEARNED_STARTS = 8


def learning_options(options: FitOptions) -> LearningOptions:
    """The learned likelihood's learning budget of ``options``."""
    return LearningOptions(
        initial=options.learning_initial,
        rounds=options.learning_rounds,
        per_round=options.learning_per_round,
    )


def checked_points(problem: Problem, fit: LearnedFit) -> dict[str, np.ndarray]:
    """The points whose simulations check the learned likelihood: the optimum, and the
    profile's optimum at each end of the drag torque's and each film's interval."""
    points = {"optimum": fit.optimum.z}
    for i, prof in fit.profiles.items():
        name = problem.specs[i].name
        if name not in problem.space.of_role("physical"):
            continue
        for end, zi in (("lower", prof.lower), ("upper", prof.upper)):
            k = int(np.argmin(np.abs(prof.z - zi)))
            points[f"{name} {end}"] = prof.points[k]
    return points


def profiles_of(problem: Problem, fit: LearnedFit) -> dict[str, list[tuple[float, float]]]:
    """Each parameter's profile as ``[(value in SI, Δcost), …]`` in increasing value."""
    return {
        problem.specs[i].name: [
            (float(problem.specs[i].value(z)), float(d)) for z, d in zip(p.z, p.delta, strict=True)
        ]
        for i, p in fit.profiles.items()
    }


def momentum_quantities(problem: Problem, lubrications) -> dict[str, LogMomentum]:
    """Each boundary film's squeeze momentum's log as a function of ``z``
    (:class:`~rattlefit.inference.smooth.LogMomentum`), by the film's name."""
    out = {}
    for film in group_films(problem, lubrications):
        mu, radius, width = flanks(problem, film)
        out[film] = LogMomentum(
            problem.index(film),
            problem.index(VISCOSITY_SCALE),
            problem.index(MIN_FILM),
            mu,
            radius,
            width,
            problem.specs,
        )
    return out


def momentum_estimates(
    problem: Problem, learned: Learned, fit: LearnedFit, quantities, thresholds, say
) -> tuple[dict[str, ParameterEstimate], dict[str, list[tuple[float, float]]]]:
    """Each boundary film's squeeze momentum (N s; what a boundary recording pins), profiled
    on the learned likelihood, its interval cut at ``thresholds[film]`` (χ²₁'s 3.84 where
    missing): its estimates and its profiles as ``(M, Δcost)`` pairs. ``quantities``:
    :func:`momentum_quantities`."""
    found, profiles = {}, {}
    for film, g in quantities.items():
        say(f"profiling the squeeze momentum of {film} …")
        cut = thresholds.get(film, CHI2_95)
        prof = profile_derived(learned.likelihood, g, fit.optimum, threshold=cut)
        spec = group_spec(problem, film)
        m = float(np.exp(g(jnp.asarray(fit.optimum.z))))
        ends = [spec.z_of(float(np.exp(v))) for v in (prof.lower, prof.upper)]
        found[spec.name] = estimate(spec, spec.z_of(m), *ends)
        profiles[spec.name] = [
            (float(np.exp(v)), float(d)) for v, d in zip(prof.z, prof.delta, strict=True)
        ]
    return found, profiles


def calibrated(problem: Problem, learned: Learned, fit: LearnedFit, quantities, options, seed, say):
    """``fit`` with each profile cut at its critical value by simulation
    (:mod:`~rattlefit.inference.critical`), and the critical values (None, and ``fit`` as it
    is, when ``options.calibration_simulations`` is 0)."""
    n = options.calibration_simulations
    if not n:
        return fit, None
    say(f"critical values of the profiles from {n} recordings simulated near the optimum …")
    like = learned.likelihood
    critical = critical_values(problem, like, fit, n=n, seed=seed, derived=quantities)
    names = critical_names(problem, critical)
    say(
        "  critical values (χ²₁: 3.84): "
        + ", ".join(f"{names[k]} {v:.2f}" for k, v in critical.values.items())
    )
    cut = {i: critical.values[i] for i in fit.profiles}
    return fit_learned(like, fit.optimum.z[None], list(fit.profiles), threshold=cut), critical


def critical_names(problem: Problem, critical: CriticalValues) -> dict:
    """The name in the fit's table of each quantity of ``critical`` (a parameter's index, or a
    film whose squeeze momentum it is)."""
    return {
        k: problem.specs[k].name if isinstance(k, int) else group_spec(problem, k).name
        for k in critical.values
    }


def learned_result(
    problem: Problem,
    learned: Learned,
    fit: LearnedFit,
    rigs,
    options: FitOptions,
    *,
    info: dict,
    wall: float,
    platform: dict,
    groups: tuple[dict, dict] = ({}, {}),
    critical: CriticalValues | None = None,
) -> FitResult:
    """The :class:`FitResult` of a fit on the learned likelihood, its intervals cut at the
    ``critical`` values (χ²₁'s 3.84 when None)."""
    like = learned.likelihood
    z = fit.optimum.z
    cov = fit.covariance_z
    sd = np.sqrt(np.clip(np.diag(cov), 1e-300, None))
    z_lo = np.array([fit.profiles[i].lower for i in range(len(z))])
    z_hi = np.array([fit.profiles[i].upper for i in range(len(z))])
    mean, total = (np.asarray(x) for x in like.moments(jnp.asarray(z)))
    chi2_rec, _ = like.chi2_terms(jnp.asarray(z))
    lubrications = [r.recording.operating.lubrication for r in rigs]
    converged = fit.optimum.converged
    estimates = Estimates(
        parameters=with_groups(estimates_of(problem, z, z_lo, z_hi, lubrications), groups[0]),
        names=[s.name for s in problem.specs],
        correlation=cov / np.outer(sd, sd),
        map_params=map_params_of(problem, z),
        profile=profile_record(problem, critical),
        profiles={**profiles_of(problem, fit), **groups[1]},
    )
    statistics = Statistics(
        chi2=fit.chi2,
        dof=fit.dof,
        chi2_recordings=[float(c) for c in np.asarray(chi2_rec)],
        n_iterations=fit.optimum.steps,
        search=search_end(converged, (False,)),
    )
    spectra = spectra_of(problem, mean, [np.sqrt(np.diag(c)) for c in total])
    provenance = provenance_of(rigs, options, wall, platform, likelihood=info)
    sims = int(learned.design.u.shape[0])
    noise = learned_noise(total, options.n_realisations, np.asarray(chi2_rec), sims)
    learned = dataclasses.replace(learned, noise=noise)
    problem = dataclasses.replace(problem, sigma=jnp.asarray(learned.noise.sigma))
    state = FittedState(options, z, cov, likelihood=learned, problem=problem)
    return FitResult(estimates, statistics, spectra, provenance, state)


def profile_record(problem: Problem, critical: CriticalValues | None) -> dict:
    """The fit JSON's ``fit.profile``: χ²₁'s threshold and, when calibrated, each quantity's
    critical value (``thresholds``, by name) and how it was set (``calibration``)."""
    record = {"threshold": CHI2_95, "likelihood": "learned"}
    if critical is not None:
        names = critical_names(problem, critical)
        record["thresholds"] = {names[k]: float(v) for k, v in critical.values.items()}
        record["calibration"] = critical.as_dict(names)
    return record


def band_floor(problem: Problem, options: FitOptions) -> np.ndarray:
    """The learned likelihood's variance floor (F,): ``FitOptions.sigma_floor`` squared on
    each band, as the synthetic likelihood floors a band's spread (where rattle locks into a
    periodic orbit the simulator's own spread vanishes, and a recording from another rig or
    simulator differs from the model by more); nothing on the drive-cycle statistics."""
    floor = np.zeros(problem.data.shape[-1])
    floor[: problem.n_bands] = options.sigma_floor**2
    return floor


def learn_or_reuse(problem: Problem, options: FitOptions, seed, say) -> tuple[Learned, dict]:
    """The learned likelihood of ``problem``: read from ``options.reuse_likelihood`` when
    given, else learned in rounds; and what it cost (simulations, rounds)."""
    reuse = options.reuse_likelihood
    learning = learning_options(options)
    floor = band_floor(problem, options)
    if reuse is not None:
        stored = read_learned(reuse, problem)
        if not all(np.allclose(d.floor, floor) for d in stored.likelihood.densities):
            raise RattlefitError(
                f"{reuse}: /learned_likelihood: learned with another variance floor than "
                "this fit's (sigma_floor); learn anew"
            )
        say(f"reusing the learned likelihood of this test point in {reuse}")
        return stored, {"reused": str(reuse), "rounds": []}
    say(f"learning the likelihood from {learning.budget} simulations per recording")
    like, design, rounds = learn_likelihood(problem, learning, seed=seed, floor=floor, progress=say)
    learned = Learned(like, design, test_point_key(problem), options.seed, learning.density)
    return learned, {"rounds": [round_info(r) for r in rounds]}


def round_info(r) -> dict:
    """One learning round's record as JSON."""
    return {
        "simulations": r.simulations,
        "simulate_s": r.simulate_seconds,
        "train_s": r.train_seconds,
        "simulations_per_s_per_core": r.per_second_per_core,
    }


def fit_and_check(problem: Problem, learned: Learned, options: FitOptions, seed, say):
    """The fit on ``learned`` and its check against fresh simulations."""
    like = learned.likelihood
    say("optimum and profiles on the learned likelihood …")
    starts = best_points(like, learned.design.u, LEARNED_STARTS)
    fit = fit_learned(like, starts, range(len(problem.specs)))
    say(f"χ² = {fit.chi2:.1f} on {fit.dof} dof (p = {fit.p_value:.2g})")
    n = options.check_realisations
    say(f"checking the learned likelihood against {n} fresh simulations per point …")
    checks = check_points(problem, like, checked_points(problem, fit), n, seed)
    failed = [c.label for c in checks if not c.passed]
    if failed:
        say(f"  the learned likelihood misses the simulator at: {', '.join(failed)}")
    for c in checks:
        if c.label == "optimum" and c.recording_distance > FAR_RECORDING:
            say(
                f"  recording {c.recording} lies {c.recording_distance:.1f} sd from the "
                "simulations at the optimum: the optimum is not where the simulator puts it"
            )
    return fit, checks


def refine(problem: Problem, learned: Learned, options: FitOptions, seeds, say):
    """``learned`` with one more posterior round of simulations on top of its design, and
    that round's record."""
    more = dataclasses.replace(learning_options(options), rounds=1)
    like, design, rounds = learn_likelihood(
        problem,
        more,
        seed=next(seeds),
        start=(learned.likelihood, learned.design),
        floor=band_floor(problem, options),
        progress=say,
    )
    return dataclasses.replace(learned, likelihood=like, design=design), [
        round_info(r) for r in rounds
    ]


def identify_learned(
    recordings: Sequence[Recording],
    options: FitOptions,
    *,
    progress: Callable[[str], None] | None = None,
) -> FitResult:
    """:func:`~rattlefit.inference.identify.identify` on the learned likelihood (module
    docstring). Every random draw descends from ``options.seed``. Where the check fails at the
    optimum or an interval end, the likelihood (learned here or reused) gets one more round of
    simulations drawn from its posterior and the fit is repeated, up to
    ``options.learning_refinements`` times."""
    t_start = time.perf_counter()
    say = stamped(progress, t_start)
    platform = platform_info()
    problem, rigs, _ = problem_from(recordings, options)
    say(f"{len(rigs)} recording(s), {len(problem.specs)} parameters (seed {options.seed})")
    s_learn, s_check, s_more, s_critical = np.random.SeedSequence(options.seed).spawn(4)
    s_more = iter(s_more.spawn(options.learning_refinements))
    learned, info = learn_or_reuse(problem, options, s_learn, say)
    fit, checks = fit_and_check(problem, learned, options, s_check, say)
    lubrications = [r.recording.operating.lubrication for r in rigs]
    for _ in range(options.learning_refinements):
        if all(c.passed for c in checks):
            break
        say("one more round of simulations where the learned likelihood misses …")
        learned, rounds = refine(problem, learned, options, s_more, say)
        info["rounds"] += rounds
        fit, checks = fit_and_check(problem, learned, options, s_check, say)
    info = {
        "method": "learned",
        **info,
        "simulations_per_recording": int(learned.design.u.shape[0]),
        "key": learned.key,
        "profile_restarts": fit.restarts,
        "check": [c.as_dict() for c in checks],
        "check_passed": all(c.passed for c in checks),
    }
    quantities = momentum_quantities(problem, lubrications) if options.profile_group else {}
    fit, critical = calibrated(problem, learned, fit, quantities, options, s_critical, say)
    thresholds = {} if critical is None else critical.values
    groups = momentum_estimates(problem, learned, fit, quantities, thresholds, say)
    wall = time.perf_counter() - t_start
    say(f"done in {wall:.1f} s")
    return learned_result(
        problem,
        learned,
        fit,
        rigs,
        options,
        info=info,
        wall=wall,
        platform=platform,
        groups=groups,
        critical=critical,
    )
