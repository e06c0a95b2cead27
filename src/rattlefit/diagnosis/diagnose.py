"""Where the model misses a recording, which unmodelled effect explains it, and by how much.

:func:`diagnose` starts from an identification (:func:`rattlefit.inference.fit.identify`) and

1. **locates the gap**: each band's standardised residual ``(measured − fitted)/σ`` at the
   optimum, and the bands where it exceeds :data:`MISSED_Z`;
2. **tries each effect** of :mod:`rattlefit.physics.effects` on its own: the effect is added to the
   model, its fields are screened over their ranges at the identification's optimum (and
   with less film, and less or more drag, :data:`FREE_FACTORS`) and
   then fitted together with the free parameters ``a`` and ``drag_torque`` (damped
   Gauss–Newton on finite differences, as the profile polish of :mod:`rattlefit.inference.fit` does;
   the nuisances stay at the optimum). The model without effects is first re-fitted over
   ``a`` and ``drag_torque`` the same way, from the same :data:`FREE_FACTORS` starts, so
   that an effect is not credited with what that re-fit alone gains (measured on the
   shared dry file after a quick fit: every effect "gained" 15–20 % of the misfit until the
   comparison was made fair). When that re-fit lowers the identification's cost by more
   than half (:data:`REFIT_WARN_RATIO`), or the identification stopped at its step limit,
   the diagnosis says so in :attr:`Diagnosis.warnings` (:func:`baseline_warnings`);
3. **measures how far the gap shrinks**, out of sample: the χ² of the data rows (band
   correlations included, the identification's noise model fixed) at the optimum without
   the effect and at the fit with it, both from the same :attr:`DiagnoseOptions.n_final`
   fresh realisations (common random numbers), none of which the fits saw. Fitting to the
   fit's own few realisations finds "lucky" points whose χ² does not survive fresh ones
   (measured: re-fitting every parameter moved the out-of-sample χ² without any effect
   between 23 and 57 on one synthetic file), so only the effect and the free parameters
   are fitted, and only fresh realisations judge. ``gap_closed`` is the share of the
   excess misfit (χ² − dof) that the effect removes. An effect is *supported* when an
   F-test of the χ² drop against the remaining misfit gives p < ``significance`` divided by
   the number of effects tried (Bonferroni: ``significance`` is the family-wise level, the
   chance that any effect is supported by chance when none is present) and the drop exceeds
   the Monte Carlo noise of a difference of two χ²s; the verdict is the supported effect
   that leaves the least misfit (the lowest χ² with it). Not the largest drop: each
   effect's χ² without it is the same model at the same point, but simulated by another
   compiled program (the effect's terms are there, at their absent values), and in chaos
   that is another realisation. Measured in session 33 on the CI recording with withheld
   flank friction: the three χ²s without ranged 1735–2217, so run-out's drop (2217 → 1148)
   outranked friction's (1735 → 954) while friction left the least misfit, with the lower
   p. The drops stay the evidence for each effect (paired on common realisations), the
   misfit that remains ranks them. Measured on the shared dry file, whose friction none of the
   catalogue's effects captures: without the correction a drive ripple was supported at
   p = 0.009, one of seven effects tried at the 0.01 level.

Every effect sits at the absent end of its range before the fit, so a χ² drop is evidence
for that effect and the size it takes is an estimate of it. Effects can mimic each other
(a drive ripple and tooth errors both add lines); the ranking says which one the data prefer,
the drop how much it matters.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from collections.abc import Callable, Sequence

import jax.numpy as jnp
import numpy as np
from scipy import stats

from ..errors import RattlefitError
from ..inference.fit import FitOptions, FitResult, _build, _evaluate, _release_states, identify
from ..inference.parameters import Z_END, ParameterSpec
from ..inference.profile import polish_profile
from ..io.recording import Recording
from ..physics.effects import EFFECTS, absent, effect_class
from ..reproducibility import platform_info
from ..util import stamped

#: A band counts as missed when its standardised residual exceeds this (in σ).
MISSED_Z = 3.0

#: Where each effect field is screened before the fit: decades below the top of its range
#: (each range's top is a generous size for a production gearbox, so the sizes worth finding
#: lie within a few decades of it; the lower end means absent). Quarter decades (a factor
#: 1.78) over the top two: an effect's basin can be narrower than half a decade. Measured
#: (session 36, an Intel Xeon with AVX-512) on the CI recording with withheld flank friction
#: μ_f = 0.2: with half decades the best start was μ_f 0.316, a point that looked good on
#: the fit's own realisations (cost 262.5 → 200.7) and not on fresh ones (χ² 251.9 → 493.8:
#: no verdict); with quarter decades μ_f 0.178, χ² 251.9 → 45.8 (p 1.7e-11, the verdict), at
#: 285 s for three effects against 210 s.
SCREEN_DECADES = (0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 3.0)

#: diagnose warns when re-fitting a and T_b without effects lowers the identification's cost
#: below this share of it (the identification had not found the model's best fit).
REFIT_WARN_RATIO = 0.5


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
class EffectOutcome:
    """One effect tried on top of the identification.

    values : the fitted fields (SI, see ``units``); at the lower end of a range the effect is
        absent.
    chi2_without, chi2_with : χ² of the data rows after re-fitting without and with it.
    delta_chi2 : their difference (positive: the effect explains part of the misfit).
    gap_closed : share of the excess misfit (χ² − dof) removed, in [0, 1] (0 when there is
        no excess).
    p_value : F-test of ``delta_chi2`` against the misfit that remains.
    noise_threshold : Monte Carlo noise of a χ² difference (95 % one-sided).
    supported : ``p_value`` < the significance over the number of effects tried, and
        ``delta_chi2`` > ``noise_threshold``.
    residuals : (R, B) standardised band residuals with the effect.
    """

    name: str
    values: dict[str, float]
    units: dict[str, str]
    chi2_without: float
    chi2_with: float
    delta_chi2: float
    gap_closed: float
    p_value: float
    noise_threshold: float
    supported: bool
    residuals: np.ndarray
    wall_time: float

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["parameters"] = {
            k: {"value": v, "unit": self.units[k]} for k, v in d.pop("values").items()
        }
        d.pop("units")
        d["residuals"] = np.asarray(self.residuals).tolist()
        return d


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """What :func:`diagnose` returns: the gap and the effects, best first."""

    baseline: FitResult
    residuals: np.ndarray  # (R, B) standardised residuals of the identification
    band_centers: np.ndarray
    band_edges: np.ndarray
    outcomes: list[EffectOutcome]
    seed: int
    wall_time: float
    refit_costs: tuple[float, float]  # cost at the identification, after the re-fit
    warnings: tuple[str, ...] = ()

    @property
    def missed_bands(self) -> list[dict]:
        """Bands whose standardised residual exceeds :data:`MISSED_Z`: recording index,
        band edges (Hz) and residual (positive: the recording has more power)."""
        out = []
        for k, row in enumerate(np.asarray(self.residuals)):
            for b in np.flatnonzero(np.abs(row) > MISSED_Z):
                lo, hi = self.band_edges[b], self.band_edges[b + 1]
                out.append({"recording": k, "band_hz": [float(lo), float(hi)], "z": float(row[b])})
        return out

    @property
    def verdict(self) -> EffectOutcome | None:
        """The supported effect that leaves the least misfit (lowest χ² with it), or None."""
        supported = [o for o in self.outcomes if o.supported]
        return supported[0] if supported else None

    def to_json(self) -> dict:
        v = self.verdict
        return {
            "verdict": None if v is None else v.name,
            "baseline": {
                "chi2": self.baseline.chi2,
                "dof": self.baseline.dof,
                "p_value": self.baseline.p_value,
                "converged": self.baseline.success,
                "parameters": {k: p.as_dict() for k, p in self.baseline.parameters.items()},
            },
            "band_centers_hz": np.asarray(self.band_centers).tolist(),
            "residuals": np.asarray(self.residuals).tolist(),
            "missed_bands": self.missed_bands,
            "effects": [o.as_dict() for o in self.outcomes],
            "refit": {"cost_identified": self.refit_costs[0], "cost": self.refit_costs[1]},
            "warnings": list(self.warnings),
            "seed": self.seed,
            "platform": platform_info(),  # seeded results depend on it
            "wall_time_s": self.wall_time,
            "recordings": self.baseline.recordings,
        }


def baseline_warnings(converged: bool, cost_identified: float, cost_refit: float) -> list[str]:
    """Why a verdict against this identification may mislead: it stopped at its step limit,
    or re-fitting a and T_b without effects lowered its cost below :data:`REFIT_WARN_RATIO`
    of it. Measured (session 10): after a quick fit that stopped at its step limit with
    χ² 1440 on 28 dof, on a recording with withheld flank friction μ_f 0.2, tooth errors
    and run-out were supported and friction was not; the full fit (χ² 197) names friction."""
    out = []
    if not converged:
        out.append(
            "the identification stopped at its step limit, so the model without effects may "
            "fit better than it does here and an effect may be credited with that; a full "
            "identification (without --quick-fit) is the safer start."
        )
    if cost_refit < REFIT_WARN_RATIO * cost_identified:
        out.append(
            f"the identification was far from the model's best fit: re-fitting a and T_b "
            f"without effects lowered its cost from {cost_identified:.1f} to {cost_refit:.1f}"
            "; the effects are judged against the re-fit."
        )
    return out


def _gap_closed(chi2_without: float, chi2_with: float, dof: int) -> float:
    """Share of the excess misfit χ² − dof that the effect removes, in [0, 1]; 0 when there
    is no excess (the model without the effect already explains the data)."""
    excess = chi2_without - dof
    if excess <= 0:
        return 0.0
    return float(np.clip((chi2_without - chi2_with) / excess, 0.0, 1.0))


def effect_specs(name: str) -> tuple[ParameterSpec, ...]:
    """The fitted fields of effect ``name`` as :class:`~rattlefit.inference.parameters.ParameterSpec`s named
    ``"<effect>.<field>"`` (no prior: log-uniform over the range)."""
    return tuple(
        ParameterSpec(f"{name}.{field}", unit, lo, hi, fd_log_step=0.3)
        for field, (unit, lo, hi) in effect_class(name).ranges.items()
    )


#: The alternatives of (film half-length, drag torque) in the screening, as factors on their
#: fitted values (a film factor 0: the bottom of its range, dry flanks). A dissipative effect
#: (flank friction, a speed-dependent drag) can stand in for the squeeze film and for part
#: of the drag, and the fit without the effect will have given those all the dissipation
#: there is: measured on the shared dry file, whose truth is a = 0 and T_b = 0.025 N m, the
#: fit without friction puts a at 0.07–0.37 mm and T_b at 0.074–0.088 N m. But the drag can
#: be understated as well: on a synthetic dry recording with withheld friction μ_f 0.2
#: (pair II 65.6 mm, 20 % at 16 Hz, session 14) the fit gave the film a = 0.21 mm and T_b
#: 0.0035 N m against the truth 0.025, so that no start with less drag reached the friction
#: (χ² 1255 → 1037 at μ_f 0.046, not supported, and no verdict). Hence the dry starts with
#: more drag too (with them: 1255 → 840 at μ_f 0.11, the verdict).
FREE_FACTORS = (
    (1.0, 1.0),
    (0.1, 1.0),
    (0.01, 1.0),
    (0.0, 1.0),
    (1.0, 0.5),
    (0.0, 0.5),
    (1.0, 0.25),
    (0.0, 0.25),
    (0.0, 2.0),
    (0.0, 4.0),
    (0.0, 8.0),
    (1.0, 4.0),
)


def _screen_points(z_off: np.ndarray, specs: Sequence[ParameterSpec], problem) -> np.ndarray:
    """Starting points: each effect field alone at :data:`SCREEN_DECADES` below the top of
    its range (the others absent), and, with several fields, all of them together; each
    with the film half-length and the drag torque at :data:`FREE_FACTORS` of their values
    at ``z_off``."""
    first = len(problem.specs)
    grid = [np.array([s.z_of(s.upper * 10.0**-k) for s in specs]) for k in SCREEN_DECADES]
    fields = []
    for j in range(len(specs)):
        for g in grid:
            z = z_off.copy()
            z[first + j] = g[j]
            fields.append(z)
    if len(specs) > 1:
        for g in grid:
            z = z_off.copy()
            z[first:] = g
            fields.append(z)
    free = _free_indices(problem)
    points = []
    for alt in _free_alternatives(z_off, problem):
        for z in fields:
            z = z.copy()
            z[free] = alt[free]
            points.append(z)
    return np.stack(points)


def _film_indices(problem) -> list[int]:
    """Where the film half-length(s) sit in the problem's coordinates (one per lubrication)."""
    films = set(problem.films)
    return [i for i, sp in enumerate(problem.specs) if sp.name in films]


