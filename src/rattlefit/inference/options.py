"""Options of :func:`~rattlefit.inference.identify.identify`, in groups.

:class:`FitOptions` holds five groups, each a frozen dataclass checked at construction:
:class:`EnsembleOptions` (how each evaluation simulates and averages realisations),
:class:`NoiseOptions` (the band weights), :class:`SearchOptions` (starts and
Levenberg–Marquardt), :class:`ProfileOptions` (the profile intervals) and
:class:`ExperimentalOptions` (alternatives that no default uses), plus ``seed`` and ``priors``.

The flat constructor keeps working: ``FitOptions(n_realisations=3, profile_rounds=0)`` routes
each keyword to its group (:data:`FLAT_FIELDS`), and every flat name is readable as an
attribute (``options.n_realisations``). Result JSON and chain files store the options flat
(:meth:`FitOptions.to_dict`, :meth:`FitOptions.from_dict`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from ..errors import RattlefitError
from ..quantities import FILM
from .parameters import ParameterSpec, default_specs


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise RattlefitError(message)


def _check_choice(group: str, name: str, value: Any, allowed: tuple) -> None:
    _check(
        value in allowed,
        f"FitOptions.{name} must be one of {', '.join(map(repr, allowed))}, got {value!r}"
        f" ({group})",
    )


#: The feature sets a fit can compare (``EnsembleOptions.features``).
FEATURE_SETS = ("bands", "bands+folded")


@dataclasses.dataclass(frozen=True)
class EnsembleOptions:
    """How each evaluation simulates the recordings and averages its realisations.

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
    """

    n_realisations: int = 6
    n_noise_realisations: int = 8
    n_covariance_realisations: int = 24
    dither: float = 0.1
    regime_threshold: float | None = 9.0
    regime: str = "recording"
    rtol: float = 1e-5
    drive: str = "measured"
    quantisation: str = "encoders"
    burn_in: float = 0.5
    features: str = "bands"

    def __post_init__(self):
        for name in ("n_realisations", "n_noise_realisations", "n_covariance_realisations"):
            value = getattr(self, name)
            _check(value >= 2, f"FitOptions.{name} must be ≥ 2, got {value}")
        _check(self.dither >= 0, f"FitOptions.dither must be ≥ 0, got {self.dither}")
        _check(0 < self.rtol < 1, f"FitOptions.rtol must lie in (0, 1), got {self.rtol}")
        _check(self.burn_in >= 0, f"FitOptions.burn_in must be ≥ 0 s, got {self.burn_in}")
        _check_choice("ensemble", "regime", self.regime, ("recording", "common"))
        _check_choice("ensemble", "drive", self.drive, ("measured", "commanded"))
        _check_choice("ensemble", "quantisation", self.quantisation, ("encoders", "white"))
        _check_choice("ensemble", "features", self.features, FEATURE_SETS)


@dataclasses.dataclass(frozen=True)
class NoiseOptions:
    """The band weights: a recording's run-to-run spread and what is added to it (log10).

    sigma_floor : lower bound on a band's standard deviation. Default 0.03.
    floor_uncertainty : standard uncertainty of eq. (8)'s analytic quantisation floor, added
        to the bands it dominates. Default 0.
    model_discrepancy : standard deviation of the difference between this model and the rig
        at the same parameters, added to every band. Default 0 (a poor fit already widens
        the intervals by its reduced χ²).
    """

    sigma_floor: float = 0.03
    floor_uncertainty: float = 0.0
    model_discrepancy: float = 0.0

    def __post_init__(self):
        _check(self.sigma_floor > 0, f"FitOptions.sigma_floor must be > 0, got {self.sigma_floor}")
        for name in ("floor_uncertainty", "model_discrepancy"):
            _check(getattr(self, name) >= 0, f"FitOptions.{name} must be ≥ 0")


@dataclasses.dataclass(frozen=True)
class SearchOptions:
    """The search for the optimum: seeded starts, then Levenberg–Marquardt from the best.

    n_starts : starting points over the film half-lengths and the drag torque (a scrambled
        Sobol' sequence in log over :data:`~rattlefit.inference.starts.START_RANGES`); None:
        :data:`~rattlefit.inference.starts.START_POINTS`, twice as many per further film.
    start_realisations : realisations per start in the screening; the best starts are then
        re-evaluated with all of them. Default 2.
    n_refine : how many of the best starts Levenberg–Marquardt refines. Default 3.
    max_iterations : Levenberg–Marquardt steps per start; None:
        :data:`~rattlefit.inference.least_squares.LM_STEPS` per recording.
    """

    n_starts: int | None = None
    start_realisations: int = 2
    n_refine: int = 3
    max_iterations: int | None = None

    def __post_init__(self):
        _check(
            self.n_starts is None or self.n_starts >= 1,
            f"FitOptions.n_starts must be ≥ 1 or None, got {self.n_starts}",
        )
        _check(
            self.start_realisations >= 1,
            f"FitOptions.start_realisations must be ≥ 1, got {self.start_realisations}",
        )
        _check(self.n_refine >= 1, f"FitOptions.n_refine must be ≥ 1, got {self.n_refine}")
        _check(
            self.max_iterations is None or self.max_iterations >= 1,
            f"FitOptions.max_iterations must be ≥ 1 or None, got {self.max_iterations}",
        )


@dataclasses.dataclass(frozen=True)
class ProfileOptions:
    """The profile intervals of the free parameters (:mod:`rattlefit.inference.profile`).

    rounds : rounds of re-optimising the other parameters at the values just outside each
        interval, each followed by another bisection of the ends. Default 1.
    polish_iterations : damped Gauss–Newton iterations per re-optimisation. Default 1.
    bisections : rounds of bisecting each interval end's bracket where it is wide. Default 4.
    continuation : rounds of following each profile past its ends, the other parameters
        predicted along the secant and re-optimised; 0 turns it off. Default 4.
    valley : also guess the other parameters along the film's valley in (a, viscosity), the
        viscosity that keeps the squeeze coefficient at a few gaps near contact. Default True.
    roughness : widen the threshold's noise allowance to the cost's measured spread 1–2 %
        from the optimum, where it exceeds the analytic Monte Carlo allowance. Default True.
    screen : realisations that cost a profile value first; the rest only where it is not
        already far above the threshold. 0 simulates all of them. Default 6.
    group : also profile each boundary film's squeeze-film group, the squeeze film's momentum
        per approach (:mod:`rattlefit.inference.group`), what a boundary recording pins.
        Default True.
    """

    rounds: int = 1
    polish_iterations: int = 1
    bisections: int = 4
    continuation: int = 4
    valley: bool = True
    roughness: bool = True
    screen: int = 6
    group: bool = True

    def __post_init__(self):
        for name in ("rounds", "bisections", "continuation", "screen"):
            _check(
                getattr(self, name) >= 0,
                f"FitOptions.profile_{name} must be ≥ 0, got {getattr(self, name)}",
            )
        _check(
            self.polish_iterations >= 1,
            f"FitOptions.polish_iterations must be ≥ 1, got {self.polish_iterations}",
        )


@dataclasses.dataclass(frozen=True)
class ExperimentalOptions:
    """Alternatives that no default uses, kept for studies (``benchmarks/``); each is tested.

    nuisance_starts : further starts with every parameter that has a prior spread over its
        median × exp(± one log-sd); None: as many as ``n_starts``. Default 0 (none).
    start_screen : how a start is ranked from its few realisations: ``"mean"`` (default) or
        ``"nearest"`` (its realisation nearest the recording).
    roughness_sets : independent realisation sets that measure the profile roughness; with 2
        or more the allowance is their spread, not one set's rms. Default 1.
    recentre_rounds : times the covariance and profile stages may start again from the
        profiles' lowest point when it lies clearly below the optimum. Default 0.
    """

    nuisance_starts: int | None = 0
    start_screen: str = "mean"
    roughness_sets: int = 1
    recentre_rounds: int = 0

    def __post_init__(self):
        _check(
            self.nuisance_starts is None or self.nuisance_starts >= 0,
            f"FitOptions.nuisance_starts must be ≥ 0 or None, got {self.nuisance_starts}",
        )
        _check_choice("experimental", "screen", self.start_screen, ("mean", "nearest"))
        _check(
            self.roughness_sets >= 1,
            f"FitOptions.roughness_sets must be ≥ 1, got {self.roughness_sets}",
        )
        _check(
            self.recentre_rounds >= 0,
            f"FitOptions.recentre_rounds must be ≥ 0, got {self.recentre_rounds}",
        )


#: How a fit's features are compared with the model (``LikelihoodOptions.method``).
LIKELIHOODS = ("synthetic", "learned")


@dataclasses.dataclass(frozen=True)
class LikelihoodOptions:
    """Which likelihood the fit uses, and the learned one's simulation budget.

    method : ``"synthetic"`` (the mean of a few seeded realisations at each point, weighted
        by the band spread at the optimum: the ensemble, noise, search and profile groups) or
        ``"learned"`` (the features' distribution learned from simulations over the priors
        and the posterior, :mod:`rattlefit.likelihood`). Default ``"synthetic"``.
    initial : simulations per recording of the learned likelihood's space-filling round.
        Default 1024.
    rounds : further rounds drawn from the current posterior. Default 3.
    per_round : simulations per recording in each further round. Default 512.
    check_realisations : simulations at the optimum and at each interval end that check the
        learned likelihood against the simulator. Default 24.
    refinements : at most this many further rounds, each followed by a new fit and check,
        while the check fails. Default 2.
    reuse : a stored learned likelihood of this test point (a file written by
        :func:`~rattlefit.likelihood.store.write_learned`, e.g. ``identify -o``'s
        ``*.likelihood.h5``) to start from instead of learning: only where its check against
        the simulator fails are further rounds simulated. Default None.
    """

    method: str = "synthetic"
    initial: int = 1024
    rounds: int = 3
    per_round: int = 512
    check_realisations: int = 24
    refinements: int = 2
    reuse: str | None = None

    def __post_init__(self):
        _check_choice("likelihood", "likelihood", self.method, LIKELIHOODS)
        _check(self.initial >= 16, f"FitOptions.learning_initial must be ≥ 16, got {self.initial}")
        _check(self.rounds >= 0, f"FitOptions.learning_rounds must be ≥ 0, got {self.rounds}")
        _check(
            self.per_round >= 1, f"FitOptions.learning_per_round must be ≥ 1, got {self.per_round}"
        )
        _check(
            self.refinements >= 0,
            f"FitOptions.learning_refinements must be ≥ 0, got {self.refinements}",
        )
        _check(
            self.check_realisations >= 2,
            f"FitOptions.check_realisations must be ≥ 2, got {self.check_realisations}",
        )


#: Each flat option name → (group, field), in the order result JSON and chain files use.
FLAT_FIELDS: dict[str, tuple[str, str]] = {
    "n_realisations": ("ensemble", "n_realisations"),
    "n_noise_realisations": ("ensemble", "n_noise_realisations"),
    "n_covariance_realisations": ("ensemble", "n_covariance_realisations"),
    "n_starts": ("search", "n_starts"),
    "start_realisations": ("search", "start_realisations"),
    "nuisance_starts": ("experimental", "nuisance_starts"),
    "screen": ("experimental", "start_screen"),
    "n_refine": ("search", "n_refine"),
    "max_iterations": ("search", "max_iterations"),
    "sigma_floor": ("noise", "sigma_floor"),
    "floor_uncertainty": ("noise", "floor_uncertainty"),
    "model_discrepancy": ("noise", "model_discrepancy"),
    "profile_rounds": ("profile", "rounds"),
    "polish_iterations": ("profile", "polish_iterations"),
    "profile_bisections": ("profile", "bisections"),
    "profile_continuation": ("profile", "continuation"),
    "profile_valley": ("profile", "valley"),
    "profile_roughness": ("profile", "roughness"),
    "roughness_sets": ("experimental", "roughness_sets"),
    "profile_screen": ("profile", "screen"),
    "profile_group": ("profile", "group"),
    "recentre_rounds": ("experimental", "recentre_rounds"),
    "seed": ("", "seed"),
    "rtol": ("ensemble", "rtol"),
    "drive": ("ensemble", "drive"),
    "quantisation": ("ensemble", "quantisation"),
    "burn_in": ("ensemble", "burn_in"),
    "dither": ("ensemble", "dither"),
    "regime_threshold": ("ensemble", "regime_threshold"),
    "regime": ("ensemble", "regime"),
    "features": ("ensemble", "features"),
    "likelihood": ("likelihood", "method"),
    "learning_initial": ("likelihood", "initial"),
    "learning_rounds": ("likelihood", "rounds"),
    "learning_per_round": ("likelihood", "per_round"),
    "check_realisations": ("likelihood", "check_realisations"),
    "learning_refinements": ("likelihood", "refinements"),
    "reuse_likelihood": ("likelihood", "reuse"),
    "priors": ("", "priors"),
}

_GROUPS = {
    "ensemble": EnsembleOptions,
    "noise": NoiseOptions,
    "search": SearchOptions,
    "profile": ProfileOptions,
    "experimental": ExperimentalOptions,
    "likelihood": LikelihoodOptions,
}

#: The :meth:`FitOptions.quick` preset, as flat options.
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
)
#: The :meth:`FitOptions.optimum_only` preset, as flat options.
OPTIMUM_ONLY = dict(
    profile_group=False,
    profile_rounds=0,
    profile_bisections=0,
    profile_continuation=0,
    profile_valley=False,
    profile_roughness=False,
    recentre_rounds=0,
)


@dataclasses.dataclass(frozen=True, init=False)
class FitOptions:
    """Options of :func:`~rattlefit.inference.identify.identify` (all have working defaults).

    ensemble : :class:`EnsembleOptions`, how evaluations simulate and average realisations.
    noise : :class:`NoiseOptions`, the band weights.
    search : :class:`SearchOptions`, the starts and Levenberg–Marquardt.
    profile : :class:`ProfileOptions`, the profile intervals.
    experimental : :class:`ExperimentalOptions`, alternatives no default uses.
    likelihood : :class:`LikelihoodOptions`, the synthetic or the learned likelihood; a
        method's name (``"learned"``) stands for its options with the default budget.
    seed : seeds every random draw of the fit (release states, dither, encoder phases,
        starts); reported in the result. Default 0.
    priors : parameter name → replacement :class:`~rattlefit.inference.parameters.ParameterSpec`
        (e.g. from ``--prior min_film=2e-6:0.1``). Default none.

    Flat keywords (:data:`FLAT_FIELDS`) may be given instead of, or besides, groups; a flat
    keyword overrides the same field of a group given with it. Raises
    :class:`~rattlefit.errors.RattlefitError` naming the option for any invalid value.
    """

    ensemble: EnsembleOptions
    noise: NoiseOptions
    search: SearchOptions
    profile: ProfileOptions
    experimental: ExperimentalOptions
    likelihood: LikelihoodOptions
    seed: int
    priors: dict

    def __init__(
        self,
        *,
        ensemble: EnsembleOptions | None = None,
        noise: NoiseOptions | None = None,
        search: SearchOptions | None = None,
        profile: ProfileOptions | None = None,
        experimental: ExperimentalOptions | None = None,
        likelihood: LikelihoodOptions | None = None,
        seed: int = 0,
        priors: dict | None = None,
        **flat,
    ):
        if isinstance(likelihood, str):  # FitOptions(likelihood="learned"), and to_dict's form
            likelihood = LikelihoodOptions(method=likelihood)
        given = dict(
            ensemble=ensemble,
            noise=noise,
            search=search,
            profile=profile,
            experimental=experimental,
            likelihood=likelihood,
        )
        updates: dict[str, dict] = {g: {} for g in _GROUPS}
        for key, value in flat.items():
            group, field = FLAT_FIELDS.get(key, (None, None))
            if not group:
                raise RattlefitError(
                    f"FitOptions: unknown option {key!r}; expected one of "
                    f"{', '.join(k for k in FLAT_FIELDS if k not in ('seed', 'priors'))}"
                )
            updates[group][field] = value
        for name, cls in _GROUPS.items():
            base = given[name] if given[name] is not None else cls()
            if not isinstance(base, cls):
                raise RattlefitError(f"FitOptions.{name} must be a {cls.__name__}")
            object.__setattr__(self, name, dataclasses.replace(base, **updates[name]))
        object.__setattr__(self, "seed", int(seed))
        object.__setattr__(self, "priors", dict(priors or {}))
        self._check_priors()

    def _check_priors(self) -> None:
        known = {s.name for s in default_specs([], {})}  # every name but the backlashes
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

    def __getattr__(self, name: str):
        # only called when normal lookup fails: the flat names
        group, field = FLAT_FIELDS.get(name, (None, None))
        if not group:
            raise AttributeError(f"FitOptions has no option {name!r}")
        return getattr(object.__getattribute__(self, group), field)

    def replace(self, **changes) -> FitOptions:
        """A copy with ``changes`` (group objects, ``seed``, ``priors`` or flat names)."""
        current = {name: getattr(self, name) for name in (*_GROUPS, "seed", "priors")}
        return FitOptions(**{**current, **changes})

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
        """Every option by its flat name (:data:`FLAT_FIELDS`'s order), priors as dicts."""
        out = {}
        for key, (group, field) in FLAT_FIELDS.items():
            value = getattr(self, field) if not group else getattr(getattr(self, group), field)
            out[key] = value
        out["priors"] = {k: dataclasses.asdict(v) for k, v in self.priors.items()}
        return out

    @classmethod
    def from_dict(cls, doc: dict) -> FitOptions:
        """The inverse of :meth:`to_dict`."""
        doc = dict(doc)
        priors = {k: ParameterSpec(**v) for k, v in doc.pop("priors", {}).items()}
        return cls(priors=priors, **doc)
