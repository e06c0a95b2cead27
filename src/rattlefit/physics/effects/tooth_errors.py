"""Tooth profile and pitch errors: a kinematic error of the flank gap at the mesh frequency."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["ToothErrors"]


class ToothErrors(Effect):
    """A transmission error at the mesh frequency (tooth profile and pitch errors).

    The flank gap moves by ``amplitude · sin(z1 θ1 + phase)`` (m on the pitch circle), once
    per tooth of the driving wheel.
    """

    name: ClassVar[str] = "tooth_errors"
    evidence: ClassVar[str | None] = "mesh_order"
    encoder_visible: ClassVar[bool] = True
    relevant_size: ClassVar[float | None] = 1e-6
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"amplitude": ("m", 1e-13, 3e-5)}
    typical: ClassVar[tuple[float, str]] = (
        5e-6,
        "single-pitch deviations of about 5 µm (accuracy grade 6–7)",
    )

    amplitude: Scalar = parameter_field()
    phase: Scalar = parameter_field()

    def gap_error(self, t, theta1, model: RattleModel, params, drive):
        return self.amplitude * jnp.sin(2 * jnp.pi * theta1 / model.base_pitch_angle + self.phase)
