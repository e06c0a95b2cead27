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
    the model's) joined to the driven gear by a spring κ and a dashpot γ. The effect's state
    is their relative displacement and velocity ``(φ, φ̇)`` (m, m/s), ``φ = r2 (θ_s − θ2)``.
    The mode of the two masses on the spring, with the mesh open, has the frequency
    ``frequency`` (Hz) and the damping ratio ``damping_ratio`` (static, default 0.02):
    ``κ = (2π f)² μ``, ``γ = 2 ζ √(κ μ)``, ``μ = m m_s / (m + m_s)``. The shaft pulls the gear
    with ``F_s = κ φ + γ φ̇``; with ``F`` the net force on the gear from everything else,

        m r2 θ̈2 = F + F_s,    m_s r2 θ̈_s = −F_s,    φ̈ = −F_s / m_s − (F + F_s) / m.

    The bearing drag stays on the gear, and the encoders read the gear. At a small
    ``inertia_ratio`` the spring is weak (κ ∝ m_s) and the gear feels nothing.
    :class:`~rattlefit.physics.effects.ShaftCompliance` is the opposite limit, a shaft
    without inertia in series with the mesh.
    """

    name: ClassVar[str] = "shaft_inertia"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {
        "inertia_ratio": ("1", 1e-7, 10.0),
        "frequency": ("Hz", 100.0, 2000.0),
    }
    shape_fields: ClassVar[tuple[str, ...]] = ("frequency",)
    states: ClassVar[int] = 2
    state_units: ClassVar[tuple[str, ...]] = ("m", "m/s")

    inertia_ratio: Scalar = parameter_field()
    frequency: Scalar = parameter_field(350.0)
    damping_ratio: float = eqx.field(static=True, default=0.02)

    def spring_and_dashpot(self, model: RattleModel):
        """(κ in N/m, γ in N s/m) of the shaft on the pitch circle."""
        m, m_s = model.mass, self.inertia_ratio * model.mass
        reduced = m * m_s / (m + m_s)
        kappa = (2.0 * math.pi * self.frequency) ** 2 * reduced
        return kappa, 2.0 * self.damping_ratio * jnp.sqrt(kappa * reduced)

    def coupled(self, t, q, v, state, f_gear, model: RattleModel, params, drive):
        kappa, gamma = self.spring_and_dashpot(model)
        phi, phi_dot = state[0], state[1]
        f_shaft = kappa * phi + gamma * phi_dot
        m_s = self.inertia_ratio * model.mass
        phi_ddot = -f_shaft / m_s - (f_gear + f_shaft) / model.mass
        return f_shaft, jnp.stack([phi_dot, phi_ddot])
