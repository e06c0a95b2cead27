"""Where the model misses a recording, which unmodelled effect explains it, and by how much.

:func:`diagnose` first reads the recordings alone
(:mod:`rattlefit.diagnosis.evidence`): the flank positions against each wheel's angle and
tooth (run-out, a transmission error, a tooth defect) and a drift over the recording. Then it
starts from an identification (:func:`~rattlefit.inference.identify.identify`) and

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

The verdict (:class:`~rattlefit.diagnosis.result.Verdict`) is ``"none"`` when the model
without extra effects fits the band spectrum (its χ² after the re-fit, on the fresh
realisations, has p ≥ ``significance``) and no model-free
test stands out; the effects that significant model-free tests point to are named; a band
candidate is named when it is supported and leaves a misfit consistent with noise; a
significant gap that nothing explains is ``"unexplained"``.

An effect is *supported* when an F-test of its χ² drop against the misfit that remains gives
p < ``significance`` / (effects tried) (Bonferroni: ``significance`` is the family-wise
level) and the drop exceeds the Monte Carlo noise of a difference of two χ²s. One compiled
program holds every candidate, each at its absent end unless fitted, so the χ² without
effects is one number on one set of realisations, and every effect's drop and share of the
gap compare like with like.
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
from .evidence import ENCODER_VISIBLE, findings
from .result import Diagnosis, EffectOutcome, baseline_warnings, finding_phrase, gap_closed
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
        below ``significance`` over the number of effects fitted (Bonferroni); the
        model-free tests share it likewise, and the band gap is tested at it.
    every_effect : fit every effect to the band spectrum, also those the encoders show no
        sign of and when the model without effects fits within its noise (by default they
        are skipped: they could not be named).
    """

    effects: tuple[str, ...] = tuple(EFFECTS)
    fit: FitOptions = dataclasses.field(default_factory=FitOptions.optimum_only)
    iterations: int = 3
    n_final: int | None = None
    significance: float = 0.01
    every_effect: bool = False

    def __post_init__(self):
        for name in self.effects:
            effect_class(name)  # raises with the list of known effects
        if self.iterations < 0:
            raise RattlefitError("DiagnoseOptions.iterations must be ≥ 0")


@dataclasses.dataclass(frozen=True)
class Trial:
    """What every effect's trial shares.

    problem : the identification's problem (its realisations and band spread) with every
        candidate effect added at its absent end: one compiled program, so that the model
        without effects and each effect's fit are the same realisations.
    noise, data, dof : the identification's noise model, measured features (R, B) and
        degrees of freedom.
    y0 : fresh release states of the final comparison.
    iterations : Gauss–Newton iterations per fit.
    nuisances : coordinates never re-fitted: the parameters with a prior, and the film
        half-length of dry recordings, held at its dry end (dry flanks have no oil film, and
        a film fitted to them would absorb dissipation that is in the contact).
    candidates : each effect's coordinates in ``problem``.
    dry : the film coordinates of dry recordings (part of ``nuisances``).
    """

    problem: Problem
    noise: NoiseModel
    data: np.ndarray
    y0: np.ndarray
    dof: int
    iterations: int
    nuisances: list[int]
    candidates: dict[str, list[int]]
    dry: list[int] = dataclasses.field(default_factory=list)

    def dried(self, zs: np.ndarray) -> np.ndarray:
        """``zs`` (…, P) with the dry recordings' film half-lengths at their dry end."""
        zs = np.array(zs, dtype=float, copy=True)
        zs[..., self.dry] = -Z_END
        return zs

    def held(self, name: str | None = None) -> list[int]:
        """Coordinates held fixed in a fit of effect ``name`` (None: of no effect): the
        nuisances and every other effect's fields."""
        others = [i for n, idx in self.candidates.items() if n != name for i in idx]
        return sorted(self.nuisances + others)


