"""Viscous damping in the mesh while the flanks are in contact: an extra force."""

from __future__ import annotations

from typing import ClassVar

import jax.numpy as jnp
import numpy as np

from ..model import Effect, RattleModel, RattleParams
from .fields import Scalar, parameter_field

__all__ = ["MeshDamping", "mean_mesh_stiffness"]

#: Gauss–Legendre nodes and weights on [−1, 1] for the mean stiffness (the integrand is smooth).
_NODES, _WEIGHTS = np.polynomial.legendre.leggauss(8)


def mean_mesh_stiffness(model: RattleModel, params: RattleParams):
    """The mean over one base pitch of K(θ1) of eq. (4), N/m, with sharp pair windows.

    Each pair contributes its stiffness over its window of ε base pitches, so the mean is the
    integral of one pair's law over its window, ``k_p ∫₀^ε exp(C_a |(φ − ε/2)/(1.125 εα)|³) dφ``
    (φ in base pitches), times ``stiffness_scale``; symmetric about ε/2, it is evaluated by
    Gauss–Legendre over [0, ε/2]. The model's windows are smoothed over ``mesh_width``: its K
    averages to this to within ~(mesh_width)² (2·10⁻⁴ relative at the default 0.01).
    """
    eps = model.contact_ratio
    x = 0.25 * eps * (1.0 + _NODES)
    pair = jnp.exp(model.stiffness_shape * (x / (1.125 * model.transverse_contact_ratio)) ** 3)
    return params.stiffness_scale * model.pitch_stiffness * 0.5 * eps * jnp.sum(_WEIGHTS * pair)


class MeshDamping(Effect):
    """Viscous damping in the mesh while the flanks are in contact (Kahraman & Singh's c_m).

    A dashpot in parallel with the mesh spring: force ``−c_m v s`` on the pitch circle (N),
    with ``c_m = 2 ζ √(K̄ m)``, K̄ the mean mesh stiffness of eq. (4)
    (:func:`mean_mesh_stiffness`, a constant over the mesh cycle) and m = I2/r2² the model's
    mass. ``s`` is the contact indicator of the model's own smoothed contact law: the contact
    force is ``K w softplus(−h/w)`` (h the nearer flank gap, w ``contact_width``), so
    ``s = 1 − exp(−|F_mesh| / (K w)) = sigmoid(−h/w)``, its derivative in the penetration over
    K. It is read off the contact force, without recomputing the gap, and is exact in the sharp
    limit (1 in contact, 0 apart) and smooth otherwise. A single impact on a flank then has the
    coefficient of restitution of a linear spring–dashpot, ``exp(−ζ' π/√(1 − ζ'²))`` with
    ``ζ' = ζ √(K̄/K)`` at the stiffness K of the impact. ``damping_ratio`` ζ (dimensionless).
    """

    name: ClassVar[str] = "mesh_damping"
    mechanism: ClassVar[str] = "dissipation in contact"
    ranges: ClassVar[dict[str, tuple[str, float, float]]] = {"damping_ratio": ("1", 1e-7, 0.3)}
    typical: ClassVar[tuple[float, str]] = (
        0.07,
        "mesh damping ratios reported for spur and helical gears (0.03–0.17)",
    )

    damping_ratio: Scalar = parameter_field()

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        k = model.mesh_stiffness(drive.angle(t), params.stiffness_scale)
        contact = -jnp.expm1(-jnp.abs(f_mesh) / (k * model.smoothing.contact_width))
        c_m = 2.0 * self.damping_ratio * jnp.sqrt(mean_mesh_stiffness(model, params) * model.mass)
        return -c_m * v * contact