def _free_indices(problem) -> list[int]:
    """Where the film half-length(s) and the drag torque sit in the problem's coordinates."""
    names = [sp.name for sp in problem.specs]
    return [*_film_indices(problem), names.index("drag_torque")]


def _free_alternatives(z: np.ndarray, problem) -> np.ndarray:
    """``z`` with the film half-length(s) and the drag torque at each of
    :data:`FREE_FACTORS` of their values in ``z`` (a factor 0: the bottom of the range); one
    row per pair, every film half-length scaled alike."""
    i_drag = _free_indices(problem)[-1]

    def scaled(i, factor):
        spec = problem.specs[i]
        if factor == 0:
            return -Z_END
        return spec.z_of(max(float(spec.value(z[i])) * factor, spec.lower))

    rows = []
    for f_film, f_drag in FREE_FACTORS:
        row = np.array(z, dtype=float, copy=True)
        for i_film in _film_indices(problem):
            row[i_film] = scaled(i_film, f_film)
        row[i_drag] = scaled(i_drag, f_drag)
        rows.append(row)
    return np.stack(rows)


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
    messages. Results are reproducible: every realisation is seeded from the fit's seed.
    """
    options = options or DiagnoseOptions()
    t_start = time.perf_counter()

    say = stamped(progress, t_start)  # progress, stamped with the time since the start

    if baseline is None:
        say("identifying the model without extra effects …")
        baseline = identify(recordings, options.fit, progress=progress)
    elif baseline.recordings != [str(r.path) for r in recordings]:
        raise RattlefitError(
            f"diagnose: the baseline fit is of {baseline.recordings}, not of "
            f"{[str(r.path) for r in recordings]}"
        )
    fit_options = baseline.options
    noise = baseline.noise
    rng = np.random.default_rng(fit_options.seed)
    problem, rigs = _build(recordings, fit_options, rng)  # the identification's realisations
    problem = dataclasses.replace(problem, sigma=jnp.asarray(np.stack(baseline.sigma)))
    data = np.asarray(problem.data)
    residuals = (data - np.stack(baseline.fitted_features)) / np.stack(baseline.sigma)
    n_final = options.n_final or fit_options.n_covariance_realisations
    y0_final = _release_states(
        problem, baseline.z, n_final, np.random.default_rng(fit_options.seed + 1)
    )
    dof = baseline.dof

    def whitened(mean: np.ndarray) -> np.ndarray:
        return noise.whiten @ ((data - mean) / np.asarray(problem.sigma)).reshape(-1)

    def residual_rows(prob, zs):
        mean = np.asarray(prob.mean_of(_evaluate(prob, zs)))
        return np.stack(
            [
                np.concatenate([whitened(mean[k]), prob.prior_rows(np.asarray(z))])
                for k, z in enumerate(zs)
            ]
        )

    def refit(prob, z, frozen):
        """``z`` after Gauss–Newton on the coordinates not ``frozen``."""
        if not options.iterations:
            return z
        steps = np.minimum(prob.fd_steps(np.asarray(z)), 1.0)[None]
        rows = functools.partial(residual_rows, prob)
        return polish_profile(rows, z[None], [frozen], steps, iterations=options.iterations)[0]

    # the effects are fitted with the free parameters (a, T_b), the nuisances stay put; so
    # that an effect is not credited with what re-fitting a and T_b alone gains, the model
    # without effects is re-fitted the same way first, from the same alternatives of a and
    # T_b that each effect's screening starts from (else an effect is credited with that
    # wider search: after a quick fit that had failed, χ² 1440 on 28 dof, run-out was the
    # verdict on a recording with withheld flank friction)
    nuisances = [i for i, sp in enumerate(problem.specs) if sp.log_sd is not None]
    say(
        f"re-fitting a and T_b without effects ({len(FREE_FACTORS)} starts, "
        f"{options.iterations} iterations) …"
    )
    starts = _free_alternatives(np.asarray(baseline.z, dtype=float), problem)
    cost = np.sum(residual_rows(problem, starts) ** 2, axis=1)  # row 0: the identification
    z_base = refit(problem, starts[int(np.argmin(cost))], nuisances)
    refit_cost = float(np.sum(residual_rows(problem, z_base[None]) ** 2))
    warnings = baseline_warnings(baseline.success, float(cost[0]), refit_cost)
    for w in warnings:
        say("  warning: " + w)

    level = options.significance / len(options.effects)  # Bonferroni over the effects tried
    outcomes = []
    for n, name in enumerate(options.effects):
        t0 = time.perf_counter()
        specs = effect_specs(name)
        prob = dataclasses.replace(problem, specs=problem.specs + specs, effect=absent(name))
        p0, d = len(problem.specs), len(specs)
        z_off = np.concatenate([z_base, np.full(d, -Z_END)])

        say(f"effect {n + 1}/{len(options.effects)}: {name} — screening (compiling first) …")
        starts = np.concatenate([z_off[None], _screen_points(z_off, specs, problem)])
        cost = np.sum(residual_rows(prob, starts) ** 2, axis=1)
        best = starts[1 + int(np.argmin(cost[1:]))]
        say(
            f"  {name}: cost {cost[0]:.1f} without, {cost.min():.1f} at the best start; "
            f"fitting it with a and T_b ({options.iterations} iterations) …"
        )
        best = refit(prob, best, nuisances)
        pair = np.stack([z_off, best])
        per = _evaluate(prob, pair, y0_final)
        mean = np.asarray(prob.mean_of(per))
        chi2 = [float(np.sum(whitened(mean[k]) ** 2)) for k in range(2)]
        delta = chi2[0] - chi2[1]
        # Monte Carlo noise of each χ² from n_final realisations (cf. fit's profile threshold)
        var = 4.0 * max(chi2[0], dof) / (n_final + 1) + 4.0 * max(chi2[1], dof) / (n_final + 1)
        threshold = 1.645 * math.sqrt(var)
        dof_with = max(dof - d, 1)
        f_stat = (delta / d) / max(chi2[1] / dof_with, 1e-12)
        p_value = float(stats.f.sf(f_stat, d, dof_with)) if delta > 0 else 1.0
        values = {
            s.name.split(".", 1)[1]: float(s.value(pair[1][p0 + j])) for j, s in enumerate(specs)
        }
        outcome = EffectOutcome(
            name=name,
            values=values,
            units={k: u for k, (u, _, _) in effect_class(name).ranges.items()},
            chi2_without=chi2[0],
            chi2_with=chi2[1],
            delta_chi2=delta,
            gap_closed=_gap_closed(chi2[0], chi2[1], dof),
            p_value=p_value,
            noise_threshold=threshold,
            supported=bool(p_value < level and delta > threshold),
            residuals=(data - mean[1]) / np.asarray(problem.sigma),
            wall_time=time.perf_counter() - t0,
        )
        say(
            f"  {name}: χ² {chi2[0]:.1f} → {chi2[1]:.1f} (p = {p_value:.2g}"
            f"{', supported' if outcome.supported else ''}) in {outcome.wall_time:.0f} s"
        )
        outcomes.append(outcome)
    outcomes.sort(key=lambda o: o.chi2_with)  # the least misfit left first (module docstring)
    bands = rigs[0].bands
    wall = time.perf_counter() - t_start
    say(f"done in {wall:.0f} s")
    return Diagnosis(
        baseline=baseline,
        residuals=residuals,
        band_centers=bands.centers,
        band_edges=bands.edges,
        outcomes=outcomes,
        seed=fit_options.seed,
        wall_time=wall,
        refit_costs=(float(cost[0]), refit_cost),
        warnings=tuple(warnings),
    )
