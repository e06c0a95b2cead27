"""The fitted parameters as one object: the owner of what a fit's coordinate vector means.

A :class:`ParameterSpace` holds the :class:`~rattlefit.problem.parameters.ParameterSpec` of
every fitted parameter, in the order of the fit's unconstrained vector ``z``, and which film
half-length each recording uses. It is the one place that turns ``z`` into values
(:meth:`ParameterSpace.values`), values back into ``z`` (:meth:`ParameterSpace.z_of`) and
named values into a recording's :class:`~rattlefit.physics.model.RattleParams`
(:meth:`ParameterSpace.rattle_params`); every list of names (:meth:`ParameterSpace.of_role`)
reads from it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from ..errors import RattlefitError
from ..physics.model import RattleParams
from ..quantities import DRAG_TORQUE, FILM, MIN_FILM, STIFFNESS_SCALE, VISCOSITY
from ..util import array_namespace
from .parameters import ROLES, ParameterSpec, momentum_name


@dataclasses.dataclass(frozen=True)
class ParameterSpace:
    """The P fitted parameters of R recordings.

    specs : (P,) the parameters, in the order of the fit's vector ``z``.
    films : (R,) the name of the film half-length each recording uses (one per lubrication).

    Raises :class:`~rattlefit.errors.RattlefitError` for a name used twice.
    """

    specs: tuple[ParameterSpec, ...]
    films: tuple[str, ...] = ()

    def __post_init__(self):
        object.__setattr__(self, "specs", tuple(self.specs))
        object.__setattr__(self, "films", tuple(self.films))
        names = [s.name for s in self.specs]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise RattlefitError(f"parameter space: {', '.join(twice)} named twice")

    # -- names ------------------------------------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        """The parameters' names, in the order of ``z``."""
        return tuple(s.name for s in self.specs)

    def index(self, name: str) -> int:
        """The position of ``name`` in ``z``; raises ``ValueError`` if it is not fitted."""
        return self.names.index(name)

    def spec(self, name: str) -> ParameterSpec:
        """The :class:`ParameterSpec` of ``name``."""
        return self.specs[self.index(name)]

    def of_role(self, *roles: str) -> tuple[str, ...]:
        """The names of the parameters whose role is one of ``roles`` (:data:`ROLES`)."""
        unknown = set(roles) - set(ROLES)
        if unknown:
            raise ValueError(f"unknown role(s) {sorted(unknown)}: expected {ROLES}")
        return tuple(s.name for s in self.specs if s.role in roles)

    # -- changes ----------------------------------------------------------------------------
    def replaced(self, spec: ParameterSpec, name: str | None = None) -> ParameterSpace:
        """This space with the parameter ``name`` (default ``spec.name``) replaced by
        ``spec`` at its place in ``z``."""
        i = self.index(spec.name if name is None else name)
        return dataclasses.replace(self, specs=(*self.specs[:i], spec, *self.specs[i + 1 :]))

    def extended(self, *specs: ParameterSpec) -> ParameterSpace:
        """This space with ``specs`` appended to ``z``."""
        return dataclasses.replace(self, specs=(*self.specs, *specs))

    # -- coordinates ------------------------------------------------------------------------
    def values(self, z) -> dict:
        """Name → value (SI) at the unconstrained vector ``z`` (P,); traceable."""
        return {s.name: s.value(z[i]) for i, s in enumerate(self.specs)}

    def z_of(self, values: Mapping[str, float]) -> np.ndarray:
        """The vector ``z`` (P,) of named values (SI); a parameter ``values`` leaves out
        is at its prior's centre, or the geometric middle of its range without a prior."""

        def middle(s):
            return s.center if s.center is not None else math.sqrt(s.lower * s.upper)

        return np.array([s.z_of(float(values.get(s.name, middle(s)))) for s in self.specs])

    # -- the model's parameters -------------------------------------------------------------
    def rattle_params(self, values: Mapping, r, viscosities) -> RattleParams:
        """Recording ``r``'s :class:`~rattlefit.physics.model.RattleParams` from named values
        (SI; as :meth:`values` gives, the films' entries included where their coordinate is
        a squeeze-film group); ``viscosities`` (R,) is each recording's catalogue μ (Pa s).

        The film half-length is the recording's film (:attr:`films`), the backlash its own
        ``backlash[r]``, the viscosity its catalogue μ; ``drag_torque``, ``min_film`` and
        ``stiffness_scale`` are the parameters of those names where fitted (else the
        model's defaults); and each parameter that :attr:`ParameterSpec.scales` a field
        multiplies it. ``r`` may be traced.
        """
        xp = array_namespace(r, viscosities, *values.values())
        n = len(self.films)
        fields = {
            FILM: xp.stack([values[f] for f in self.films])[r],
            "backlash": xp.stack([values[f"backlash[{k}]"] for k in range(n)])[r],
            VISCOSITY: xp.asarray(viscosities)[r],
            **{k: values[k] for k in (DRAG_TORQUE, MIN_FILM, STIFFNESS_SCALE) if k in values},
        }
        for s in self.specs:
            if s.scales is not None:
                fields[s.scales] = fields.get(s.scales, 1.0) * values[s.name]
        return RattleParams.from_dict(fields)

    def group_names(self) -> dict[str, str]:
        """Film name → its squeeze-film group's name, for the films fitted by their group."""
        return {f: momentum_name(f) for f in dict.fromkeys(self.films) if f not in self.names}

    # -- documents --------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """A JSON-ready form: ``specs`` (each spec's fields) and ``films``."""
        return {"specs": [dataclasses.asdict(s) for s in self.specs], "films": list(self.films)}

    @classmethod
    def from_dict(cls, doc: Mapping) -> ParameterSpace:
        """The inverse of :meth:`to_dict`; raises ``KeyError``/``TypeError`` for a malformed
        document and :class:`~rattlefit.errors.RattlefitError` for an invalid spec."""
        return cls(tuple(ParameterSpec(**s) for s in doc["specs"]), tuple(doc["films"]))
