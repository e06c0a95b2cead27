"""An acceleration ripple of the primary shaft at an order of its rotation: an extra force."""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["DriveRipple"]


class DriveRipple(Effect):
    """An acceleration ripple of the primary shaft at an order of its rotation that the
    measured drive (harmonics of the fluctuation frequency only) does not hold.

    The primary acceleration gains ``amplitude · sin(order · θ1 + phase)`` (rad/s²), which
    forces the driven wheel through its inertia like the rest of θ̈1. ``order`` is static
    (default 2: twice per revolution, a four-cylinder engine's firing order).
    """

    name: ClassVar[str] = "drive_ripple"
    evidence: ClassVar[str | None] = "drive_order"
    encoder_visible: ClassVar[bool] = True
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"amplitude": ("rad/s²", 1e-2, 3e4)}
    typical: ClassVar[tuple[float, str]] = (
        1e3,
        "the acceleration amplitude of the paper's speed fluctuation at 16 Hz and 20 % "
        "(about 1050 rad/s²)",
    )

    amplitude: Scalar = parameter_field()
    phase: Scalar = parameter_field()
    order: int = eqx.field(static=True, default=2)

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        acc = self.amplitude * jnp.sin(self.order * drive.angle(t) + self.phase)
        return -model.mass * model.r1 * acc
