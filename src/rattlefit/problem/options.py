"""Options of :func:`~rattlefit.inference.identify.identify`: one flat, frozen
:class:`FitOptions`, checked at construction.

Its fields fall into six concerns, each checked by a function of its own: the ensemble (how
each evaluation simulates and averages realisations), the noise (the band weights), the search
(starts and Levenberg–Marquardt), the profile intervals, alternatives no default uses, and the
likelihood (synthetic or learned, and the learned one's budget); plus ``seed`` and ``priors``.
The same names are the result JSON's and the chain files' (:meth:`FitOptions.to_dict`,
:meth:`FitOptions.from_dict`) and ``--set FIELD=JSON``'s in the studies.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from ..errors import RattlefitError
from ..quantities import FILM
from .parameters import VISCOSITY, ParameterSpec, default_specs

#: The feature sets a fit can compare (``FitOptions.features``).
FEATURE_SETS = ("bands", "bands+folded")
#: How a fit's features are compared with the model (``FitOptions.likelihood``).
LIKELIHOODS = ("synthetic", "learned")


def check(ok: bool, message: str) -> None:
    """Raise :class:`~rattlefit.errors.RattlefitError` with ``message`` unless ``ok``."""
    if not ok:
        raise RattlefitError(message)


def check_choice(name: str, value: Any, allowed: tuple) -> None:
    """Raise unless option ``name``'s ``value`` is one of ``allowed``."""
    check(
        value in allowed,
        f"FitOptions.{name} must be one of {', '.join(map(repr, allowed))}, got {value!r}",
    )


def check_at_least(options, names, low: int, *, optional: bool = False) -> None:
    """Raise unless each option of ``names`` is at least ``low`` (or None, if ``optional``)."""
    for name in names:
        value = getattr(options, name)
        ok = (optional and value is None) or (value is not None and value >= low)
        check(ok, f"FitOptions.{name} must be ≥ {low}{' or None' if optional else ''}, got {value}")


def check_known(names) -> None:
    """Raise unless every one of ``names`` is an option (:data:`OPTION_NAMES`)."""
    unknown = sorted(set(names) - set(OPTION_NAMES))
    check(not unknown, f"FitOptions: unknown option(s) {', '.join(map(repr, unknown))}")


def check_ensemble(o: FitOptions) -> None:
    """The ensemble's options: counts, dither, tolerance, burn-in and the choices."""
    check_at_least(o, ("n_realisations", "n_noise_realisations", "n_covariance_realisations"), 2)
    check(o.dither >= 0, f"FitOptions.dither must be ≥ 0, got {o.dither}")
    check(0 < o.rtol < 1, f"FitOptions.rtol must lie in (0, 1), got {o.rtol}")
    check(o.burn_in >= 0, f"FitOptions.burn_in must be ≥ 0 s, got {o.burn_in}")
    check_choice("regime", o.regime, ("recording", "common"))
    check_choice("drive", o.drive, ("measured", "commanded"))
    check_choice("quantisation", o.quantisation, ("encoders", "white"))
    check_choice("features", o.features, FEATURE_SETS)


def check_noise(o: FitOptions) -> None:
    """The band weights: a positive floor, non-negative additions."""
    check(o.sigma_floor > 0, f"FitOptions.sigma_floor must be > 0, got {o.sigma_floor}")
    for name in ("floor_uncertainty", "model_discrepancy"):
        check(getattr(o, name) >= 0, f"FitOptions.{name} must be ≥ 0, got {getattr(o, name)}")


def check_search(o: FitOptions) -> None:
    """The search's starts and steps."""
    check_at_least(o, ("n_starts", "max_iterations"), 1, optional=True)
    check_at_least(o, ("start_realisations", "n_refine"), 1)


def check_profile(o: FitOptions) -> None:
    """The profile stage's rounds and screen."""
    rounds = ("profile_rounds", "profile_bisections", "profile_continuation", "profile_screen")
    check_at_least(o, rounds, 0)
    check_at_least(o, ("polish_iterations",), 1)


def check_experimental(o: FitOptions) -> None:
    """The alternatives no default uses."""
    check_at_least(o, ("nuisance_starts",), 0, optional=True)
    check_choice("screen", o.screen, ("mean", "nearest"))
    check_at_least(o, ("roughness_sets",), 1)
    check_at_least(o, ("recentre_rounds",), 0)


#: The fewest simulated recordings that set a 95 % critical value (below, it is their largest
#: statistic).
MIN_CALIBRATION = 20