def whitened_rows(trial: Trial, mean: np.ndarray) -> np.ndarray:
    """The identification's whitened data rows for mean features ``mean`` (R, B)."""
    sigma = np.asarray(trial.problem.sigma)
    return trial.noise.whiten @ ((trial.data - mean) / sigma).reshape(-1)


def residual_rows(trial: Trial, zs) -> np.ndarray:
    """Whitened data rows and prior rows at each point of ``zs``: (K, n)."""
    problem = trial.problem
    mean = np.asarray(problem.mean_of(evaluate(problem, zs)))
    return np.stack(
        [
            np.concatenate([whitened_rows(trial, mean[k]), problem.prior_rows(np.asarray(z))])
            for k, z in enumerate(zs)
        ]
    )


def refit(trial: Trial, z, held: list[int]) -> np.ndarray:
    """``z`` after ``trial.iterations`` of damped Gauss–Newton on the coordinates not in
    ``held``."""
    if not trial.iterations:
        return z
    steps = np.minimum(trial.problem.fd_steps(np.asarray(z)), 1.0)[None]
    rows = functools.partial(residual_rows, trial)
    return polish_profile(rows, z[None], [held], steps, iterations=trial.iterations)[0]


def refit_without_effects(trial: Trial, z, say) -> tuple[np.ndarray, float, float]:
    """The model without effects re-fitted over ``a`` and ``drag_torque`` from the
    screening's alternatives of them at ``z`` (every effect absent): the re-fitted point,
    the cost at ``z`` and the re-fit's."""
    say(
        f"re-fitting a and T_b without effects ({len(FREE_FACTORS)} starts, "
        f"{trial.iterations} iterations; one program holds every candidate, compiling first) …"
    )
    starts = trial.dried(free_alternatives(np.asarray(z, dtype=float), trial.problem))
    cost = np.sum(residual_rows(trial, starts) ** 2, axis=1)  # row 0: z
    z_base = refit(trial, starts[int(np.argmin(cost))], trial.held())
    refit_cost = float(np.sum(residual_rows(trial, z_base[None]) ** 2))
    return z_base, float(cost[0]), refit_cost


def fit_effect(trial: Trial, name: str, z_base, say) -> np.ndarray:
    """Effect ``name`` screened from ``z_base`` (every effect absent) and fitted with ``a``
    and ``drag_torque``, the other effects held absent: the fitted point."""
    idx = trial.candidates[name]
    starts = np.concatenate([z_base[None], screen_points(z_base, idx, trial.problem)])
    starts = trial.dried(starts)
    cost = np.sum(residual_rows(trial, starts) ** 2, axis=1)
    best = starts[1 + int(np.argmin(cost[1:]))]
    say(
        f"  {name}: cost {cost[0]:.1f} without, {cost.min():.1f} at the best start; "
        f"fitting it with a and T_b ({trial.iterations} iterations) …"
    )
    return refit(trial, best, trial.held(name))


def final_chi2(trial: Trial, z) -> tuple[float, np.ndarray]:
    """χ² of the data rows at ``z`` on the fresh release states, and the mean features."""
    mean = np.asarray(trial.problem.mean_of(evaluate(trial.problem, z[None], trial.y0)))[0]
    return float(np.sum(whitened_rows(trial, mean) ** 2)), mean


