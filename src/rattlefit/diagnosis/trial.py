"""What every candidate's trial in a diagnosis shares, and how one effect is fitted and judged.

A :class:`Trial` is the identification's problem with every candidate effect added at its
absent end — one compiled program, so that the model without effects and each effect's fit
are simulated on the same realisations — with the identification's noise model and the
fresh release states of the out-of-sample comparison. The functions here cost points of
that problem (:func:`costs`), re-fit a few coordinates (:func:`refit`), refer a band misfit to
the fitted model's own simulated null (:func:`misfit_p`), and judge a fitted effect against
the model without effects (:func:`judge_effect`).

**The misfit's null.** A band χ² is referred to χ² on its degrees of freedom only where the
band spread and its correlations are exact and the features Gaussian. Nearly deterministic
rattle breaks both: on dry flanks or in a periodic orbit the spread estimated at the
identification's optimum is far from the spread at another point, and realisations switch
between regimes. So the null is simulated: one recording of the model at the point judged per
release state of ``Trial.null_y0`` (the recordings' drive, dither and encoders), each scored
exactly as the recording is — its band χ² against the mean of the comparison's fresh
realisations in its own regime, whitened by the identification's noise model
(:func:`misfit_null`) — and the recording's χ² is set against these by
:func:`~rattlefit.diagnosis.null.null_p` (:func:`misfit_p`). The recording's χ² is taken at a
fitted point and the null's are not, so the null is a little larger than that of a re-fitted
recording: a misfit is rejected a little less often than the level says.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy import stats

from ..confidence import Z95_ONE_SIDED
from ..features.ensemble import regime_weights, weighted_mean
from ..inference.profile import polish_profile
from ..io.recording import Recording
from ..likelihood.noise import NoiseModel
from ..physics.effects import absent, effect_class
from ..problem.forward import evaluate
from ..problem.parameters import Z_END, ParameterSpec
from ..problem.problem import Problem
from .null import null_p
from .outcome import EffectOutcome, gap_closed
from .policy import effects_of, is_pair

#: One-sided 95 % quantile of the standard normal (the χ² drop's Monte Carlo allowance).
#: The re-fit without effects stops once two iterations lower its cost by less than this
#: share (:func:`settled_path`).
BASE_TOLERANCE = 0.02


@dataclasses.dataclass(frozen=True)
class Trial:
    """What every effect's trial shares.

    problem : the identification's problem (its realisations and band spread) with every
        candidate effect added at its absent end: one compiled program, so that the model
        without effects and each effect's fit are the same realisations.
    noise, data, dof : the identification's noise model, measured features (R, B) and
        degrees of freedom.
    y0 : fresh release states of the final comparison.
    validation : release states (the fit's covariance count, from another seed) that
        choose between the re-fits of the model without effects; never used to judge.
    iterations : Gauss–Newton iterations per effect's fit.
    nuisances : the coordinates with a prior (viscosity and stiffness scales, h_min, the
        backlashes). One re-fit of the model without effects moves them, with their prior
        rows; an effect's fit holds them at the chosen re-fit's values, so that an effect is
        credited only with what a plausible shift of the nuisances cannot explain.
    candidates : each effect's coordinates in ``problem``.
    dry : the film coordinates of dry recordings, never re-fitted: held at their dry end
        (dry flanks have no oil film, and a film fitted to them would absorb dissipation
        that is in the contact).
    base_iterations : most Gauss–Newton iterations of the re-fit without effects over the
        nuisances (:func:`settled_path`).
    null_y0 : release states (R, n, 2) of the misfit's simulated null (:func:`misfit_null`);
        None refers misfits to the χ² tail instead.
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
    base_iterations: int = 12
    validation: np.ndarray | None = None
    null_y0: np.ndarray | None = None

    def dried(self, zs: np.ndarray) -> np.ndarray:
        """``zs`` (…, P) with the dry recordings' film half-lengths at their dry end."""
        zs = np.array(zs, dtype=float, copy=True)
        zs[..., self.dry] = -Z_END
        return zs

    def fields(self, name: str) -> list[int]:
        """Coordinates of effect ``name``, or of every effect of ``"<effect>+<effect>"``."""
        return [i for n in effects_of(name) for i in self.candidates[n]]

    def held(self, name: str | None = None, *, nuisances: bool = True) -> list[int]:
        """Coordinates held fixed in a fit of effect ``name`` (None: of no effect; ``"a+b"``:
        of two together): the dry films, the nuisances (unless ``nuisances`` is False) and
        every other effect's fields."""
        fitted = set(self.fields(name)) if name else set()
        others = [i for idx in self.candidates.values() for i in idx if i not in fitted]
        return sorted(set(self.dry + (self.nuisances if nuisances else []) + others))


def whitened(trial: Trial, observed, mean) -> np.ndarray:
    """Band features ``observed`` (R, B) against the mean features ``mean`` (R, B), whitened
    by the identification's noise model: (R·B,)."""
    sigma = np.asarray(trial.problem.sigma)
    return trial.noise.whiten @ ((np.asarray(observed) - mean) / sigma).reshape(-1)


def whitened_rows(trial: Trial, mean: np.ndarray) -> np.ndarray:
    """The identification's whitened data rows for mean features ``mean`` (R, B)."""
    return whitened(trial, trial.data, mean)


def residual_rows(trial: Trial, zs, realisations=None) -> np.ndarray:
    """Whitened data rows and prior rows at each point of ``zs``: (K, n); ``realisations``
    (indices into the fit's) averages only those."""
    problem = trial.problem
    mean = np.asarray(problem.mean_of(evaluate(problem, zs, realisations=realisations)))
    return np.stack(
        [
            np.concatenate([whitened_rows(trial, mean[k]), problem.prior_rows(np.asarray(z))])
            for k, z in enumerate(zs)
        ]
    )


def costs(trial: Trial, zs, realisations=None) -> np.ndarray:
    """The fit's cost (data and prior rows) at each point of ``zs``; +inf where a
    simulation failed (a non-finite feature)."""
    cost = np.sum(residual_rows(trial, zs, realisations) ** 2, axis=1)
    return np.where(np.isfinite(cost), cost, np.inf)


def refit_steps(trial: Trial, zs) -> np.ndarray:
    """Finite-difference steps (K, P) of the re-fits from the points ``zs`` (K, P)."""
    return np.stack([np.minimum(trial.problem.fd_steps(np.asarray(z)), 1.0) for z in zs])


def refit_all(trial: Trial, zs, held: list[int], *, iterations: int | None = None) -> np.ndarray:
    """Each point of ``zs`` (K, P) after ``iterations`` (default ``trial.iterations``) of
    damped Gauss–Newton on the coordinates not in ``held``, all K in one batch of
    simulations: (K, P)."""
    iterations = trial.iterations if iterations is None else iterations
    zs = np.asarray(zs, dtype=float)
    if not iterations:
        return zs
    rows = functools.partial(residual_rows, trial)
    steps = refit_steps(trial, zs)
    return polish_profile(rows, zs, [held] * len(zs), steps, iterations=iterations)


def refit(trial: Trial, z, held: list[int], *, iterations: int | None = None) -> np.ndarray:
    """``z`` after ``iterations`` (default ``trial.iterations``) of damped Gauss–Newton on
    the coordinates not in ``held`` (:func:`refit_all` of one point)."""
    return refit_all(trial, np.asarray(z)[None], held, iterations=iterations)[0]


def settled_path(
    trial: Trial, z, held: list[int], *, iterations: int, tolerance: float = BASE_TOLERANCE
) -> np.ndarray:
    """The points (K, P) of a re-fit of ``z`` on the coordinates not in ``held``
    (:func:`refit`) after every two Gauss–Newton iterations, until the fit's cost drops by
    less than the share ``tolerance`` over two, or after ``iterations`` in all."""
    cost = float(costs(trial, np.asarray(z)[None])[0])
    path = []
    for _ in range(0, iterations, 2):
        z = refit(trial, z, held, iterations=2)
        path.append(z)
        new = float(costs(trial, z[None])[0])
        settled = new > (1.0 - tolerance) * cost
        cost = new
        if settled:
            break
    return np.stack(path) if path else np.asarray(z)[None]


def fresh_features(trial: Trial, zs, y0=None, *, problem: Problem | None = None) -> np.ndarray:
    """Features (K, R, M, B) at the points ``zs`` of each of the fresh release states (or of
    ``y0``, (R, M, 2)) by ``problem`` (default ``trial.problem``). More states than the
    problem has dither offsets are simulated in parts, each part with the offsets from the
    first on."""
    problem = trial.problem if problem is None else problem
    y0 = np.asarray(trial.y0 if y0 is None else y0)
    part = np.asarray(problem.dither).shape[0]
    pieces = [evaluate(problem, zs, y0[:, i : i + part]) for i in range(0, y0.shape[1], part)]
    return np.concatenate(pieces, axis=2)


def fresh_means(trial: Trial, zs, y0=None) -> np.ndarray:
    """Mean features (K, R, B) at the points ``zs`` on the fresh release states (or on
    ``y0``), in the recording's regime (:meth:`~rattlefit.problem.problem.Problem.mean_of`)."""
    return np.asarray(trial.problem.mean_of(fresh_features(trial, zs, y0)))


def chi2s(trial: Trial, zs, y0=None) -> np.ndarray:
    """χ² of the data rows at each point of ``zs`` on the fresh release states (or on
    ``y0``): (K,)."""
    means = fresh_means(trial, zs, y0)
    return np.array([np.sum(whitened_rows(trial, m) ** 2) for m in means])


def validated(trial: Trial, zs) -> tuple[int, np.ndarray]:
    """Which of the points ``zs`` (K, P) has the lowest χ² on the validation release states
    (``trial.validation``; the fresh states when there are none), and the K values (+inf where
    a simulation failed). A fit on the few realisations of the search can settle where a
    rare regime of those few happens to match the recording; points are chosen out of
    sample, and judged on yet other states (:func:`judge_effect`)."""
    values = chi2s(trial, np.asarray(zs, dtype=float), trial.validation)
    values = np.where(np.isfinite(values), values, np.inf)
    return int(np.argmin(values)), values


def final_chi2(trial: Trial, z, fresh=None) -> tuple[float, np.ndarray]:
    """χ² of the data rows at ``z`` on the fresh release states, and the mean features;
    ``fresh`` (R, M, B) are the fresh realisations' features at ``z`` if already simulated."""
    if fresh is None:
        fresh = fresh_features(trial, np.asarray(z)[None])[0]
    mean = np.asarray(trial.problem.mean_of(np.asarray(fresh)))
    return float(np.sum(whitened_rows(trial, mean) ** 2)), mean


def misfit_nulls(trial: Trial, zs, fresh=None) -> np.ndarray:
    """χ² (K, n) of the null recordings of the model at each point of ``zs`` (K, P), one per
    release state of ``trial.null_y0`` (R, n, 2), each against the mean of that point's fresh
    realisations ``fresh`` (K, R, M, B; simulated when None) in the regime that recording is
    in (module docstring). Every point's null recordings are simulated in one batch."""
    zs = np.asarray(zs, dtype=float)
    fresh = np.asarray(fresh_features(trial, zs) if fresh is None else fresh)
    null = np.asarray(fresh_features(trial, zs, trial.null_y0))
    return np.stack([null_chi2s(trial, f, n) for f, n in zip(fresh, null, strict=True)])


def null_chi2s(trial: Trial, fresh, null) -> np.ndarray:
    """χ² (n,) of the null recordings ``null`` (R, n, B) of one point, each against the mean
    of the point's fresh realisations ``fresh`` (R, M, B) in its own regime."""
    problem = trial.problem
    nb = problem.n_bands
    out = []
    for m in range(null.shape[1]):
        target = null[:, m, :nb] if problem.recording_regime else None
        weights = regime_weights(fresh[..., :nb], problem.regime_threshold, target=target)
        mean = weighted_mean(fresh, np.asarray(weights))
        out.append(float(np.sum(whitened(trial, null[:, m], mean) ** 2)))
    return np.array(out)


def misfit_null(trial: Trial, z, fresh=None) -> np.ndarray:
    """:func:`misfit_nulls` of the one point ``z`` (P,), with its fresh features ``fresh``
    (R, M, B) if given: (n,)."""
    fresh = None if fresh is None else np.asarray(fresh)[None]
    return misfit_nulls(trial, np.asarray(z, dtype=float)[None], fresh)[0]


def misfit_ps(trial: Trial, zs, observed, dof: int, fresh=None) -> np.ndarray:
    """p (K,) of each band χ² ``observed`` (K,) at its point of ``zs`` (K, P) under the model
    there: :func:`misfit_nulls` (with ``fresh``, (K, R, M, B)) and
    :func:`~rattlefit.diagnosis.null.null_p`; without null release states (``trial.null_y0``
    None), the χ² tail on ``dof``. NaN where no null recording could be simulated."""
    observed = np.asarray(observed, dtype=float)
    if trial.null_y0 is None:
        return stats.chi2.sf(observed, dof)
    nulls = misfit_nulls(trial, zs, fresh)
    return np.array([null_p_of(o, null) for o, null in zip(observed, nulls, strict=True)])


def null_p_of(observed: float, null: np.ndarray) -> float:
    """:func:`~rattlefit.diagnosis.null.null_p` of ``observed`` against the finite values of
    ``null``; NaN when there are none."""
    null = null[np.isfinite(null)]
    return null_p(observed, null) if null.size else float("nan")


def misfit_p(trial: Trial, z, observed: float, dof: int, fresh=None) -> float:
    """:func:`misfit_ps` of the one point ``z`` (P,) and its χ² ``observed``, with its fresh
    features ``fresh`` (R, M, B) if given."""
    fresh = None if fresh is None else np.asarray(fresh)[None]
    zs = np.asarray(z, dtype=float)[None]
    return float(misfit_ps(trial, zs, np.array([observed]), dof, fresh)[0])


def difference_sd(trial: Trial, chi2_a: float, chi2_b: float, dof: int | None = None) -> float:
    """Monte Carlo standard deviation of the difference of two χ²s on ``dof`` degrees of
    freedom (default ``trial.dof``), each from the ``trial.y0`` fresh realisations (cf. the
    profile threshold)."""
    n, dof = trial.y0.shape[1], trial.dof if dof is None else dof
    return math.sqrt(4.0 * max(chi2_a, dof) / (n + 1) + 4.0 * max(chi2_b, dof) / (n + 1))


def f_test(delta: float, d: int, chi2_with: float, dof_with: int) -> float:
    """p of an F-test of a χ² drop ``delta`` from ``d`` extra fields against the misfit
    ``chi2_with`` left on ``dof_with`` degrees of freedom (1 when nothing dropped)."""
    if delta <= 0:
        return 1.0
    f_stat = (delta / d) / max(chi2_with / dof_with, 1e-12)
    return float(stats.f.sf(f_stat, d, dof_with))


def judge_effect(
    trial: Trial, name: str, chi2_without: float, z_fit, level: float
) -> EffectOutcome:
    """The effect's outcome: χ² with it on the fresh realisations against ``chi2_without``
    (the same realisations without any effect), the F-test at ``level``, the Monte Carlo
    noise of the drop, and the p of the misfit it leaves under the model with it
    (:func:`misfit_p`)."""
    d = len(trial.fields(name))
    fresh = fresh_features(trial, np.asarray(z_fit)[None])[0]
    chi2_with, mean = final_chi2(trial, z_fit, fresh)
    if not np.isfinite(chi2_with):
        return failed_outcome(trial, name, chi2_without, z_fit)
    delta = chi2_without - chi2_with
    dof = trial.dof
    threshold = Z95_ONE_SIDED * difference_sd(trial, chi2_without, chi2_with)
    dof_with = max(dof - d, 1)
    p_value = f_test(delta, d, chi2_with, dof_with)
    return EffectOutcome(
        name=name,
        values=effect_values(trial, name, z_fit),
        units=effect_units(trial, name),
        chi2_without=chi2_without,
        chi2_with=chi2_with,
        delta_chi2=delta,
        gap_closed=gap_closed(chi2_without, chi2_with, dof),
        p_value=p_value,
        noise_threshold=threshold,
        supported=bool(p_value < level and delta > threshold),
        residuals=(trial.data - mean) / np.asarray(trial.problem.sigma),
        wall_time=0.0,
        p_after=misfit_p(trial, z_fit, chi2_with, dof_with, fresh),
    )


def field_key(trial: Trial, name: str, i: int) -> str:
    """The key of coordinate ``i`` in effect ``name``'s values: its field (``"amplitude"``),
    or, for two effects together, ``"<effect>.<field>"``."""
    spec_name = trial.problem.specs[i].name
    return spec_name if is_pair(name) else spec_name.split(".", 1)[1]


def effect_values(trial: Trial, name: str, z) -> dict[str, float]:
    """Effect ``name``'s fields at ``z``: key (:func:`field_key`) → value (SI)."""
    return {
        field_key(trial, name, i): float(trial.problem.specs[i].value(z[i]))
        for i in trial.fields(name)
    }


def effect_units(trial: Trial, name: str) -> dict[str, str]:
    """Effect ``name``'s fields: key (:func:`field_key`) → unit."""
    return {field_key(trial, name, i): trial.problem.specs[i].unit for i in trial.fields(name)}


def failed_outcome(trial: Trial, name: str, chi2_without: float, z_fit) -> EffectOutcome:
    """The outcome of an effect whose simulation failed at its fitted point (non-finite
    features on the fresh realisations): never supported, with the reason."""
    return EffectOutcome(
        name=name,
        values=effect_values(trial, name, z_fit),
        units=effect_units(trial, name),
        chi2_without=chi2_without,
        chi2_with=float("nan"),
        delta_chi2=float("nan"),
        gap_closed=0.0,
        p_value=float("nan"),
        noise_threshold=float("nan"),
        supported=False,
        residuals=np.full(np.shape(trial.data), np.nan),
        wall_time=0.0,
        p_after=float("nan"),
        failure="its simulation failed at the fitted size (non-finite features); "
        "the size is at or beyond what the solver can integrate",
    )


def moves(trial: Trial, z_base, z_fit) -> dict[str, tuple[float, float]]:
    """How the parameters the effect is fitted with (the film half-lengths, the drag
    torque) move once it is in: name → (without, with), SI units. A base-model estimate that
    the effect moves far was biased by its absence."""
    effect_coords = {i for idx in trial.candidates.values() for i in idx}
    out = {}
    for i, spec in enumerate(trial.problem.specs):
        if i in effect_coords or i in trial.nuisances or i in trial.dry:
            continue
        out[spec.name] = (float(spec.value(z_base[i])), float(spec.value(z_fit[i])))
    return out


def effect_specs(name: str) -> tuple[ParameterSpec, ...]:
    """The fitted fields of effect ``name`` as
    :class:`~rattlefit.problem.parameters.ParameterSpec` objects named ``"<effect>.<field>"`` (no
    prior: log-uniform over the range)."""
    return tuple(
        ParameterSpec(f"{name}.{field}", unit, lo, hi, fd_log_step=0.3, role="effect")
        for field, (unit, lo, hi) in effect_class(name).ranges.items()
    )


def candidate_problem(
    problem: Problem, names, static: Mapping[str, dict] | None = None
) -> tuple[Problem, dict[str, list[int]]]:
    """``problem`` with every effect in ``names`` added at its absent end (with the static
    fields ``static[name]``, e.g. the order a drive-ripple test found), and each effect's
    coordinates."""
    specs, candidates = list(problem.specs), {}
    for name in names:
        extra = effect_specs(name)
        candidates[name] = list(range(len(specs), len(specs) + len(extra)))
        specs += extra
    static = static or {}
    effects = tuple(absent(name, **static.get(name, {})) for name in names)
    return dataclasses.replace(problem, specs=tuple(specs), effects=effects), candidates


def dry_films(problem: Problem, recordings: Sequence[Recording]) -> list[int]:
    """Coordinates of the film half-lengths that only dry recordings use."""
    lubrication = [r.operating.lubrication for r in recordings]
    wet = {f for f, lub in zip(problem.films, lubrication, strict=True) if lub != "dry"}
    dry = {f for f in problem.films} - wet
    return [i for i, sp in enumerate(problem.specs) if sp.name in dry]
