"""The fitted parameters: their coordinates, ranges, priors and roles.

Every parameter :func:`~rattlefit.inference.fit.identify` fits is a :class:`ParameterSpec`: a range
``(lower, upper)`` in SI units, mapped from an unconstrained coordinate ``z`` by
``lower · (upper/lower)^sigmoid(z)`` (positive and bounded without clipping), an optional
log-normal prior, and a role (:data:`ROLES`): *physical* (what the fit is for: profiled, its
range's lower end standing for zero), *nuisance* (fitted with its prior, not profiled),
*group* (the squeeze-film momentum that replaces a film's coordinate while it is profiled) or
*effect* (a diagnosis candidate's field). A prior does not make a parameter a nuisance:
``--prior drag_torque=0.025:0.3`` keeps the drag torque physical. :func:`default_specs` lists
them for a set of recordings: one film half-length per lubrication, the drag torque, the
viscosity and stiffness factors, ``h_min``, and each recording's backlash within its
measurement uncertainty; :func:`parameter_prior` and :func:`parse_prior` give one a prior.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
from scipy.special import expit

from ..errors import RattlefitError
from ..physics.model import DEFAULT_MIN_FILM, PARAM_UNITS
from ..quantities import (
    DRAG_TORQUE,
    FILM,
    MIN_FILM,
    MOMENTUM,
    QUANTITIES,
    STIFFNESS_SCALE,
    VISCOSITY,
    VISCOSITY_SCALE,
    base_name,
    quantity,
)
from ..util import array_namespace

if TYPE_CHECKING:
    from ..rig import RigSetup

#: The roles a parameter can have (see the module notes).
ROLES = ("physical", "nuisance", "group", "effect")

#: Range ends of the unconstrained coordinate (sigmoid(±8) is within 3.4e-4 of the end:
#: a = 1.003 µm, for instance).
Z_END = 8.0


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """One fitted parameter: its range, optional log-normal prior, finite-difference step and
    role.

    The value is ``lower · (upper/lower)^sigmoid(z)``. With ``center`` and ``log_sd`` the
    residual gets the prior row ``(log v − log center) / log_sd``. ``role`` is one of
    :data:`ROLES`; left empty, a parameter with a prior is a nuisance and one without is
    physical. ``scales`` names the :class:`~rattlefit.physics.model.RattleParams` field the
    parameter multiplies, for a factor (``viscosity_scale`` scales ``viscosity``); how the
    others reach the model is :meth:`~rattlefit.problem.space.ParameterSpace.rattle_params`.
    ``unit`` is SI, the registry's (:mod:`rattlefit.quantities`) for a name it knows.
    ``start_range`` (lower, upper) is where the fit's starts spread a physical parameter
    (log-uniformly; None: its whole range); ``dither`` is the weight of the realisations'
    log-offsets of it (``FitOptions.dither`` × this × N(0, 1); None: not dithered). Raises
    :class:`~rattlefit.errors.RattlefitError` for an empty range, an unknown role, a unit the
    registry contradicts or an unknown ``scales``.
    """

    name: str
    unit: str
    lower: float
    upper: float
    center: float | None = None
    log_sd: float | None = None
    fd_log_step: float = 0.15
    role: str = ""
    scales: str | None = None
    start_range: tuple[float, float] | None = None
    dither: float | None = None

    def __post_init__(self):
        if self.start_range is not None:
            object.__setattr__(self, "start_range", tuple(map(float, self.start_range)))
        if not (0 < self.lower < self.upper):
            raise RattlefitError(f"parameter {self.name}: need 0 < lower < upper")
        known = QUANTITIES.get(base_name(self.name))
        if known is not None and known.unit != self.unit:
            raise RattlefitError(
                f"parameter {self.name}: unit {self.unit!r}, but {known.name} is in {known.unit!r}"
            )
        if self.scales is not None and self.scales not in PARAM_UNITS:
            raise RattlefitError(
                f"parameter {self.name}: scales {self.scales!r}, which is not one of "
                f"{', '.join(PARAM_UNITS)}"
            )
        if not self.role:
            object.__setattr__(self, "role", "nuisance" if self.log_sd is not None else "physical")
        if self.role not in ROLES:
            raise RattlefitError(
                f"parameter {self.name}: role {self.role!r} is not one of {', '.join(ROLES)}"
            )

    @property
    def nuisance(self) -> bool:
        """Fitted with its prior and not profiled (:data:`ROLES`)."""
        return self.role == "nuisance"

    @property
    def log_range(self) -> float:
        return math.log(self.upper / self.lower)

    def value(self, z):
        xp = array_namespace(z)
        return self.lower * xp.exp(self.log_range * _sigmoid(z))

    def z_of(self, value: float) -> float:
        u = (math.log(value) - math.log(self.lower)) / self.log_range
        u = min(max(u, 1e-6), 1 - 1e-6)
        return math.log(u / (1 - u))

    def dlog_dz(self, z):
        """d(log value)/dz: converts a step in log value into a step in z."""
        s = _sigmoid(z)
        return self.log_range * s * (1 - s)


def _sigmoid(z):
    """The logistic function, in JAX while ``z`` is traced, else in numpy (scipy's expit)."""
    return jax.nn.sigmoid(z) if array_namespace(z) is jnp else expit(z)


def film_names(lubrications: Sequence[str]) -> tuple[str, ...]:
    """The name of the film half-length each recording uses: ``film_half_length`` when all
    share one lubrication, else ``film_half_length[<lubrication>]`` (one per lubrication)."""
    if len(set(lubrications)) <= 1:
        return (FILM,) * len(lubrications)
    return tuple(f"{FILM}[{lub}]" for lub in lubrications)


def momentum_name(film: str) -> str:
    """The squeeze-film group's name for the film half-length ``film``:
    ``film_half_length`` → ``squeeze_momentum``, ``film_half_length[boundary]`` →
    ``squeeze_momentum[boundary]``."""
    return MOMENTUM + film[len(FILM) :]


def films_of(rigs: Sequence[RigSetup]) -> tuple[str, ...]:
    """:func:`film_names` of the rigs' recordings."""
    return film_names([rig.recording.operating.lubrication for rig in rigs])


#: Where the fit's starts spread each film half-length and the drag torque (m, N m).
FILM_STARTS = (5e-6, 2e-3)
DRAG_STARTS = (5e-3, 0.2)


def default_specs(rigs: Sequence[RigSetup], priors: dict) -> tuple[ParameterSpec, ...]:
    """The fitted parameters with their prior ranges (SI units); ``priors`` replaces by name.

    A fit across lubrications has one film half-length per lubrication (:func:`film_names`,
    in the order the lubrications first appear); everything else but the backlashes is
    shared.
    """
    films = films_of(rigs) or (FILM,)
    film = {"fd_log_step": 0.2, "role": "physical", "start_range": FILM_STARTS, "dither": 1.0}
    specs = [
        *(ParameterSpec(n, "m", 1e-6, 5e-3, **film) for n in dict.fromkeys(films)),
        ParameterSpec(
            DRAG_TORQUE,
            "N m",
            2e-3,
            0.5,
            fd_log_step=0.15,
            role="physical",
            start_range=DRAG_STARTS,
            dither=1.0,
        ),
        ParameterSpec(
            VISCOSITY_SCALE,
            "1",
            0.2,
            5.0,
            center=1.0,
            log_sd=0.25,
            fd_log_step=0.15,
            scales=VISCOSITY,
            dither=0.5,
        ),
        ParameterSpec(
            STIFFNESS_SCALE,
            "1",
            0.3,
            3.0,
            center=1.0,
            log_sd=0.3,
            fd_log_step=0.15,
        ),
        ParameterSpec(
            MIN_FILM, "m", 0.5e-6, 20e-6, center=DEFAULT_MIN_FILM, log_sd=0.7, fd_log_step=0.2
        ),
    ]
    for k, rig in enumerate(rigs):
        b = rig.geometry.backlash
        sd = rig.geometry.backlash_std or 0.01 * b
        rel = max(sd / b, 2e-3)
        specs.append(
            ParameterSpec(
                f"backlash[{k}]",
                "m",
                b * (1 - 6 * rel),
                b * (1 + 6 * rel),
                center=b,
                log_sd=rel,
                fd_log_step=min(0.15, 1.5 * rel),
            )
        )
    if VISCOSITY in priors and rigs:
        priors = {**priors, VISCOSITY_SCALE: viscosity_prior(priors[VISCOSITY], rigs[0])}
    return tuple(with_defaults(priors[s.name], s) if s.name in priors else s for s in specs)


def with_defaults(spec: ParameterSpec, default: ParameterSpec) -> ParameterSpec:
    """``spec`` (a prior given by the user) with ``default``'s start range and dither where
    it leaves them unset."""
    return dataclasses.replace(
        spec,
        start_range=spec.start_range or default.start_range,
        dither=default.dither if spec.dither is None else spec.dither,
    )


#: The nuisance parameters: the recording-independent parameters of :func:`default_specs`
#: that are fitted with a prior and not profiled.
NUISANCES = tuple(s.name for s in default_specs([], {}) if s.nuisance)
#: Every name a prior can be given under (:func:`parameter_prior`): the physical parameters
#: (a film half-length, also as ``film_half_length[lubrication]``), the viscosity in Pa s
#: and the nuisances.
PRIORABLE = (FILM, DRAG_TORQUE, VISCOSITY, *NUISANCES)


def viscosity_prior(spec: ParameterSpec, rig: RigSetup) -> ParameterSpec:
    """A prior on the viscosity in Pa s (``spec``, named :data:`VISCOSITY`) as the prior of
    the factor ``viscosity_scale`` on the oil's μ at ``rig``'s oil temperature."""
    (scale,) = (s for s in default_specs([], {}) if s.name == VISCOSITY_SCALE)
    return dataclasses.replace(scale, center=spec.center / rig.viscosity, log_sd=spec.log_sd)


def parameter_prior(name: str, center: float, log_sd: float) -> ParameterSpec:
    """Parameter ``name`` (one of :data:`PRIORABLE`) with a log-normal prior of median
    ``center`` (SI: ``min_film`` and a film half-length in m, the drag torque in N m, the
    viscosity in Pa s, the scales as factors) and standard deviation ``log_sd`` in the natural
    log; its range and role are kept (a physical parameter stays physical). Pass it as
    ``FitOptions(priors={name: parameter_prior(name, ...)})``.

    What the rig knows besides the recording belongs here: ``h_min`` from the flanks'
    roughness, for instance. In mild rattle the data pin the squeeze film's momentum sink,
    which scales as a³/h_min², so a is known only as well as ``h_min`` is (the default prior's
    95 % factor 15.6 becomes about 6 in a). Raises
    :class:`~rattlefit.errors.RattlefitError` naming an unknown name, a centre outside the
    range or a log_sd that is not positive.
    """
    if base_name(name) not in PRIORABLE:
        raise RattlefitError(
            f"prior {name!r}: not a parameter that takes a prior; expected one of "
            f"{', '.join(PRIORABLE)}"
        )
    spec = prior_template(name)
    if not (math.isfinite(center) and spec.lower < center < spec.upper):
        raise RattlefitError(
            f"prior {name}: centre {center:g} {spec.unit} is outside the range "
            f"({spec.lower:g}, {spec.upper:g}) {spec.unit}"
        )
    if not (math.isfinite(log_sd) and log_sd > 0):
        raise RattlefitError(f"prior {name}: log_sd must be a positive number, got {log_sd:g}")
    return dataclasses.replace(spec, center=center, log_sd=log_sd)


def prior_template(name: str) -> ParameterSpec:
    """The default spec a prior on ``name`` replaces (its range and role): the viscosity's is
    the catalogue oil's range in Pa s at 20 °C's order, a film's carries ``name``."""
    if name == VISCOSITY:
        return ParameterSpec(VISCOSITY, "Pa s", 1e-3, 10.0, role="nuisance")
    (spec,) = (s for s in default_specs([], {}) if s.name == base_name(name))
    return dataclasses.replace(spec, name=name)


_CENTER = re.compile(r"\s*([-+0-9.eE]+)\s*([a-zA-Zµ]*)\s*")


def parse_prior(text: str) -> tuple[str, ParameterSpec]:
    """``"NAME=CENTER:LOG_SD"`` → ``(name, spec)`` of :func:`parameter_prior`, for command
    lines. CENTER is in the quantity's display unit (:mod:`rattlefit.quantities`), which it
    must name where that differs from SI (``min_film=2um:0.1``: h_min 2 µm, known to about
    10 %; ``film_half_length=0.085mm:0.3``), may name where it is SI
    (``drag_torque=0.025:0.3``, ``viscosity=0.49Pas:0.2``; spaces left out) and must not name
    for a factor (``viscosity_scale=1:0.05``). Raises
    :class:`~rattlefit.errors.RattlefitError` naming the problem and, for a unit slip, the
    probable fix."""
    name, sep, rest = text.partition("=")
    center, sep2, log_sd = rest.partition(":")
    name = name.strip()
    m = _CENTER.fullmatch(center)
    try:
        if not (sep and sep2 and m):
            raise ValueError
        value, sd = float(m.group(1)), float(log_sd)
    except ValueError:
        raise RattlefitError(
            f"prior {text!r}: expected NAME=CENTER:LOG_SD, e.g. min_film=2um:0.1"
        ) from None
    if base_name(name) not in PRIORABLE:
        return name, parameter_prior(name, value, sd)  # raises, naming the known names
    q = quantity(name)
    typed, shown = m.group(2), q.display_unit.replace(" ", "")
    if typed not in {shown, shown.replace("µ", "u")} and (typed or q.scale != 1.0):
        problem = f"is in {q.display_unit} and must say so" if q.scale != 1.0 else (
            f"is in {q.display_unit}" if q.display_unit else "has no unit")  # fmt: skip
        raise RattlefitError(
            f"prior {text!r}: {name}'s centre {problem}, e.g. "
            f"{name}={q.shown(value):g}{q.typed_unit.replace(' ', '')}:{sd:g} if {value:g} was "
            f"in {q.unit}"
        )
    return name, parameter_prior(name, value / q.scale, sd)