def judge_effect(
    trial: Trial, name: str, chi2_without: float, z_fit, level: float
) -> EffectOutcome:
    """The effect's outcome: χ² with it on the fresh realisations against ``chi2_without``
    (the same realisations without any effect), the F-test at ``level`` and the Monte Carlo
    noise of the drop."""
    idx = trial.candidates[name]
    d = len(idx)
    chi2_with, mean = final_chi2(trial, z_fit)
    delta = chi2_without - chi2_with
    # Monte Carlo noise of each χ² from n realisations (cf. the profile threshold)
    n, dof = trial.y0.shape[1], trial.dof
    var = 4.0 * max(chi2_without, dof) / (n + 1) + 4.0 * max(chi2_with, dof) / (n + 1)
    threshold = Z95_ONE_SIDED * math.sqrt(var)
    dof_with = max(dof - d, 1)
    f_stat = (delta / d) / max(chi2_with / dof_with, 1e-12)
    p_value = float(stats.f.sf(f_stat, d, dof_with)) if delta > 0 else 1.0
    specs = [trial.problem.specs[i] for i in idx]
    values = {
        s.name.split(".", 1)[1]: float(s.value(z_fit[i])) for i, s in zip(idx, specs, strict=True)
    }
    return EffectOutcome(
        name=name,
        values=values,
        units={k: u for k, (u, _, _) in effect_class(name).ranges.items()},
        chi2_without=chi2_without,
        chi2_with=chi2_with,
        delta_chi2=delta,
        gap_closed=gap_closed(chi2_without, chi2_with, dof),
        p_value=p_value,
        noise_threshold=threshold,
        supported=bool(p_value < level and delta > threshold),
        residuals=(trial.data - mean) / np.asarray(trial.problem.sigma),
        wall_time=0.0,
        p_after=float(stats.chi2.sf(chi2_with, dof_with)),
    )


def moves(trial: Trial, z_base, z_fit) -> dict[str, tuple[float, float]]:
    """How the parameters the effect is fitted with (the film half-lengths, the drag
    torque) move once it is in: name → (without, with), SI units. A base-model estimate that
    the effect moves far was biased by its absence."""
    effect_coords = {i for idx in trial.candidates.values() for i in idx}
    out = {}
    for i, spec in enumerate(trial.problem.specs):
        if i in effect_coords or spec.name.startswith("backlash"):
            continue
        if i in trial.nuisances:
            continue
        out[spec.name] = (float(spec.value(z_base[i])), float(spec.value(z_fit[i])))
    return out


def try_effect(
    trial: Trial, name: str, z_base, chi2_without: float, level: float, say
) -> EffectOutcome:
    """Fit effect ``name`` (:func:`fit_effect`) and judge it (:func:`judge_effect`)."""
    t0 = time.perf_counter()
    z_fit = fit_effect(trial, name, z_base, say)
    outcome = judge_effect(trial, name, chi2_without, z_fit, level)
    outcome = dataclasses.replace(
        outcome, wall_time=time.perf_counter() - t0, moves=moves(trial, z_base, z_fit)
    )
    say(
        f"  {name}: χ² {outcome.chi2_without:.1f} → {outcome.chi2_with:.1f} "
        f"(p = {outcome.p_value:.2g}{', supported' if outcome.supported else ''}) in "
        f"{outcome.wall_time:.0f} s"
    )
    return outcome


def candidate_problem(problem: Problem, names) -> tuple[Problem, dict[str, list[int]]]:
    """``problem`` with every effect in ``names`` added at its absent end, and each effect's
    coordinates."""
    specs, candidates = list(problem.specs), {}
    for name in names:
        extra = effect_specs(name)
        candidates[name] = list(range(len(specs), len(specs) + len(extra)))
        specs += extra
    effects = tuple(absent(name) for name in names)
    return dataclasses.replace(problem, specs=tuple(specs), effects=effects), candidates


def dry_films(problem: Problem, recordings: Sequence[Recording]) -> list[int]:
    """Coordinates of the film half-lengths that only dry recordings use."""
    lubrication = [r.operating.lubrication for r in recordings]
    wet = {f for f, lub in zip(problem.films, lubrication, strict=True) if lub != "dry"}
    dry = {f for f in problem.films} - wet
    return [i for i, sp in enumerate(problem.specs) if sp.name in dry]


