"""Where the model misses a recording, which unmodelled effect explains it, and by how much.

:func:`diagnose` first reads the recordings alone
(:mod:`rattlefit.diagnosis.evidence`): the flank positions against each wheel's angle and
tooth (run-out, a transmission error, a tooth defect) and a drift over the recording. Then it
starts from an identification (:func:`~rattlefit.inference.identify.identify`) and

1. **locates the gap**: each band's standardised residual ``(measured − fitted)/σ`` at the
   optimum, and the bands where it exceeds :data:`~rattlefit.diagnosis.result.MISSED_Z`;
2. **re-fits the model without effects** over ``a``, ``drag_torque`` and the nuisances
   (with their priors) from the alternatives of ``a`` and ``drag_torque`` every effect's
   screening starts from (:data:`~rattlefit.diagnosis.screening.FREE_FACTORS` and
   :data:`~rattlefit.diagnosis.screening.DRAG_SPREAD`), so that an
   effect is not credited with what that re-fit alone gains, nor with what a plausible
   shift of the mesh stiffness, h_min or the viscosity explains; when the re-fit lowers
   the identification's cost by more than half, or the identification stopped at its step
   limit, the diagnosis warns (:func:`~rattlefit.diagnosis.result.baseline_caveats`);
3. **tries each effect** of :mod:`rattlefit.physics.effects` on its own: added to the model
   at its absent end, its fields screened over their ranges
   (:func:`~rattlefit.diagnosis.screening.screen`), then fitted together with ``a``
   and ``drag_torque`` (damped Gauss–Newton on finite differences; the nuisances stay at
   the re-fit's values);
4. **measures how far the gap shrinks**, out of sample: the χ² of the data rows (band
   correlations included, the identification's noise model fixed: on the learned likelihood,
   its covariance at the optimum) without the effect and
   with it, both from the same :attr:`DiagnoseOptions.n_final` fresh realisations (common
   random numbers) that no fit saw, so that points which fit the fit's own few
   realisations by luck do not count. ``gap_closed`` is the share of the excess misfit
   (χ² − dof) that the effect removes;
5. **pairs** the best supported candidate with the next ones when it leaves a significant
   misfit, after fitting it on until settled (:mod:`rattlefit.diagnosis.pairs`), and
   **sizes** the named candidate with a profile interval (:mod:`rattlefit.diagnosis.size`).

Beside the bands, the drive-cycle-folded statistics of the recordings are compared with the
model without effects (:mod:`rattlefit.diagnosis.cycle`): where in the speed fluctuation,
and on which flank, it misses.

The verdict (:func:`~rattlefit.diagnosis.verdict.decide`) is ``"none"`` when the model
without extra effects fits the band spectrum (its χ² after the re-fit, on the fresh
realisations, has p ≥ ``significance`` against recordings the model itself makes:
:func:`~rattlefit.diagnosis.trial.misfit_p`) and its drive-cycle statistics, and no
model-free test stands out; the effects that significant model-free tests point to are
named; a band candidate is named when it is supported and leaves a misfit consistent with
noise (by the same null, at its fitted point), no candidate of another mechanism does too
(:func:`~rattlefit.diagnosis.verdict.rivals`), and,
beside an effect the encoders found, only together with that effect (it is known to be
there, so the other candidate must close clearly more than it alone); a significant gap
that a candidate nearly closes but not to noise is ``"model_form"``, and one that nothing
explains is ``"unexplained"``.

An effect is *supported* when an F-test of its χ² drop against the misfit that remains gives
p < ``significance`` / (effects tried) (Bonferroni: ``significance`` is the family-wise
level) and the drop exceeds the Monte Carlo noise of a difference of two χ²s. One compiled
program holds every candidate, each at its absent end unless fitted, so the χ² without
effects is one number on one set of realisations, and every effect's drop and share of the
gap compare like with like.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence

import numpy as np

from ..errors import RattlefitError
from ..inference.identify import identify
from ..inference.result import FitResult
from ..io.recording import Recording
from ..physics.effects import DEFAULT_EFFECTS, effect_class
from ..problem.options import FitOptions
from ..problem.parameters import Z_END
from ..problem.problem import release_states
from ..reproducibility import platform_info
from ..rig import setup
from ..util import stamped
from .cycle import cycle_gap
from .evidence import candidate_static, findings
from .null import NULL_REALISATIONS, with_simulated_null
from .outcome import EffectOutcome
from .pairs import pair_candidates, settled_single, try_pair
from .policy import (
    CONTENDERS,
    SIGNIFICANCE,
    effects_to_try,
    in_program,
    is_pair,
    misses,
    pair_name,
)
from .result import Diagnosis, baseline_caveats
from .screening import distinct_rows, free_alternatives, screen
from .size import interval_caveat, relevant, size_intervals
from .trial import (
    Trial,
    candidate_problem,
    costs,
    dry_films,
    final_chi2,
    fresh_features,
    judge_effect,
    misfit_p,
    moves,
    refit,
    refit_all,
    residual_rows,
    settled_path,
    validated,
)
from .verdict import Evidence, decide

#: The final χ²s are measured on this many times the fit's covariance realisations: near a
#: regime boundary the χ² of one set of 24 can be 11 and of another 67 at the same point
#: (the mean keeps the realisations in the recording's regime, and a small set may hold
#: none), and a candidate that makes the regime unique would be credited with that.
FINAL_FACTOR = 2
#: Each candidate is fitted from this many of its screening's best starts.
CANDIDATE_STARTS = 2
#: Recordings of the model behind a band misfit's null (``DiagnoseOptions.misfit_null``).
MISFIT_NULL_REALISATIONS = 32


@dataclasses.dataclass(frozen=True)
class DiagnoseOptions:
    """Options of :func:`diagnose`.

    effects : names of the effects to try (of :data:`rattlefit.physics.effects.EFFECTS`;
        default :data:`~rattlefit.physics.effects.DEFAULT_EFFECTS`).
    fit : options of the identification that the diagnosis starts from (its seed seeds the
        diagnosis too, and its likelihood's noise model at the optimum is the one the
        diagnosis judges with); by default :meth:`FitOptions.optimum_only`, since the
        diagnosis uses the optimum and its noise model, not the intervals.
    iterations : Gauss–Newton iterations per effect.
    base_iterations : most Gauss–Newton iterations of the re-fit without effects that moves
        the nuisances (with their priors) besides ``a`` and ``drag_torque``; it stops
        earlier once settled (:func:`~rattlefit.diagnosis.trial.settled_path`).
    n_final : realisations behind each final χ² (default: :data:`FINAL_FACTOR` × the fit's
        covariance count).
    significance : family-wise level: an effect counts as supported when its F-test p is
        below ``significance`` over the number of effects fitted (Bonferroni); the
        model-free tests share it likewise, and the band gap is tested at it.
    null_realisations : recordings of the fitted model without effects that give the
        encoder tests' null where one of them finds a pattern
        (:mod:`rattlefit.diagnosis.null`); 0 judges them by their decoys alone.
    misfit_null : recordings of the model at each point judged that give the band misfit's
        null (:func:`~rattlefit.diagnosis.trial.misfit_null`): the gap's p and every
        candidate's ``p_after``; 0 refers them to the χ² tail instead.
    every_effect : fit every effect to the band spectrum, also those the encoders show no
        sign of and when the model without effects fits within its noise (by default they
        are skipped: they could not be named).
    """

    effects: tuple[str, ...] = DEFAULT_EFFECTS
    fit: FitOptions = dataclasses.field(default_factory=FitOptions.optimum_only)
    iterations: int = 3
    base_iterations: int = 12
    n_final: int | None = None
    significance: float = SIGNIFICANCE
    every_effect: bool = False
    null_realisations: int = NULL_REALISATIONS
    misfit_null: int = MISFIT_NULL_REALISATIONS

    def __post_init__(self):
        for name in self.effects:
            effect_class(name)  # raises with the list of known effects
        if self.iterations < 0 or self.base_iterations < 0:
            raise RattlefitError("DiagnoseOptions.iterations and base_iterations must be ≥ 0")
        if self.null_realisations != 0 and self.null_realisations < 8:
            raise RattlefitError(
                "DiagnoseOptions.null_realisations must be 0 (decoys alone) or ≥ 8, got "
                f"{self.null_realisations}"
            )
        if self.misfit_null != 0 and self.misfit_null < 8:
            raise RattlefitError(
                "DiagnoseOptions.misfit_null must be 0 (the χ² tail) or ≥ 8, got "
                f"{self.misfit_null}"
            )


def refit_without_effects(trial: Trial, z, say) -> tuple[np.ndarray, float, float]:
    """The model without effects re-fitted from the best of the screening's alternatives of
    ``a`` and ``drag_torque`` at ``z`` (every effect absent): over ``a`` and ``drag_torque``
    alone, and over them and the nuisances, two iterations at a time until settled
    (:func:`~rattlefit.diagnosis.trial.settled_path`). Of these points the one with the
    lowest χ² on the validation realisations is kept: a re-fit with more coordinates can
    chase the fit's own few realisations, and validation stops it early. Returns the kept
    point, the cost at ``z`` and the kept point's cost."""
    starts = distinct_rows(
        trial.dried(free_alternatives(np.asarray(z, dtype=float), trial.problem))
    )
    say(
        f"re-fitting the model without effects ({len(starts)} starts; a and T_b, then also "
        "the nuisances; one program holds every candidate, compiling first) …"
    )
    cost = costs(trial, starts)  # row 0: z
    start = starts[int(np.argmin(cost))]
    path = settled_path(trial, start, trial.held(nuisances=False), iterations=trial.base_iterations)
    refits = np.concatenate([refit(trial, start, trial.held())[None], path])
    k, validation = validated(trial, refits)
    kept = "a and T_b alone" if k == 0 else f"with the nuisances after {2 * k} iterations"
    say(f"  validation χ² {' → '.join(f'{v:.1f}' for v in validation)}: keeping {kept}")
    refit_cost = float(np.sum(residual_rows(trial, refits[k][None]) ** 2))
    return refits[k], float(cost[0]), refit_cost