def check_likelihood(o: FitOptions) -> None:
    """The likelihood's method and the learned one's budget."""
    check_choice("likelihood", o.likelihood, LIKELIHOODS)
    check_at_least(o, ("learning_initial",), 16)
    check_at_least(o, ("learning_rounds", "learning_refinements"), 0)
    check_at_least(o, ("learning_per_round",), 1)
    check_at_least(o, ("check_realisations",), 2)
    n = o.calibration_simulations
    check(
        n == 0 or n >= MIN_CALIBRATION,
        f"FitOptions.calibration_simulations must be 0 or ≥ {MIN_CALIBRATION}, got {n}",
    )


@dataclasses.dataclass(frozen=True, kw_only=True)
class FitOptions:
    """Options of :func:`~rattlefit.inference.identify.identify` (all have working defaults).
    Raises :class:`~rattlefit.errors.RattlefitError` naming the option for any invalid value.

    **The ensemble**: how each evaluation simulates the recordings and averages realisations.

    n_realisations : M, seeded realisations averaged per evaluation (released from different
        states in the gap; the same ones at every point: common random numbers). Default 6.
    n_noise_realisations : realisations that estimate each band's run-to-run spread during
        the search. Default 8.
    n_covariance_realisations : realisations of the Laplace covariance, the noise model and
        the profile stage. Default 24.
    dither : log-sd of each realisation's fixed, centred offsets of the film half-lengths and
        the drag torque (half of it for the viscosity). Averaging over a small neighbourhood
        makes the mean features, whose landscape is rough in chaotic rattle, well posed.
        Default 0.1.
    regime_threshold : realisations further than this from the ensemble median (mean squared
        robust z over the bands) are set aside as another regime; None keeps all. Default 9.
    regime : which regime the statistics describe where realisations split: ``"recording"``
        (the one the recording is in, when enough realisations reach it) or ``"common"``.
    rtol : relative tolerance of the simulator (absolute ones follow from it:
        :func:`~rattlefit.simulation.solve.absolute_tolerances`). Default 1e-5.
    drive : the primary wheel's motion: ``"measured"`` (a smooth fit to the primary encoder)
        or ``"commanded"`` (the recording's nominal fluctuation).
    quantisation : how simulations are measured: ``"encoders"`` (read through the two
        encoders like the rig, each realisation with its own count phases) or ``"white"``
        (eq. 8's white quantisation floor added to the PSD).
    burn_in : simulated seconds discarded before the features, as in
        :func:`~rattlefit.simulation.solve.simulate`. Default 0.5.
    features : what a recording and each simulation are compared by: ``"bands"`` (the log
        band PSDs of Δθ*) or ``"bands+folded"`` (those, then the drive-cycle-folded
        statistics of :mod:`rattlefit.features.folded`, each with its ensemble spread and
        correlations like a band). Default ``"bands"``.

    **The noise**: a recording's run-to-run spread and what is added to it (log10).

    sigma_floor : lower bound on a band's standard deviation. Default 0.03.
    floor_uncertainty : standard uncertainty of eq. (8)'s analytic quantisation floor, added
        to the bands it dominates. Default 0.
    model_discrepancy : standard deviation of the difference between this model and the rig
        at the same parameters, added to every band. Default 0 (a poor fit already widens
        the intervals by its reduced χ²).

    **The search**: seeded starts, then Levenberg–Marquardt from the best.

    n_starts : starting points over the film half-lengths and the drag torque (a scrambled
        Sobol' sequence in log over each one's ``ParameterSpec.start_range``); None:
        :data:`~rattlefit.inference.starts.START_POINTS`, twice as many per further film.
    start_realisations : realisations per start in the screening; the best starts are then
        re-evaluated with all of them. Default 2.
    n_refine : how many of the best starts Levenberg–Marquardt refines. Default 3.
    max_iterations : Levenberg–Marquardt steps per start; None:
        :data:`~rattlefit.inference.least_squares.LM_STEPS` per recording.

    **The profile intervals** (:mod:`rattlefit.inference.profile`).

    profile_rounds : rounds of re-optimising the other parameters at the values just outside
        each interval, each followed by another bisection of the ends. Default 1.
    polish_iterations : damped Gauss–Newton iterations per re-optimisation. Default 1.
    profile_bisections : rounds of bisecting each interval end's bracket where it is wide.
        Default 4.
    profile_continuation : rounds of following each profile past its ends, the other
        parameters predicted along the secant and re-optimised; 0 turns it off. Default 4.
    profile_valley : also guess the other parameters along the film's valley in
        (a, viscosity), the viscosity that keeps the squeeze coefficient at a few gaps near
        contact. Default True.
    profile_roughness : widen the threshold's noise allowance to the cost's measured spread
        1–2 % from the optimum, where it exceeds the analytic Monte Carlo allowance. Default
        True.
    profile_screen : realisations that cost a profile value first; the rest only where it is
        not already far above the threshold. 0 simulates all of them. Default 6.
    profile_group : also profile each boundary film's squeeze-film group, the squeeze film's
        momentum per approach (:mod:`rattlefit.inference.group`), what a boundary recording
        pins. Default True.

    **Alternatives that no default uses**, kept for studies; each is tested.

    nuisance_starts : further starts with every parameter that has a prior spread over its
        median × exp(± one log-sd); None: as many as ``n_starts``. Default 0 (none).
    screen : how a start is ranked from its few realisations: ``"mean"`` (default) or
        ``"nearest"`` (its realisation nearest the recording).
    roughness_sets : independent realisation sets that measure the profile roughness; with 2
        or more the allowance is their spread, not one set's rms. Default 1.
    recentre_rounds : times the covariance and profile stages may start again from the
        profiles' lowest point when it lies clearly below the optimum. Default 0.

    **The likelihood**, and the learned one's simulation budget.

    likelihood : ``"synthetic"`` (the mean of a few seeded realisations at each point,
        weighted by the band spread at the optimum) or ``"learned"`` (the features'
        distribution learned from simulations over the priors and the posterior,
        :mod:`rattlefit.likelihood`). Default ``"synthetic"``.
    learning_initial : simulations per recording of the learned likelihood's space-filling
        round. Default 1024.
    learning_rounds : further rounds drawn from the current posterior. Default 3.
    learning_per_round : simulations per recording in each further round. Default 512.
    check_realisations : simulations at the optimum and at each interval end that check the
        learned likelihood against the simulator. Default 24.
    learning_refinements : at most this many further rounds, each followed by a new fit and
        check, while the check fails. Default 2.
    calibration_simulations : recordings simulated near the learned fit's optimum that set
        each profile's critical value (:mod:`rattlefit.inference.critical`: intervals that
        hold their truth at their level even where the learned density is too narrow);
        0 cuts every profile at χ²₁'s 3.84. Default 200; at least 20 when not 0.
    reuse_likelihood : a stored learned likelihood of this test point (a file written by
        :func:`~rattlefit.likelihood.store.write_learned`, e.g. ``identify -o``'s
        ``*.likelihood.h5``) to start from instead of learning: only where its check against
        the simulator fails are further rounds simulated. Default None.

    **The rest.**

    seed : seeds every random draw of the fit (release states, dither, encoder phases,
        starts); reported in the result. Default 0.
    priors : parameter name → replacement :class:`~rattlefit.problem.parameters.ParameterSpec`
        (e.g. from ``--prior min_film=2e-6:0.1``). Default none.
    extra_parameters : more parameters to fit, each a
        :class:`~rattlefit.problem.parameters.ParameterSpec` that declares the model field it
        multiplies (``scales``), appended to the fit's vector. Default none.
    """

    n_realisations: int = 6
    n_noise_realisations: int = 8
    n_covariance_realisations: int = 24
    n_starts: int | None = None
    start_realisations: int = 2
    nuisance_starts: int | None = 0
    screen: str = "mean"
    n_refine: int = 3
    max_iterations: int | None = None
    sigma_floor: float = 0.03
    floor_uncertainty: float = 0.0
    model_discrepancy: float = 0.0
    profile_rounds: int = 1
    polish_iterations: int = 1
    profile_bisections: int = 4
    profile_continuation: int = 4
    profile_valley: bool = True
    profile_roughness: bool = True
    roughness_sets: int = 1
    profile_screen: int = 6
    profile_group: bool = True
    recentre_rounds: int = 0
    seed: int = 0
    rtol: float = 1e-5
    drive: str = "measured"
    quantisation: str = "encoders"
    burn_in: float = 0.5
    dither: float = 0.1
    regime_threshold: float | None = 9.0
    regime: str = "recording"
    features: str = "bands"
    likelihood: str = "synthetic"
    learning_initial: int = 1024
    learning_rounds: int = 3
    learning_per_round: int = 512
    check_realisations: int = 24
    learning_refinements: int = 2
    calibration_simulations: int = 200
    reuse_likelihood: str | None = None
    priors: dict = dataclasses.field(default_factory=dict)
    extra_parameters: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "seed", int(self.seed))
        object.__setattr__(self, "priors", dict(self.priors or {}))
        object.__setattr__(self, "extra_parameters", tuple(self.extra_parameters or ()))
        for check_concern in (
            check_ensemble,
            check_noise,
            check_search,
            check_profile,
            check_experimental,
            check_likelihood,
        ):
            check_concern(self)
        self._check_priors()
        self._check_extra_parameters()

    def _check_extra_parameters(self) -> None:
        known = {s.name for s in default_specs([], {})} | {VISCOSITY}
        for k, spec in enumerate(self.extra_parameters):
            where = f"FitOptions.extra_parameters[{k}]"
            check(isinstance(spec, ParameterSpec), f"{where}: expected a ParameterSpec")
            check(spec.name not in known, f"{where}: {spec.name!r} is a parameter already")
            check(
                spec.scales is not None and spec.role in ("physical", "nuisance"),
                f"{where}: {spec.name!r} must declare the model field it scales",
            )

    def _check_priors(self) -> None:
        known = {s.name for s in default_specs([], {})} | {VISCOSITY}  # but the backlashes
        for name, spec in self.priors.items():
            # a misspelt name would otherwise replace nothing, silently
            if not (name in known or name.startswith(("backlash[", f"{FILM}["))):
                raise RattlefitError(
                    f"FitOptions.priors: unknown parameter {name!r}; expected one of "
                    f"{', '.join(sorted(known))}, {FILM}[lubrication] or backlash[k]"
                )
            if not isinstance(spec, ParameterSpec) or spec.name != name:
                raise RattlefitError(
                    f"FitOptions.priors[{name!r}]: expected a ParameterSpec named {name!r}"
                )

    def replace(self, **changes) -> FitOptions:
        """A copy with ``changes`` (option name → value), checked again."""
        check_known(changes)
        return dataclasses.replace(self, **changes)

    @classmethod
    def quick(cls, **overrides) -> FitOptions:
        """A rough first look, several times cheaper than the defaults (:data:`QUICK`): fewer
        realisations, starts and iterations, a covariance from 8 realisations and the profile
        ends neither bisected nor re-optimised. Intervals are wider and less reliable."""
        return cls(**{**QUICK, **overrides})

    @classmethod
    def optimum_only(cls, **overrides) -> FitOptions:
        """The defaults with the profile stage cut to its coarse scan (:data:`OPTIMUM_ONLY`),
        for callers that need the optimum and noise model, not the intervals (diagnose)."""
        return cls(**{**OPTIMUM_ONLY, **overrides})

    def to_dict(self) -> dict:
        """Every option by its name, in the fields' order, priors as dicts."""
        out = {name: getattr(self, name) for name in OPTION_NAMES}
        out["priors"] = {k: dataclasses.asdict(v) for k, v in self.priors.items()}
        out["extra_parameters"] = [dataclasses.asdict(v) for v in self.extra_parameters]
        return out

    @classmethod
    def from_dict(cls, doc: dict) -> FitOptions:
        """The inverse of :meth:`to_dict`. Raises :class:`~rattlefit.errors.RattlefitError`
        naming an unknown option."""
        doc = dict(doc)
        priors = {k: ParameterSpec(**v) for k, v in doc.pop("priors", {}).items()}
        extra = tuple(ParameterSpec(**v) for v in doc.pop("extra_parameters", ()))
        check_known(doc)
        return cls(priors=priors, extra_parameters=extra, **doc)


