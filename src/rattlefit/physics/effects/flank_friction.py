"""Coulomb friction between flanks in contact: an extra force on the pitch circle."""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ..model import Effect
from .fields import Scalar, parameter_field

__all__ = ["FlankFriction"]


class FlankFriction(Effect):
    """Coulomb friction between flanks in contact, the dissipation the paper's dry case lacks.

    While the flanks are pressed together by the contact force ``F`` (N), a friction force
    ``μ_f |F|`` opposes their relative motion, ``−μ_f |F| tanh(v / sliding_speed)``: the
    impacts lose energy (a coefficient of restitution below one), where the paper's model has
    a purely elastic contact. ``coefficient`` μ_f (dimensionless); ``sliding_speed`` (m/s,
    not fitted) regularises the sign function.
    """

    name: ClassVar[str] = "flank_friction"
    mechanism: ClassVar[str] = "dissipation in contact"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"coefficient": ("1", 1e-6, 1.0)}
    typical: ClassVar[tuple[float, str]] = (
        0.05,
        "a mean friction coefficient of lubricated steel gear flanks (0.03–0.08)",
    )

    coefficient: Scalar = parameter_field()
    sliding_speed: float = eqx.field(static=True, default=1e-3)

    def force(self, t, q, v, f_mesh, model, params, drive):
        return -self.coefficient * jnp.abs(f_mesh) * jnp.tanh(v / self.sliding_speed)