def fit_effect(trial: Trial, name: str, z_base, say) -> np.ndarray:
    """Effect ``name`` screened from ``z_base`` (:func:`screen`) and fitted with ``a`` and
    ``drag_torque`` from each of the :data:`CANDIDATE_STARTS` best starts, the other effects
    held absent: of the fits and the best start, the point best on the validation states
    (:func:`validated`)."""
    starts, cost_without, cost_best = screen(trial, name, z_base)
    starts = starts[:CANDIDATE_STARTS]
    say(
        f"  {name}: cost {cost_without:.1f} without, {cost_best:.1f} at the best start; "
        f"fitting it with a and T_b from {len(starts)} starts ({trial.iterations} iterations) …"
    )
    points = np.concatenate([refit_all(trial, starts, trial.held(name)), starts[:1]])
    return points[validated(trial, points)[0]]


def try_effect(
    trial: Trial, name: str, z_base, chi2_without: float, level: float, say
) -> tuple[EffectOutcome, np.ndarray]:
    """Fit effect ``name`` (:func:`fit_effect`) and judge it (:func:`judge_effect`): the
    outcome and the fitted point."""
    t0 = time.perf_counter()
    z_fit = fit_effect(trial, name, z_base, say)
    outcome = judge_effect(trial, name, chi2_without, z_fit, level)
    outcome = dataclasses.replace(
        outcome, wall_time=time.perf_counter() - t0, moves=moves(trial, z_base, z_fit)
    )
    say(f"  {outcome_phrase(outcome)}")
    return outcome, z_fit


