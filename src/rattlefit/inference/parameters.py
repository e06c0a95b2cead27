"""The fitted parameters: their coordinates, ranges and priors.

Every parameter :func:`~rattlefit.inference.fit.identify` fits is a :class:`ParameterSpec`: a range
``(lower, upper)`` in SI units, mapped from an unconstrained coordinate ``z`` by
``lower · (upper/lower)^sigmoid(z)`` (positive and bounded without clipping), with an
optional log-normal prior. :func:`default_specs` lists them for a set of recordings: one film
half-length per lubrication, the drag torque, the viscosity and stiffness factors, ``h_min``,
and each recording's backlash within its measurement uncertainty; :func:`nuisance_prior` and
:func:`parse_prior` replace a nuisance's prior.
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
from ..physics.model import DEFAULT_MIN_FILM
from ..quantities import FILM, quantity
from ..util import array_namespace

if TYPE_CHECKING:
    from ..rig import RigSetup

#: Range ends of the unconstrained coordinate (sigmoid(±8) is within 3.4e-4 of the end:
#: a = 1.003 µm, for instance).
Z_END = 8.0


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """One fitted parameter: its range, optional log-normal prior and finite-difference step.

    The value is ``lower · (upper/lower)^sigmoid(z)``. With ``center`` and ``log_sd`` the
    residual gets the prior row ``(log v − log center) / log_sd``.
    """

    name: str
    unit: str
    lower: float
    upper: float
    center: float | None = None
    log_sd: float | None = None
    fd_log_step: float = 0.15

    def __post_init__(self):
        if not (0 < self.lower < self.upper):
            raise RattlefitError(f"parameter {self.name}: need 0 < lower < upper")

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


#: Name of the squeeze-film group's coordinate, the squeeze film's momentum per approach
#: (:mod:`rattlefit.inference.group`).
MOMENTUM = "squeeze_momentum"


def momentum_name(film: str) -> str:
    """The squeeze-film group's name for the film half-length ``film``:
    ``film_half_length`` → ``squeeze_momentum``, ``film_half_length[boundary]`` →
    ``squeeze_momentum[boundary]``."""
    return MOMENTUM + film[len(FILM) :]


def films_of(rigs: Sequence[RigSetup]) -> tuple[str, ...]:
    """:func:`film_names` of the rigs' recordings."""
    return film_names([rig.recording.operating.lubrication for rig in rigs])


def default_specs(rigs: Sequence[RigSetup], priors: dict) -> tuple[ParameterSpec, ...]:
    """The fitted parameters with their prior ranges (SI units); ``priors`` replaces by name.

    A fit across lubrications has one film half-length per lubrication (:func:`film_names`,
    in the order the lubrications first appear); everything else but the backlashes is
    shared.
    """
    films = films_of(rigs) or (FILM,)
    specs = [
        *(ParameterSpec(n, "m", 1e-6, 5e-3, fd_log_step=0.2) for n in dict.fromkeys(films)),
        ParameterSpec("drag_torque", "N m", 2e-3, 0.5, fd_log_step=0.15),
        ParameterSpec("viscosity_scale", "1", 0.2, 5.0, center=1.0, log_sd=0.25, fd_log_step=0.15),
        ParameterSpec(
            "stiffness_scale",
            "1",
            0.3,
            3.0,
            center=1.0,
            log_sd=0.3,
            fd_log_step=0.15,
        ),
        ParameterSpec(
            "min_film", "m", 0.5e-6, 20e-6, center=DEFAULT_MIN_FILM, log_sd=0.7, fd_log_step=0.2
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
    return tuple(priors.get(s.name, s) for s in specs)


#: The nuisance parameters whose prior a caller may replace with :func:`nuisance_prior`: the
#: recording-independent parameters of :func:`default_specs` that have a prior.
NUISANCES = tuple(s.name for s in default_specs([], {}) if s.log_sd is not None)


def nuisance_prior(name: str, center: float, log_sd: float) -> ParameterSpec:
    """The prior of nuisance ``name`` (one of :data:`NUISANCES`) replaced by a log-normal one
    with median ``center`` (in the parameter's unit: ``min_film`` in m, the scales as
    factors) and standard deviation ``log_sd`` in the natural log; the range is kept. Pass it
    as ``FitOptions(priors={name: nuisance_prior(name, ...)})``.

    What the rig knows besides the recording belongs here: ``h_min`` from the flanks'
    roughness, for instance. In mild rattle the data pin the squeeze film's momentum sink,
    which scales as a³/h_min², so a is known only as well as ``h_min`` is (the default prior's
    95 % factor 15.6 becomes about 6 in a).
    """
    if name not in NUISANCES:
        raise RattlefitError(
            f"prior {name!r}: not a nuisance parameter; expected one of {', '.join(NUISANCES)}"
        )
    (spec,) = (s for s in default_specs([], {}) if s.name == name)
    if not (math.isfinite(center) and spec.lower < center < spec.upper):
        raise RattlefitError(
            f"prior {name}: centre {center:g} {spec.unit} is outside the range "
            f"({spec.lower:g}, {spec.upper:g}) {spec.unit}"
        )
    if not (math.isfinite(log_sd) and log_sd > 0):
        raise RattlefitError(f"prior {name}: log_sd must be a positive number, got {log_sd:g}")
    return dataclasses.replace(spec, center=center, log_sd=log_sd)


_CENTER = re.compile(r"\s*([-+0-9.eE]+)\s*([a-zA-Zµ]*)\s*")


def parse_prior(text: str) -> tuple[str, ParameterSpec]:
    """``"NAME=CENTER:LOG_SD"`` → ``(name, spec)`` of :func:`nuisance_prior`, for command
    lines. CENTER is in the quantity's display unit (:mod:`rattlefit.quantities`), which it
    must name when there is one: ``min_film=2um:0.1`` (h_min 2 µm, known to about 10 %),
    ``viscosity_scale=1:0.05``. Raises :class:`~rattlefit.errors.RattlefitError` naming the
    problem."""
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
    if name not in NUISANCES:
        return name, nuisance_prior(name, value, sd)  # raises, naming the nuisances
    q = quantity(name)
    if m.group(2) not in {q.display_unit, q.typed_unit}:
        (usual,) = (s.center for s in default_specs([], {}) if s.name == name)
        raise RattlefitError(
            f"prior {text!r}: {name}'s centre "
            + (f"is in {q.display_unit} and must say so" if q.display_unit else "has no unit")
            + f", e.g. {name}={q.shown(usual):g}{q.typed_unit}:{sd:g}"
        )
    return name, nuisance_prior(name, value / q.scale, sd)
