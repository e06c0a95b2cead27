"""A torsionally compliant shaft in series with the mesh, in its quasi-static limit."""

from __future__ import annotations

from typing import ClassVar

from ..model import Effect, RattleModel
from .fields import Scalar, parameter_field

__all__ = ["ShaftCompliance"]


class ShaftCompliance(Effect):
    """A torsionally compliant shaft in series with the mesh (its quasi-static limit).

    The contact force becomes ``F / (1 + K(θ1) · compliance)``, K the mesh stiffness of
    eq. (4) and ``compliance`` the shafts' torsional compliance referred to the pitch circle
    (m/N): the mesh-stiffness variation flattens as well as its level falling, which a scale
    on K cannot do. A shaft with its own inertia is
    :class:`~rattlefit.physics.effects.ShaftInertia`.
    """

    name: ClassVar[str] = "shaft_compliance"
    mechanism: ClassVar[str] = "shaft flexibility"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"compliance": ("m/N", 1e-15, 1e-7)}
    typical: ClassVar[tuple[float, str]] = (
        4e-9,
        "a shaft as compliant as the mesh (ISO 6336's mesh stiffness, about 20 N/(mm µm) of "
        "face width: 2.6·10⁸ N/m at 13 mm)",
    )

    compliance: Scalar = parameter_field()

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        kc = model.mesh_stiffness(drive.angle(t), params.stiffness_scale) * self.compliance
        return -f_mesh * kc / (1.0 + kc)