def outcome_phrase(o: EffectOutcome) -> str:
    """One judged outcome in a progress line."""
    if o.failure:
        return f"{o.name}: failed ({o.failure}) in {o.wall_time:.0f} s"
    return (
        f"{o.name}: χ² {o.chi2_without:.1f} → {o.chi2_with:.1f} "
        f"(p = {o.p_value:.2g}{', supported' if o.supported else ''}) in {o.wall_time:.0f} s"
    )


def trial_of(
    recordings: Sequence[Recording],
    baseline: FitResult,
    options: DiagnoseOptions,
    names: Sequence[str] | None = None,
    static: dict[str, dict] | None = None,
) -> Trial:
    """The :class:`Trial` of ``baseline``: its problem with the candidates ``names`` (default:
    every effect of ``options``; each with its ``static`` fields), noise model, fresh release
    states for the final comparison and validation states (the fit's covariance count), from
    two children spawned from the fit's seed."""
    if baseline.state.likelihood is None:
        raise RattlefitError("diagnose: the baseline fit holds no likelihood (identify first)")
    noise, base = baseline.state.likelihood.noise, baseline.problem_for(recordings)
    names = options.effects if names is None else names
    problem, candidates = candidate_problem(base, names, static)
    fit_options = baseline.state.options
    n_validation = fit_options.n_covariance_realisations
    n_final = options.n_final or FINAL_FACTOR * n_validation
    # children 0 and 1: the final and validation states; 2: the encoder null; 3: the misfit's
    s_final, s_validation, _, s_null = np.random.SeedSequence(fit_options.seed).spawn(4)
    y0 = release_states(base, baseline.state.z, n_final, np.random.default_rng(s_final))
    validation = release_states(
        base, baseline.state.z, n_validation, np.random.default_rng(s_validation)
    )
    null_y0 = None
    if options.misfit_null:
        null_y0 = release_states(
            base, baseline.state.z, options.misfit_null, np.random.default_rng(s_null)
        )
    dry = dry_films(base, recordings)
    nuisances = [i for i, sp in enumerate(base.specs) if sp.nuisance]
    return Trial(
        problem,
        noise,
        np.asarray(base.data),
        y0,
        baseline.statistics.dof,
        options.iterations,
        nuisances,
        candidates,
        dry,
        options.base_iterations,
        validation,
        null_y0,
    )


