"""Where the model misses a recording, which unmodelled effect explains it, and by how much.

:func:`diagnose` starts from an identification
(:func:`~rattlefit.inference.identify.identify`) and

1. **locates the gap**: each band's standardised residual ``(measured − fitted)/σ`` at the
   optimum, and the bands where it exceeds :data:`~rattlefit.diagnosis.result.MISSED_Z`;
2. **re-fits the model without effects** over ``a`` and ``drag_torque`` from the
   alternatives every effect's screening starts from
   (:data:`~rattlefit.diagnosis.screening.FREE_FACTORS`), so that an effect is not credited
   with what that re-fit alone gains; when the re-fit lowers the identification's cost by
   more than half, or the identification stopped at its step limit, the diagnosis warns
   (:func:`~rattlefit.diagnosis.result.baseline_warnings`);
3. **tries each effect** of :mod:`rattlefit.physics.effects` on its own: added to the model
   at its absent end, its fields screened over their ranges
   (:func:`~rattlefit.diagnosis.screening.screen_points`), then fitted together with ``a``
   and ``drag_torque`` (damped Gauss–Newton on finite differences; the nuisances stay put);
4. **measures how far the gap shrinks**, out of sample: the χ² of the data rows (band
   correlations included, the identification's noise model fixed) without the effect and
   with it, both from the same :attr:`DiagnoseOptions.n_final` fresh realisations (common
   random numbers) that no fit saw, so that points which fit the fit's own few
   realisations by luck do not count. ``gap_closed`` is the share of the excess misfit
   (χ² − dof) that the effect removes.

An effect is *supported* when an F-test of its χ² drop against the misfit that remains gives
p < ``significance`` / (effects tried) (Bonferroni: ``significance`` is the family-wise
level) and the drop exceeds the Monte Carlo noise of a difference of two χ²s. The verdict is
the supported effect that leaves the least misfit: each effect's χ² without it is simulated
by another compiled program (the effect's terms at their absent values), which chaos turns
into another realisation, so the drops are the evidence for each effect and the misfit left
ranks them.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable, Sequence

import numpy as np
from scipy import stats

from ..errors import RattlefitError
from ..inference.forward import evaluate
from ..inference.identify import identify
from ..inference.noise import NoiseModel
from ..inference.options import FitOptions
from ..inference.parameters import Z_END
from ..inference.problem import Problem, release_states
from ..inference.profile import polish_profile
from ..inference.result import FitResult
from ..io.recording import Recording
from ..physics.effects import EFFECTS, absent, effect_class
from ..reproducibility import platform_info
from ..util import stamped
from .result import Diagnosis, EffectOutcome, baseline_warnings, gap_closed
from .screening import FREE_FACTORS, effect_specs, free_alternatives, screen_points

#: One-sided 95 % quantile of the standard normal (the χ² drop's Monte Carlo allowance).
Z95_ONE_SIDED = 1.645


@dataclasses.dataclass(frozen=True)
class DiagnoseOptions:
    """Options of :func:`diagnose`.

    effects : names of the effects to try (:data:`rattlefit.physics.effects.EFFECTS`).
    fit : options of the identification that the diagnosis starts from (its seed seeds the
        diagnosis too); by default :meth:`FitOptions.optimum_only`, since the diagnosis uses
        the optimum and its noise model, not the intervals.
    iterations : Gauss–Newton iterations per effect.
    n_final : realisations behind each final χ² (default: the fit's covariance count).
    significance : family-wise level: an effect counts as supported when its F-test p is
        below ``significance / len(effects)`` (Bonferroni).
    """

    effects: tuple[str, ...] = tuple(EFFECTS)
    fit: FitOptions = dataclasses.field(default_factory=FitOptions.optimum_only)
    iterations: int = 3
    n_final: int | None = None
    significance: float = 0.01

    def __post_init__(self):
        for name in self.effects:
            effect_class(name)  # raises with the list of known effects
        if self.iterations < 0:
            raise RattlefitError("DiagnoseOptions.iterations must be ≥ 0")


@dataclasses.dataclass(frozen=True)
class Trial:
    """What every effect's trial shares: the identification's problem (its realisations and
    band spread), noise model and measured features, the fresh release states ``y0`` of the
    final comparison, the identification's degrees of freedom, the Gauss–Newton iterations
    and the coordinates held fixed (the nuisances)."""

    problem: Problem
    noise: NoiseModel
    data: np.ndarray
    y0: np.ndarray
    dof: int
    iterations: int
    nuisances: list[int]


def whitened_rows(trial: Trial, mean: np.ndarray) -> np.ndarray:
    """The identification's whitened data rows for mean features ``mean`` (R, B)."""
    sigma = np.asarray(trial.problem.sigma)
    return trial.noise.whiten @ ((trial.data - mean) / sigma).reshape(-1)


def residual_rows(trial: Trial, problem: Problem, zs) -> np.ndarray:
    """Whitened data rows and prior rows of ``problem`` at each point of ``zs``: (K, n)."""
    mean = np.asarray(problem.mean_of(evaluate(problem, zs)))
    return np.stack(
        [
            np.concatenate([whitened_rows(trial, mean[k]), problem.prior_rows(np.asarray(z))])
            for k, z in enumerate(zs)
        ]
    )


def refit(trial: Trial, problem: Problem, z) -> np.ndarray:
    """``z`` after ``trial.iterations`` of damped Gauss–Newton on the coordinates not in
    ``trial.nuisances``."""
    if not trial.iterations:
        return z
    steps = np.minimum(problem.fd_steps(np.asarray(z)), 1.0)[None]
    rows = functools.partial(residual_rows, trial, problem)
    return polish_profile(rows, z[None], [trial.nuisances], steps, iterations=trial.iterations)[0]


def refit_without_effects(trial: Trial, z, say) -> tuple[np.ndarray, float, float]:
    """The model without effects re-fitted over ``a`` and ``drag_torque`` from the
    screening's alternatives of them at the identification's optimum ``z``: the re-fitted
    point, the identification's cost and the re-fit's."""
    say(
        f"re-fitting a and T_b without effects ({len(FREE_FACTORS)} starts, "
        f"{trial.iterations} iterations) …"
    )
    starts = free_alternatives(np.asarray(z, dtype=float), trial.problem)
    cost = np.sum(residual_rows(trial, trial.problem, starts) ** 2, axis=1)  # row 0: z
    z_base = refit(trial, trial.problem, starts[int(np.argmin(cost))])
    refit_cost = float(np.sum(residual_rows(trial, trial.problem, z_base[None]) ** 2))
    return z_base, float(cost[0]), refit_cost


def fit_effect(trial: Trial, name: str, z_base, say) -> tuple[Problem, np.ndarray, np.ndarray]:
    """Effect ``name`` added at its absent end, screened and fitted with ``a`` and
    ``drag_torque``: its problem, the point without it and the fitted point."""
    specs = effect_specs(name)
    problem = dataclasses.replace(
        trial.problem, specs=trial.problem.specs + specs, effect=absent(name)
    )
    z_off = np.concatenate([z_base, np.full(len(specs), -Z_END)])
    starts = np.concatenate([z_off[None], screen_points(z_off, specs, trial.problem)])
    cost = np.sum(residual_rows(trial, problem, starts) ** 2, axis=1)
    best = starts[1 + int(np.argmin(cost[1:]))]
    say(
        f"  {name}: cost {cost[0]:.1f} without, {cost.min():.1f} at the best start; "
        f"fitting it with a and T_b ({trial.iterations} iterations) …"
    )
    return problem, z_off, refit(trial, problem, best)


def judge_effect(
    trial: Trial, name: str, problem: Problem, z_off, z_fit, level: float
) -> EffectOutcome:
    """The effect's outcome: χ² without and with it on the fresh realisations, the F-test
    at ``level`` and the Monte Carlo noise of the drop."""
    specs = problem.specs[len(trial.problem.specs) :]
    d, p0 = len(specs), len(trial.problem.specs)
    pair = np.stack([z_off, z_fit])
    mean = np.asarray(problem.mean_of(evaluate(problem, pair, trial.y0)))
    chi2 = [float(np.sum(whitened_rows(trial, mean[k]) ** 2)) for k in range(2)]
    delta = chi2[0] - chi2[1]
    # Monte Carlo noise of each χ² from n realisations (cf. the profile threshold)
    n, dof = trial.y0.shape[1], trial.dof
    var = 4.0 * max(chi2[0], dof) / (n + 1) + 4.0 * max(chi2[1], dof) / (n + 1)
    threshold = Z95_ONE_SIDED * math.sqrt(var)
    dof_with = max(dof - d, 1)
    f_stat = (delta / d) / max(chi2[1] / dof_with, 1e-12)
    p_value = float(stats.f.sf(f_stat, d, dof_with)) if delta > 0 else 1.0
    values = {s.name.split(".", 1)[1]: float(s.value(pair[1][p0 + j])) for j, s in enumerate(specs)}
    return EffectOutcome(
        name=name,
        values=values,
        units={k: u for k, (u, _, _) in effect_class(name).ranges.items()},
        chi2_without=chi2[0],
        chi2_with=chi2[1],
        delta_chi2=delta,
        gap_closed=gap_closed(chi2[0], chi2[1], dof),
        p_value=p_value,
        noise_threshold=threshold,
        supported=bool(p_value < level and delta > threshold),
        residuals=(trial.data - mean[1]) / np.asarray(trial.problem.sigma),
        wall_time=0.0,
    )


def try_effect(trial: Trial, name: str, z_base, level: float, say) -> EffectOutcome:
    """Fit effect ``name`` (:func:`fit_effect`) and judge it (:func:`judge_effect`)."""
    t0 = time.perf_counter()
    problem, z_off, z_fit = fit_effect(trial, name, z_base, say)
    outcome = judge_effect(trial, name, problem, z_off, z_fit, level)
    outcome = dataclasses.replace(outcome, wall_time=time.perf_counter() - t0)
    say(
        f"  {name}: χ² {outcome.chi2_without:.1f} → {outcome.chi2_with:.1f} "
        f"(p = {outcome.p_value:.2g}{', supported' if outcome.supported else ''}) in "
        f"{outcome.wall_time:.0f} s"
    )
    return outcome


def trial_of(
    recordings: Sequence[Recording], baseline: FitResult, options: DiagnoseOptions
) -> Trial:
    """The :class:`Trial` of ``baseline``: its problem, noise model and fresh release states
    (seeded from the fit's seed + 1) for the final comparison."""
    problem = baseline.problem_for(recordings)
    fit_options = baseline.options
    n_final = options.n_final or fit_options.n_covariance_realisations
    y0 = release_states(problem, baseline.z, n_final, np.random.default_rng(fit_options.seed + 1))
    nuisances = [i for i, sp in enumerate(problem.specs) if sp.log_sd is not None]
    return Trial(
        problem,
        baseline.noise,
        np.asarray(problem.data),
        y0,
        baseline.dof,
        options.iterations,
        nuisances,
    )


def diagnose(
    recordings: Sequence[Recording],
    options: DiagnoseOptions | None = None,
    *,
    baseline: FitResult | None = None,
    progress: Callable[[str], None] | None = None,
) -> Diagnosis:
    """Diagnose what the model misses in ``recordings`` (fitted jointly, as by identify).

    ``baseline`` is an identification of the same recordings (run first with
    ``options.fit`` when not given; when given, its own options and seed are used, so that
    the diagnosis sees the realisations it was fitted with). ``progress`` receives one-line
    messages. Every realisation is seeded from the fit's seed. Raises
    :class:`~rattlefit.errors.RattlefitError` when ``baseline`` is of other recordings.
    """
    options = options or DiagnoseOptions()
    t_start = time.perf_counter()
    say = stamped(progress, t_start)  # progress, stamped with the time since the start
    platform = platform_info()
    if baseline is None:
        say("identifying the model without extra effects …")
        baseline = identify(recordings, options.fit, progress=progress)
    elif baseline.recordings != [str(r.path) for r in recordings]:
        raise RattlefitError(
            f"diagnose: the baseline fit is of {baseline.recordings}, not of "
            f"{[str(r.path) for r in recordings]}"
        )
    trial = trial_of(recordings, baseline, options)
    z_base, cost_identified, refit_cost = refit_without_effects(trial, baseline.z, say)
    warnings = baseline_warnings(baseline.success, cost_identified, refit_cost)
    for w in warnings:
        say("  warning: " + w)
    level = options.significance / len(options.effects)  # Bonferroni over the effects tried
    outcomes = []
    for n, name in enumerate(options.effects):
        say(f"effect {n + 1}/{len(options.effects)}: {name} — screening (compiling first) …")
        outcomes.append(try_effect(trial, name, z_base, level, say))
    outcomes.sort(key=lambda o: o.chi2_with)  # the least misfit left first (module docstring)
    bands = trial.problem.bands
    wall = time.perf_counter() - t_start
    say(f"done in {wall:.0f} s")
    return Diagnosis(
        baseline=baseline,
        residuals=(trial.data - np.stack(baseline.fitted_features)) / np.stack(baseline.sigma),
        band_centers=bands.centers,
        band_edges=bands.edges,
        outcomes=outcomes,
        seed=baseline.options.seed,
        wall_time=wall,
        refit_costs=(cost_identified, refit_cost),
        warnings=tuple(warnings),
        platform=platform,
    )
