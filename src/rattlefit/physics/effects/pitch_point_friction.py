"""Sliding friction between flanks in contact that reverses at the pitch point: an extra force."""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ...errors import ParameterError
from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["PitchPointFriction"]


class PitchPointFriction(Effect):
    """Sliding friction between the flanks in contact, whose direction reverses at the pitch
    point of each tooth pair's mesh cycle (the friction of the paper's dry case).

    Along the path of contact the flanks slide at a speed proportional to the contact's
    distance from the pitch point, so the friction's direction is set by the mesh position,
    not by the relative velocity v (:class:`FlankFriction` opposes v instead). Force on the
    pitch circle (N)::

        μ · F_mesh · g(s),   g(s) = tanh((s − s_p)/w) · tanh(sin(π s)/(π w)),

    with ``s = θ1/Θp mod 1`` the roll position within the current pair's mesh cycle (base
    pitches; s = 0 where a pair enters, the phase of K(θ1) in eq. 4), ``s_p`` = ``pitch_point``
    the pitch point within the cycle and ``w`` = ``width`` (base pitches) the smoothing of the
    sign; the second factor smooths the reversal back at the hand-over to the next pair
    (s = 0 ≡ 1). On the drive flank (F_mesh > 0) the driven flank slides ahead of the driving
    one before the pitch point (approach) and friction holds the driven wheel back (−μ|F|);
    after it (recess) friction pulls it forward (+μ|F|). On the coast flank the path of contact
    runs the other way along the profiles and the signs swap, which the sign of F_mesh gives;
    both flanks share the mesh cycle of K(θ1), as the model's stiffness does. The wheels are
    taken to turn forward (as in rattle), and the friction arm to be the pitch radius (arm
    ratio 1): ``coefficient`` μ (dimensionless) is an effective coefficient that absorbs the
    ratio of the true arm to r2 and of the normal to the tangential force. ``pitch_point``
    (default 0.5, mid-cycle: a pair of contact ratio one; K(θ1) of eq. 4 passes a pair's
    pitch point at s = frac(ε/2)) and ``width`` (default 0.02) are static, not fitted.

    Not among a diagnosis' default candidates (``tried_by_default``): its mechanism,
    dissipation in contact, is :class:`FlankFriction`'s and :class:`MeshDamping`'s, and its
    reversal at every pitch point makes it the slowest effect to simulate.
    """

    name: ClassVar[str] = "pitch_point_friction"
    mechanism: ClassVar[str] = "dissipation in contact"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"coefficient": ("1", 1e-6, 1.0)}
    typical: ClassVar[tuple[float, str]] = (
        0.05,
        "a mean friction coefficient of lubricated steel gear flanks (0.03–0.08)",
    )

    tried_by_default: ClassVar[bool] = False

    coefficient: Scalar = parameter_field()
    pitch_point: float = eqx.field(static=True, default=0.5)
    width: float = eqx.field(static=True, default=0.02)

    def __check_init__(self):
        if not (0.0 < self.pitch_point < 1.0 and 0.0 < self.width < 0.25):
            raise ParameterError(
                "pitch_point_friction: pitch_point must lie in (0, 1) and width in (0, 0.25) "
                f"base pitches, got {self.pitch_point} and {self.width}"
            )

    def direction(self, theta1, model: RattleModel):
        """g(s) at the primary angle ``theta1`` (rad): −1 before the pitch point, +1 after."""
        s = jnp.mod(theta1 / model.base_pitch_angle, 1.0)
        w = self.width
        return jnp.tanh((s - self.pitch_point) / w) * jnp.tanh(jnp.sin(jnp.pi * s) / (jnp.pi * w))

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        return self.coefficient * f_mesh * self.direction(drive.angle(t), model)