def trial_of(
    recordings: Sequence[Recording],
    baseline: FitResult,
    options: DiagnoseOptions,
    names: Sequence[str] | None = None,
) -> Trial:
    """The :class:`Trial` of ``baseline``: its problem with the candidates ``names`` (default:
    every effect of ``options``), noise model and fresh release states (seeded from the fit's
    seed + 1) for the final comparison."""
    base = baseline.problem_for(recordings)
    problem, candidates = candidate_problem(base, options.effects if names is None else names)
    fit_options = baseline.options
    n_final = options.n_final or fit_options.n_covariance_realisations
    y0 = release_states(base, baseline.z, n_final, np.random.default_rng(fit_options.seed + 1))
    dry = dry_films(base, recordings)
    nuisances = [i for i, sp in enumerate(base.specs) if sp.log_sd is not None] + dry
    return Trial(
        problem,
        baseline.noise,
        np.asarray(base.data),
        y0,
        baseline.dof,
        options.iterations,
        nuisances,
        candidates,
        dry,
    )


def in_program(options: DiagnoseOptions, seen: set[str]) -> tuple[str, ...]:
    """The candidates the compiled program holds: every effect of ``options`` but those the
    encoders see and did not (:data:`~rattlefit.diagnosis.evidence.ENCODER_VISIBLE`), unless
    ``options.every_effect``."""
    if options.every_effect:
        return options.effects
    return tuple(n for n in options.effects if n not in ENCODER_VISIBLE or n in seen)


def effects_to_try(
    options: DiagnoseOptions, seen: set[str], band_gap: bool
) -> tuple[list[str], dict[str, str]]:
    """The effects fitted to the band spectrum, and why each other one is not: an effect the
    encoders see is named only when they see it, and a band candidate only explains a
    significant band gap (unless ``options.every_effect``)."""
    tried, skipped = [], {}
    for name in options.effects:
        if options.every_effect:
            tried.append(name)
        elif name in ENCODER_VISIBLE and name not in seen:
            skipped[name] = "the encoders show no sign of it"
        elif name not in ENCODER_VISIBLE and not band_gap:
            skipped[name] = "the model without effects fits the band spectrum within its noise"
        else:
            tried.append(name)
    return tried, skipped


def try_effects(trial: Trial, names, z_base, chi2_without, significance, say):
    """Each effect of ``names`` fitted and judged (:func:`try_effect`) at ``significance``
    over their number (Bonferroni), the least misfit left first."""
    level = significance / max(len(names), 1)
    outcomes = []
    for n, name in enumerate(names):
        say(f"effect {n + 1}/{len(names)}: {name} — screening …")
        outcomes.append(try_effect(trial, name, z_base, chi2_without, level, say))
    return sorted(outcomes, key=lambda o: o.chi2_with)


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
    found = findings(recordings, options.significance)
    for f in found:
        if f.significant:
            say(f"model-free evidence: {finding_phrase(f)}")
    if baseline is None:
        say("identifying the model without extra effects …")
        baseline = identify(recordings, options.fit, progress=progress)
    elif baseline.recordings != [str(r.path) for r in recordings]:
        raise RattlefitError(
            f"diagnose: the baseline fit is of {baseline.recordings}, not of "
            f"{[str(r.path) for r in recordings]}"
        )
    seen = {f.effect for f in found if f.significant}
    trial = trial_of(recordings, baseline, options, in_program(options, seen))
    z_absent = trial.dried(
        np.concatenate([baseline.z, np.full(len(trial.problem.specs) - len(baseline.z), -Z_END)])
    )
    z_base, cost_identified, refit_cost = refit_without_effects(trial, z_absent, say)
    chi2_without, _ = final_chi2(trial, z_base)
    warnings = baseline_warnings(baseline.success, cost_identified, refit_cost)
    for w in warnings:
        say("  warning: " + w)
    gap = stats.chi2.sf(chi2_without, trial.dof) < options.significance
    tried, skipped = effects_to_try(options, seen, gap)
    for name, why in skipped.items():
        say(f"not fitting {name}: {why}")
    outcomes = try_effects(trial, tried, z_base, chi2_without, options.significance, say)
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
        findings=tuple(found),
        significance=options.significance,
        chi2_without=chi2_without,
        skipped=skipped,
        platform=platform,
    )
