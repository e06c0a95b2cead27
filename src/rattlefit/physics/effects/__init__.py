"""Physical effects outside the seed paper's one-dof model, each a self-contained plug-in.

Every effect is an :class:`~rattlefit.physics.model.Effect`: an immutable module whose array fields
are its parameters (SI units) and which changes the model through one of three hooks — a
kinematic error of the flank gap, an extra force on the pitch circle, or parameters that
change in time. Add one to a model with ``model.with_effects(Runout(...))``; nothing else in
the simulator knows about it. :func:`rattlefit.diagnosis.diagnose.diagnose` fits each effect in
:data:`EFFECTS` on top of an identification and reports how much of the misfit it removes.

Each class declares ``ranges``: its fitted fields with (unit, lower, upper). The lower end
stands for the effect being absent: there it changes the model's acceleration by less than
a thousandth of the drag's plus 10⁻⁴ of the acceleration itself, anywhere along a rattle
trajectory (tests/test_effects.py); the upper end is generous for a production gearbox.

What cannot be a plug-in here: a torsionally flexible *shaft with inertia* adds degrees of
freedom to the state. :class:`ShaftCompliance` is its quasi-static limit (the shaft's
stiffness in series with the mesh), which is what a one-dof model can hold.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from ..errors import RattlefitError
from .model import Effect, RattleModel, RattleParams

Scalar = Float[Array, ""]


def _field(default: float = 0.0):
    return eqx.field(default=default, converter=lambda x: jnp.asarray(x, dtype=float))


class Runout(Effect):
    """Eccentricity (mounting run-out) of both wheels, as in the paper's Fig. 3.

    The flank gap moves by ``e1 sin(θ1 + φ1) + e2 sin(θ2 + φ2)`` on the pitch circle, with
    θ2 = θ1·r1/r2 the driven wheel's nominal angle: the contact positions (and the recorded
    Δθ*) wander once per revolution of each wheel. ``driving_amplitude`` e1 and
    ``driven_amplitude`` e2 in m; the phases φ in rad (not fitted: over a recording of many
    revolutions the band spectrum hardly depends on them).
    """

    name: ClassVar[str] = "runout"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {
        "driving_amplitude": ("m", 1e-12, 1e-4),
        "driven_amplitude": ("m", 1e-12, 1e-4),
    }

    driving_amplitude: Scalar = _field()
    driven_amplitude: Scalar = _field()
    driving_phase: Scalar = _field()
    driven_phase: Scalar = _field()

    def gap_error(self, t, theta1, model: RattleModel, params, drive):
        theta2 = theta1 * model.r1 / model.r2
        return self.driving_amplitude * jnp.sin(
            theta1 + self.driving_phase
        ) + self.driven_amplitude * jnp.sin(theta2 + self.driven_phase)


class ToothErrors(Effect):
    """A transmission error at the mesh frequency (tooth profile and pitch errors).

    The flank gap moves by ``amplitude · sin(z1 θ1 + phase)`` (m on the pitch circle), once
    per tooth of the driving wheel.
    """

    name: ClassVar[str] = "tooth_errors"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"amplitude": ("m", 1e-13, 3e-5)}

    amplitude: Scalar = _field()
    phase: Scalar = _field()

    def gap_error(self, t, theta1, model: RattleModel, params, drive):
        return self.amplitude * jnp.sin(2 * jnp.pi * theta1 / model.base_pitch_angle + self.phase)


class FlankFriction(Effect):
    """Coulomb friction between flanks in contact, the dissipation the paper's dry case lacks.

    While the flanks are pressed together by the contact force ``F`` (N), a friction force
    ``μ_f |F|`` opposes their relative motion, ``−μ_f |F| tanh(v / sliding_speed)``: the
    impacts lose energy (a coefficient of restitution below one), where the paper's model has
    a purely elastic contact. ``coefficient`` μ_f (dimensionless); ``sliding_speed`` (m/s,
    not fitted) regularises the sign function.
    """

    name: ClassVar[str] = "flank_friction"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"coefficient": ("1", 1e-6, 1.0)}

    coefficient: Scalar = _field()
    sliding_speed: float = eqx.field(static=True, default=1e-3)

    def force(self, t, q, v, f_mesh, model, params, drive):
        return -self.coefficient * jnp.abs(f_mesh) * jnp.tanh(v / self.sliding_speed)


class SpeedDependentDrag(Effect):
    """A bearing and churning drag that grows with the driven wheel's speed.

    Extra torque ``coefficient · (ω2 − Ω2)`` (N m) against the driven wheel, ω2 its speed and
    Ω2 = Ω r1/r2 its mean: the mean drag stays ``drag_torque``, the fluctuation is damped.
    ``coefficient`` in N m s/rad.
    """

    name: ClassVar[str] = "speed_dependent_drag"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {
        "coefficient": ("N m s/rad", 1e-7, 1e-2)
    }

    coefficient: Scalar = _field()

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        omega2 = (v + model.r1 * drive.speed(t)) / model.r2
        mean = drive.mean_speed * model.r1 / model.r2
        return -self.coefficient * (omega2 - mean) / model.r2


class DriveRipple(Effect):
    """An acceleration ripple of the primary shaft at an order of its rotation that the
    measured drive (harmonics of the fluctuation frequency only) does not hold.

    The primary acceleration gains ``amplitude · sin(order · θ1 + phase)`` (rad/s²), which
    forces the driven wheel through its inertia like the rest of θ̈1. ``order`` is static
    (default 2: twice per revolution, a four-cylinder engine's firing order).
    """

    name: ClassVar[str] = "drive_ripple"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"amplitude": ("rad/s²", 1e-2, 3e4)}

    amplitude: Scalar = _field()
    phase: Scalar = _field()
    order: int = eqx.field(static=True, default=2)

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        acc = self.amplitude * jnp.sin(self.order * drive.angle(t) + self.phase)
        return -model.mass * model.r1 * acc


class ViscosityDrift(Effect):
    """The oil warms during the recording: its viscosity falls as ``μ · exp(−rate · t)``.

    ``rate`` in 1/s (t in s from the first sample; the burn-in runs at slightly higher
    viscosity).
    """

    name: ClassVar[str] = "viscosity_drift"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"rate": ("1/s", 1e-6, 1.0)}

    rate: Scalar = _field()

    def adjust(self, t, params: RattleParams, model, drive) -> RattleParams:
        return eqx.tree_at(
            lambda p: p.viscosity, params, params.viscosity * jnp.exp(-self.rate * t)
        )


class ShaftCompliance(Effect):
    """A torsionally compliant shaft in series with the mesh (its quasi-static limit).

    The contact force becomes ``F / (1 + K(θ1) · compliance)``, K the mesh stiffness of
    eq. (4) and ``compliance`` the shafts' torsional compliance referred to the pitch circle
    (m/N): the mesh-stiffness variation flattens as well as its level falling, which a scale
    on K cannot do. A shaft with its own inertia is another degree of freedom, not a plug-in.
    """

    name: ClassVar[str] = "shaft_compliance"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"compliance": ("m/N", 1e-15, 1e-7)}

    compliance: Scalar = _field()

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        kc = model.mesh_stiffness(drive.angle(t), params.stiffness_scale) * self.compliance
        return -f_mesh * kc / (1.0 + kc)


#: The catalogue, by name.
EFFECTS: dict[str, type[Effect]] = {
    cls.name: cls
    for cls in (
        Runout,
        ToothErrors,
        FlankFriction,
        SpeedDependentDrag,
        DriveRipple,
        ViscosityDrift,
        ShaftCompliance,
    )
}


def absent(name: str) -> Effect:
    """The effect ``name`` with every fitted field at the absent end of its range."""
    cls = effect_class(name)
    return cls(**{k: lo for k, (_, lo, _) in cls.ranges.items()})


def effect_class(name: str) -> type[Effect]:
    """The effect class called ``name`` (see :data:`EFFECTS`)."""
    try:
        return EFFECTS[name]
    except KeyError:
        known = ", ".join(sorted(EFFECTS))
        raise RattlefitError(f"unknown effect {name!r}; known effects: {known}") from None