def by_misfit(outcomes) -> list[EffectOutcome]:
    """``outcomes`` judged first, the least misfit left first."""
    return sorted(outcomes, key=lambda o: (bool(o.failure), o.chi2_with))


def settle(trial: Trial, single: EffectOutcome, fitted: dict, z_base, chi2_without, level, say):
    """``single`` fitted on until settled (:func:`~rattlefit.diagnosis.pairs.settled_single`)
    from its point in ``fitted``, which gets the new point: the settled outcome."""
    say(f"fitting {single.name} on until settled, the nuisances free …")
    settled, fitted[single.name] = settled_single(
        trial, single, fitted[single.name], z_base, chi2_without, level
    )
    say(f"  {outcome_phrase(settled)}")
    return settled


def settle_contenders(
    trial: Trial,
    outcomes: list[EffectOutcome],
    fitted: dict,
    z_base,
    chi2_without: float,
    level: float,
    significance: float,
    say,
) -> tuple[list[EffectOutcome], frozenset[str]]:
    """The :data:`~.policy.CONTENDERS` supported single candidates with the least misfit that still
    leave a significant one (``p_after`` below ``significance``), each fitted on until
    settled with the nuisances free, as the model without effects was
    (:func:`~rattlefit.diagnosis.pairs.settled_single`): a few Gauss–Newton steps from a
    screened start can stop short of an effect's minimum. Returns the outcomes (each
    settled one in its place, least misfit first) and the names settled; ``fitted`` gets
    their new points."""
    contenders = [
        o
        for o in outcomes
        if o.supported and not o.failure and not is_pair(o.name) and o.p_after < significance
    ][:CONTENDERS]
    for first in contenders:
        settled = settle(trial, first, fitted, z_base, chi2_without, level, say)
        outcomes = [settled if o is first else o for o in outcomes]
    return by_misfit(outcomes), frozenset(o.name for o in contenders)