def preset_of(options: dict) -> str:
    """Which preset ``options`` (:meth:`FitOptions.to_dict`, or a fit JSON's ``options``)
    were made with: ``"quick"`` (:data:`QUICK`), ``"optimum_only"`` (:data:`OPTIMUM_ONLY`) or
    ``"full"`` (the defaults, or any other choice)."""
    for name, preset in (("quick", QUICK), ("optimum_only", OPTIMUM_ONLY)):
        if all(options.get(k) == v for k, v in preset.items()):
            return name
    return "full"


def unfinished_fit_advice(options: dict) -> str:
    """What to run when a fit made with ``options`` (as :func:`preset_of` reads them) stopped
    at its step limit: a full fit after a quick one, else more iterations or another seed."""
    if preset_of(options) == "quick":
        return "a full identification (without --quick) is safer"
    steps = options.get("max_iterations", "its")
    return (
        f"the fit used all {steps} iterations of each search; more (FitOptions(max_iterations=…)) "
        "or another --seed may finish it"
    )


#: Every option's name, in the order result JSON and chain files use.
OPTION_NAMES: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(FitOptions))

#: The :meth:`FitOptions.quick` preset.
QUICK = dict(
    n_realisations=3,
    n_noise_realisations=6,
    n_covariance_realisations=8,
    n_starts=16,
    n_refine=1,
    max_iterations=3,
    profile_rounds=0,
    profile_bisections=0,
    profile_continuation=0,
    learning_initial=512,
    learning_rounds=2,
    learning_per_round=256,
    calibration_simulations=100,
)
#: The :meth:`FitOptions.optimum_only` preset.
OPTIMUM_ONLY = dict(
    profile_group=False,
    profile_rounds=0,
    profile_bisections=0,
    profile_continuation=0,
    profile_valley=False,
    profile_roughness=False,
    recentre_rounds=0,
)
