"""A secondary shaft with inertia of its own behind the driven gear: a second degree of freedom."""

from __future__ import annotations

import math
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp

from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["ShaftInertia"]


class ShaftInertia(Effect):
    """The driven gear on a torsionally flexible secondary shaft that carries an inertia of its
    own (the rest of the shaft and what it holds): the rig's flexural mode.

    On the pitch circle the shaft's inertia is a mass ``m_s = inertia_ratio · m`` (m = I2/r2²,
    the model's) joined to the driven gear by a spring κ and a dashpot γ. The mode of the two
    masses on the spring, with the mesh open, has the frequency ``frequency`` (Hz) and the
    damping ratio ``damping_ratio`` (static, default 0.02): ``κ = (2π f)² μ``,
    ``γ = 2 ζ √(κ μ)``, ``μ = m m_s / (m + m_s)``. The shaft pulls the gear with
    ``F_s = κ φ + γ φ̇``, φ = r2 (θ_s − θ2) its deflection; with ``F`` the net force on the
    gear from everything else,

        m r2 θ̈2 = F + F_s,    m_s r2 θ̈_s = −F_s.

    The effect's state ``(u, u̇)`` (m, m/s) is the far mass's displacement from the rigid
    drive motion, ``ψ = r2 θ_s − r1 θ1``, times its share of the two masses,
    ``s = m_s / (m + m_s)``: ``u = s ψ``. Then ``s φ = u − s q``,

        F_s = m ω² (u − s q) + 2 ζ ω m (u̇ − s v),    ü = −F_s / (m (1 + r)) − s r1 θ̈1,

    with ω = 2π f and r the inertia ratio. u is the gear's motion filtered by the shaft's
    mode and scaled by what the gear feels of it, so the solver resolves the shaft's ringing
    only as far as it moves the gear: at the absent end (r = 1e-7) it costs no steps, where
    φ as the state made every simulation take about 30 % more. The shaft starts
    undeflected, ``(u, u̇) = s (q, v)``.

    The bearing drag stays on the gear, and the encoders read the gear. At a small
    ``inertia_ratio`` the spring is weak (κ ∝ m_s) and the gear feels nothing.
    :class:`~rattlefit.physics.effects.ShaftCompliance` is the opposite limit, a shaft
    without inertia in series with the mesh.
    """

    name: ClassVar[str] = "shaft_inertia"
    mechanism: ClassVar[str] = "shaft flexibility"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {
        "inertia_ratio": ("1", 1e-7, 10.0),
        "frequency": ("Hz", 100.0, 2000.0),
    }
    typical: ClassVar[tuple[float, str]] = (
        1.0,
        "a far inertia equal to the driven wheel's own",
    )
    shape_fields: ClassVar[tuple[str, ...]] = ("frequency",)
    states: ClassVar[int] = 2
    state_units: ClassVar[tuple[str, ...]] = ("m", "m/s")

    inertia_ratio: Scalar = parameter_field()
    frequency: Scalar = parameter_field(350.0)
    damping_ratio: float = eqx.field(static=True, default=0.02)

    def share(self):
        """s = m_s / (m + m_s), the far mass's share of the two."""
        return self.inertia_ratio / (1.0 + self.inertia_ratio)

    def initial_state(self, q, v):
        """The shaft undeflected at the start: ``(u, u̇) = s (q, v)`` (a batch of shafts,
        fields of shape (N,), with ``q`` and ``v`` of shape (N,))."""
        return jnp.expand_dims(self.share(), -1) * jnp.stack([q, v], axis=-1)

    def coupled(self, t, q, v, state, f_gear, model: RattleModel, params, drive):
        w = 2.0 * math.pi * self.frequency
        s = self.share()
        u, u_dot = state[0], state[1]
        f_shaft = model.mass * w * (w * (u - s * q) + 2.0 * self.damping_ratio * (u_dot - s * v))
        # the vector field's own call (one computation once traced), not the libm series
        acc1 = drive.angle_and_acceleration(t)[1]
        u_ddot = -f_shaft / (model.mass * (1.0 + self.inertia_ratio)) - s * model.r1 * acc1
        return f_shaft, jnp.stack([u_dot, u_ddot])