def try_effects(trial: Trial, names, z_base, chi2_without, level, say):
    """Each effect of ``names`` fitted and judged (:func:`try_effect`) at ``level``: the
    outcomes, the least misfit left first, and each effect's fitted point."""
    outcomes, fitted = [], {}
    for n, name in enumerate(names):
        say(f"effect {n + 1}/{len(names)}: {name} — screening …")
        outcome, fitted[name] = try_effect(trial, name, z_base, chi2_without, level, say)
        outcomes.append(outcome)
    return by_misfit(outcomes), fitted


def try_pairs(
    trial: Trial,
    outcomes: list[EffectOutcome],
    evidence: Evidence,
    chi2_without: float,
    fitted: dict,
    z_base,
    level: float,
    say,
    settled_names: frozenset[str] = frozenset(),
):
    """When the band gap is significant (``evidence``) and the first candidate of
    :func:`~rattlefit.diagnosis.pairs.pair_candidates` (an effect the encoders found, else
    the best supported one) leaves a significant misfit: that candidate fitted on until
    settled (:func:`~rattlefit.diagnosis.pairs.settled_single`; not again when it is in
    ``settled_names``) and, if it still leaves one, fitted together with each of the next
    supported ones. Returns the single outcomes (the
    settled one in its place, least misfit first) and the pairs' outcomes; ``fitted`` gets
    every new point."""
    pairs = pair_candidates(outcomes, evidence.seen)
    if not evidence.band_gap or not pairs or pairs[0][0].p_after >= evidence.significance:
        return outcomes, []
    first = pairs[0][0]
    settled = (
        first
        if first.name in settled_names
        else settle(trial, first, fitted, z_base, chi2_without, level, say)
    )
    outcomes = by_misfit(settled if o is first else o for o in outcomes)
    if settled.p_after >= evidence.significance:
        return outcomes, []
    out = []
    for _, second in pairs:
        say(f"fitting {settled.name} and {second.name} together …")
        t0 = time.perf_counter()
        outcome, fitted[pair_name(settled.name, second.name)] = try_pair(
            trial, settled, second, fitted, chi2_without, level
        )
        outcome = dataclasses.replace(outcome, wall_time=time.perf_counter() - t0)
        say(f"  {outcome_phrase(outcome)}")
        out.append(outcome)
    return outcomes, out


def sized(trial: Trial, named: EffectOutcome, fitted: dict, significance: float) -> EffectOutcome:
    """``named`` with its size estimated with an interval
    (:func:`~rattlefit.diagnosis.size.size_intervals`): its ``values`` hold the profile's
    estimate, its ``intervals`` the 95 % interval, ``relevant`` whether that interval stays
    above the relevance floor (:func:`~rattlefit.diagnosis.size.relevant`), and
    ``interval_caveat`` why it is not a 95 % interval of the size when ``named`` leaves a
    misfit significant at ``significance`` (:func:`~rattlefit.diagnosis.size.interval_caveat`)."""
    profiled = size_intervals(trial, named.name, fitted[named.name], named.chi2_with)
    intervals = {k: (lo, hi) for k, (_, lo, hi) in profiled.items()}
    out = dataclasses.replace(
        named,
        values={**named.values, **{k: best for k, (best, _, _) in profiled.items()}},
        intervals=intervals,
        relevant=relevant(intervals, named.name, trial),
    )
    dof = max(trial.dof - len(trial.fields(named.name)), 1)
    return dataclasses.replace(out, interval_caveat=interval_caveat(out, significance, dof))


def to_size(outcomes: list[EffectOutcome], evidence: Evidence) -> list[EffectOutcome]:
    """The band candidates the verdict rests on whose size is not yet profiled: the one it
    names, or every supported one it cannot tell apart
    (:attr:`~rattlefit.diagnosis.verdict.Verdict.indistinguishable`; an unsupported one is a
    rival whatever its size)."""
    verdict = decide(outcomes, evidence)
    rest = verdict.indistinguishable or ([verdict.explaining] if verdict.explaining else [])
    return [o for o in rest if not o.intervals and o.supported]


