"""Bearing and churning drag that grows with the driven wheel's speed: an extra force."""

from __future__ import annotations

from typing import ClassVar

from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["SpeedDependentDrag"]


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
    typical: ClassVar[tuple[float, str]] = (
        5e-4,
        "a drag that adds the paper's drag torque (0.025 N m) at the paper's mean driven "
        "speed (about 50 rad/s)",
    )

    coefficient: Scalar = parameter_field()

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        omega2 = (v + model.r1 * drive.speed(t)) / model.r2
        mean = drive.mean_speed * model.r1 / model.r2
        return -self.coefficient * (omega2 - mean) / model.r2
