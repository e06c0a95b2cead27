"""Mounting run-out of both wheels: a once-per-revolution kinematic error of the flank gap."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp

from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["Runout"]


class Runout(Effect):
    """Eccentricity (mounting run-out) of both wheels, as in the paper's Fig. 3.

    The flank gap moves by ``e1 sin(θ1 + φ1) + e2 sin(θ2 + φ2)`` on the pitch circle, with
    θ2 = θ1·r1/r2 the driven wheel's nominal angle: the contact positions (and the recorded
    Δθ*) wander once per revolution of each wheel. ``driving_amplitude`` e1 and
    ``driven_amplitude`` e2 in m; the phases φ in rad (not fitted: over a recording of many
    revolutions the band spectrum hardly depends on them).
    """

    name: ClassVar[str] = "runout"
    evidence: ClassVar[str | None] = "runout"
    encoder_visible: ClassVar[bool] = True
    relevant_size: ClassVar[float | None] = 2e-6
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {
        "driving_amplitude": ("m", 1e-12, 1e-4),
        "driven_amplitude": ("m", 1e-12, 1e-4),
    }
    typical: ClassVar[tuple[float, str]] = (
        2e-5,
        "the radial run-out tolerance of a gear of this size in accuracy grade 7, of the "
        "order of 20 µm (ISO 1328-2)",
    )

    driving_amplitude: Scalar = parameter_field()
    driven_amplitude: Scalar = parameter_field()
    driving_phase: Scalar = parameter_field()
    driven_phase: Scalar = parameter_field()

    def gap_error(self, t, theta1, model: RattleModel, params, drive):
        theta2 = theta1 * model.r1 / model.r2
        return self.driving_amplitude * jnp.sin(
            theta1 + self.driving_phase
        ) + self.driven_amplitude * jnp.sin(theta2 + self.driven_phase)