def with_interval(
    trial: Trial, outcomes: list[EffectOutcome], evidence: Evidence, fitted: dict, say
) -> list[EffectOutcome]:
    """``outcomes`` with the band candidates the verdict rests on (:func:`to_size`) sized
    (:func:`sized`). A candidate whose interval reaches below its relevance floor is no
    longer nameable, nor a rival of another: the verdict is decided again, and what it then
    rests on is sized in turn (each candidate at most once)."""
    while pending := to_size(outcomes, evidence):
        for named in pending:
            say(f"profiling the size of {named.name} …")
            done = sized(trial, named, fitted, evidence.significance)
            if not done.relevant:
                say(f"  {named.name}: its interval reaches below the size worth naming")
            outcomes = [done if o is named else o for o in outcomes]
    return outcomes


def drive_cycle(trial: Trial, z_base, recordings, baseline: FitResult, level: float, say):
    """The recordings' drive-cycle statistics against the model without effects at
    ``z_base`` (:func:`~rattlefit.diagnosis.cycle.cycle_gap`) at the family-wise ``level``,
    each recording's drive reconstructed as ``baseline``'s."""
    say("comparing the drive-cycle statistics with the model without effects …")
    rigs = [setup(r, drive=baseline.state.options.drive) for r in recordings]
    gap = cycle_gap(trial, z_base, rigs, level)
    if gap.significant:
        say(f"  the drive-cycle statistics miss: {gap.phrase()} (p = {gap.p_value:.2g})")
    return gap


def identified(recordings, options: DiagnoseOptions, baseline: FitResult | None, progress, say):
    """``baseline``, checked to be of ``recordings``, or an identification of them."""
    if baseline is None:
        say("identifying the model without extra effects …")
        return identify(recordings, options.fit, progress=progress)
    if baseline.provenance.recordings != [str(r.path) for r in recordings]:
        raise RattlefitError(
            f"diagnose: the baseline fit is of {baseline.provenance.recordings}, not of "
            f"{[str(r.path) for r in recordings]}"
        )
    return baseline


def require_band_fit(options: DiagnoseOptions, baseline: FitResult | None) -> None:
    """Raise :class:`~rattlefit.errors.RattlefitError` unless the fit the diagnosis starts
    from (``baseline``, else ``options.fit``) compares the band features alone: the
    judgement, its thresholds and its figures are those of the bands."""
    fit_options = options.fit if baseline is None else baseline.state.options
    if fit_options.features != "bands":
        raise RattlefitError(
            f"diagnose: FitOptions.features: the diagnosis judges the band features, but the "
            f"fit compares {fit_options.features!r}; identify with features='bands'"
        )


def model_free(recordings, options: DiagnoseOptions, say):
    """The model-free tests of ``recordings`` (:func:`~rattlefit.diagnosis.evidence.findings`)
    and the effects the significant ones point to."""
    found = findings(recordings, options.significance)
    for f in found:
        if f.significant:
            say(f"model-free evidence: {f.effect} ({f.test.name}, p = {f.test.p_value:.2g})")
    return found, {f.effect for f in found if f.significant}


def simulated_null(found, recordings, baseline: FitResult, options: DiagnoseOptions, say):
    """``found`` with the encoder findings judged again against the fitted model's null
    (:func:`~rattlefit.diagnosis.null.with_simulated_null`, from the third child of the fit's
    seed), and the effects the significant ones then point to."""
    seed = np.random.SeedSequence(baseline.state.options.seed).spawn(3)[2]
    again = with_simulated_null(
        found, recordings, baseline, n=options.null_realisations, seed=seed, say=say
    )
    for before, after in zip(found, again, strict=True):
        if before.significant and not after.significant:
            say(
                f"  {after.test.name} of recording {after.recording}: within the null of "
                f"{options.null_realisations} recordings of the model without effects "
                f"(p = {after.test.detail['null_p']:.2g}); not evidence of {after.effect}"
            )
    return again, {f.effect for f in again if f.significant}


