"""A localised defect on one tooth of the driving wheel: a kinematic error of the flank gap."""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ...errors import ParameterError
from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["ToothDefect"]


class ToothDefect(Effect):
    """A notch on the drive flank of one tooth of the driving wheel (a chipped or pitted
    tooth): the flank gap grows while that tooth is in mesh, once per revolution.

    The gap error is ``−depth · b(θ1)`` (m on the pitch circle), with the raised-cosine bump
    ``b = ½ (1 + cos(π x / L))`` for ``|x| < L`` and 0 elsewhere, ``x = θ1 − position`` wrapped
    to [−π, π) and ``L = width_teeth · Θp / 2``: the defect tooth is in mesh over
    ``width_teeth`` base pitches of θ1 centred on ``position`` (rad), and b is smooth
    (continuous with its slope) at the ends. A positive ``depth`` moves the drive flank's
    contact from q = −c to q = −c − depth·b: the driven wheel lags further before the notched
    flank reaches it, and the play on the drive side widens by the notch. As a kinematic error
    of the one-dof model it moves the whole tooth space, so the coast flank's contact moves
    with it, from +c to +c − depth·b (the total play stays 2c); in the recorded Δθ* = −q/r1
    both flanks rise by depth·b/r1 while the tooth is in mesh. ``depth`` in m; ``position`` in
    rad (not fitted); ``width_teeth`` static (default 1.0, below the driving wheel's tooth
    count).
    """

    name: ClassVar[str] = "tooth_defect"
    evidence: ClassVar[str | None] = "tooth"
    encoder_visible: ClassVar[bool] = True
    relevant_size: ClassVar[float | None] = 2e-6
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"depth": ("m", 1e-12, 3e-5)}
    typical: ClassVar[tuple[float, str]] = (
        1e-5,
        "a pit or chip 10 µm deep",
    )

    depth: Scalar = parameter_field()
    position: Scalar = parameter_field()
    width_teeth: float = eqx.field(static=True, default=1.0)

    def __check_init__(self):
        if not self.width_teeth > 0:
            raise ParameterError(f"tooth_defect: width_teeth must be > 0, got {self.width_teeth}")

    def bump(self, theta1, model: RattleModel):
        """b(θ1): 1 with the defect tooth mid-mesh, 0 while it is out of mesh."""
        x = jnp.mod(theta1 - self.position + jnp.pi, 2 * jnp.pi) - jnp.pi
        half = 0.5 * self.width_teeth * model.base_pitch_angle
        inside = jnp.abs(x) < half
        return jnp.where(
            inside, 0.5 * (1.0 + jnp.cos(jnp.pi * jnp.where(inside, x, 0.0) / half)), 0.0
        )

    def gap_error(self, t, theta1, model: RattleModel, params, drive):
        return -self.depth * self.bump(theta1, model)
