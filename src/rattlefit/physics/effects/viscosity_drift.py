"""The oil warming during a recording: a parameter that changes in time."""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ..model import Effect, RattleParams
from .fields import Scalar, parameter_field

__all__ = ["ViscosityDrift"]


class ViscosityDrift(Effect):
    """The oil warms during the recording: its viscosity falls as ``μ · exp(−rate · t)``.

    ``rate`` in 1/s (t in s from the first sample; the burn-in runs at slightly higher
    viscosity).
    """

    name: ClassVar[str] = "viscosity_drift"
    evidence: ClassVar[str | None] = "drift"
    named_only_when_found: ClassVar[bool] = True
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"rate": ("1/s", 1e-6, 1.0)}
    typical: ClassVar[tuple[float, str]] = (
        1e-2,
        "oil warming that lowers the viscosity by 1 % per second",
    )

    rate: Scalar = parameter_field()

    def adjust(self, t, params: RattleParams, model, drive) -> RattleParams:
        return eqx.tree_at(
            lambda p: p.viscosity, params, params.viscosity * jnp.exp(-self.rate * t)
        )