def base_model(trial: Trial, baseline: FitResult, say):
    """The model without effects re-fitted (:func:`refit_without_effects`) from
    ``baseline``: its point, its χ² on the fresh realisations with that χ²'s p under the
    model's simulated null (:func:`~rattlefit.diagnosis.trial.misfit_p`), the
    identification's cost and the re-fit's, and the warnings about the identification."""
    z_absent = trial.dried(
        np.concatenate(
            [baseline.state.z, np.full(len(trial.problem.specs) - len(baseline.state.z), -Z_END)]
        )
    )
    z_base, cost_identified, refit_cost = refit_without_effects(trial, z_absent, say)
    fresh = fresh_features(trial, z_base[None])[0]
    chi2_without, _ = final_chi2(trial, z_base, fresh)
    gap_p = misfit_p(trial, z_base, chi2_without, trial.dof, fresh)
    against = (
        "the χ² tail"
        if trial.null_y0 is None
        else f"{trial.null_y0.shape[1]} simulated recordings of the model"
    )
    say(f"  χ² without effects {chi2_without:.1f} on {trial.dof}: p = {gap_p:.2g} by {against}")
    caveats = baseline_caveats(baseline.statistics.success, cost_identified, refit_cost)
    for c in caveats:
        say(f"  caveat: {c.value.replace('_', ' ')}")
    return z_base, (chi2_without, gap_p), (cost_identified, refit_cost), caveats


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
    :class:`~rattlefit.errors.RattlefitError` when ``baseline`` is of other recordings or
    the fit compares more than the bands (``FitOptions.features``).
    """
    options = options or DiagnoseOptions()
    require_band_fit(options, baseline)
    t_start = time.perf_counter()
    say = stamped(progress, t_start)  # progress, stamped with the time since the start
    platform = platform_info()
    found, _ = model_free(recordings, options, say)
    baseline = identified(recordings, options, baseline, progress, say)
    found, seen = simulated_null(found, recordings, baseline, options, say)
    trial = trial_of(
        recordings,
        baseline,
        options,
        in_program(options.effects, seen, options.every_effect),
        candidate_static(found),
    )
    z_base, (chi2_without, gap_p), refit_costs, warnings = base_model(trial, baseline, say)
    cycle = drive_cycle(trial, z_base, recordings, baseline, options.significance, say)
    gap = misses(gap_p, options.significance)
    tried, skipped = effects_to_try(options.effects, seen, gap, options.every_effect)
    for name, why in skipped.items():
        say(f"not fitting {name}: {why}")
    level = options.significance / max(len(tried), 1)  # Bonferroni
    outcomes, fitted = try_effects(trial, tried, z_base, chi2_without, level, say)
    outcomes, settled = settle_contenders(
        trial, outcomes, fitted, z_base, chi2_without, level, options.significance, say
    )
    evidence = Evidence(tuple(found), bool(gap), cycle.significant, options.significance)
    outcomes, pairs = try_pairs(
        trial, outcomes, evidence, chi2_without, fitted, z_base, level, say, settled
    )
    outcomes = with_interval(trial, outcomes + pairs, evidence, fitted, say)
    wall = time.perf_counter() - t_start
    say(f"done in {wall:.0f} s")
    bands = trial.problem.bands
    return Diagnosis(
        baseline=baseline,
        residuals=(trial.data - np.stack(baseline.spectra.fitted))
        / np.stack(baseline.spectra.sigma),
        band_centers=bands.centers,
        band_edges=bands.edges,
        outcomes=outcomes,
        seed=baseline.state.options.seed,
        wall_time=wall,
        refit_costs=refit_costs,
        warnings=warnings,
        findings=tuple(found),
        significance=options.significance,
        chi2_without=chi2_without,
        gap_p=gap_p,
        skipped=skipped,
        platform=platform,
        drive_cycle=cycle,
    )
