"""The rig as a torsional chain: parameters of one recording and its linearised modes.

Four rotating bodies (kg m²), angles θ in each one's own direction of rotation (rad):

    motor rotor J_m ──k_p, c_p── pinion J_1 ═mesh═ driven gear J_2 ──k_s, c_s── far end J_s

* **Motor**: a brushless servo under a speed controller: PI on its own speed with acceleration
  feed-forward, torque limited to ±2.2 N m (the paper's motor), ``T = J_ff ω̇_c + K_p (ω_c −
  ω_m) + K_i (θ_c − θ_m) + T_0``; ω_c(t) = Ω + ΔΩ sin 2πft the commanded law the file states.
  ``K_p = 2π f_bw J_tot``, ``K_i = 2π f_i K_p`` with J_tot the rigid chain's inertia at the
  motor, ``J_ff = (1 + ff_error) J_tot`` and T_0 the mean drag at the motor.
* **Primary shaft**: bellows coupling and shaft in series, stiffness ``k_p`` (N m/rad), with a
  damping ratio on the motor–pinion mode. The primary encoder reads the pinion (it sits on the
  shaft's free end beyond the pinion).
* **Mesh** along the transverse line of action, ``x = rb2 θ2 − rb1 θ1`` (m), play 2c: load
  sharing over contact lines (:mod:`rig_mesh`), squeeze film (:mod:`rig_film`).
* **Secondary shaft**: stiffness ``k_s`` and damping ratio to the far end J_s, which the
  secondary encoder reads. J_2 + J_s is the driven inertia the recording states.
* **Drag**: bearing drag T_b split between the gear's bearing (share ``drag_gear_share``) and
  the far bearing; with the speed-dependent-drag effect a viscous part on the far bearing and a
  churning part ∝ ω^{3/2} on the gear (their sum at the mean speed stays T_b).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import linalg

from .rig_geometry import Pair, dynamic_viscosity
from .rig_mesh import MeshLaw

#: The paper's motor: maximum output torque, N m.
TORQUE_LIMIT = 2.2


@dataclass(frozen=True)
class Rig:
    """Everything one recording is simulated with (SI units; angles in rad).

    ``ripple``: motor torque ripple terms (order of the motor's rotation, amplitude N m, phase
    rad). ``runout``: (pinion eccentricity m, phase; driven eccentricity m, phase; driven
    ovality m, phase). ``restitution`` < 1 makes the contact hysteretic (:mod:`rig_solver`).
    ``warmup_k``/``warmup_time``: the oil warms by warmup_k·(1 − e^{−t/τ}) over the recording.
    ``a_max`` (flooded) and ``h_oil`` (starved) bound the film; ``lubrication`` "dry" has none.
    """

    pair: Pair
    mesh: MeshLaw
    lubrication: str
    temperature_c: float
    drag_torque: float
    mean_speed: float = 52.36
    speed_amplitude: float = 10.472
    drive_frequency: float = 16.0
    motor_inertia: float = 1.5e-4
    pinion_inertia: float = 7e-5
    far_inertia: float = 3e-5
    drive_stiffness: float = 6.5e3
    drive_damping: float = 0.03
    shaft_stiffness: float = 4e4
    shaft_damping: float = 0.02
    bandwidth_hz: float = 120.0
    integral_hz: float = 30.0
    ff_error: float = 0.0
    torque_limit: float = TORQUE_LIMIT
    ripple: tuple[tuple[int, float, float], ...] = ()
    drag_gear_share: float = 0.5
    viscous_drag: float = 0.0
    churning_drag: float = 0.0
    a_max: float = math.inf
    h_oil: float = math.inf
    h_min: float = 2e-6
    restitution: float = 1.0
    runout: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    warmup_k: float = 0.0
    warmup_time: float = 1.0
    mesh_phase: float = 0.0
    start_fraction: float = 0.0
    table: np.ndarray | None = field(default=None, compare=False, repr=False)

    # -- derived --------------------------------------------------------------------------
    @property
    def gear_inertia(self) -> float:
        """J_2 = the stated driven inertia less the far end's, kg m²."""
        return self.pair.driven_inertia - self.far_inertia

    @property
    def chain_inertia(self) -> float:
        """The rigid chain's inertia at the motor, kg m²."""
        return (
            self.motor_inertia + self.pinion_inertia + self.pair.driven_inertia / self.pair.ratio**2
        )

    @property
    def gains(self) -> tuple[float, float, float]:
        """(K_p in N m s/rad, K_i in N m/rad, J_ff in kg m²) of the speed controller."""
        kp = 2 * math.pi * self.bandwidth_hz * self.chain_inertia
        return kp, 2 * math.pi * self.integral_hz * kp, (1 + self.ff_error) * self.chain_inertia

    def dashpot(self, stiffness, ja, jb, ratio) -> float:
        """c = 2 ζ √(k μ), μ = ja jb/(ja + jb): the dashpot of damping ratio ζ on that mode."""
        return 2 * ratio * math.sqrt(stiffness * ja * jb / (ja + jb))

    @property
    def drive_dashpot(self) -> float:
        return self.dashpot(
            self.drive_stiffness, self.motor_inertia, self.pinion_inertia, self.drive_damping
        )

    @property
    def shaft_dashpot(self) -> float:
        return self.dashpot(
            self.shaft_stiffness, self.gear_inertia, self.far_inertia, self.shaft_damping
        )

    @property
    def driven_speed(self) -> float:
        """Mean driven speed Ω z1/z2, rad/s."""
        return self.mean_speed / self.pair.ratio

    @property
    def constant_drag(self) -> float:
        """The speed-independent part of the drag, N m (T_b less the speed-dependent parts at
        the mean speed)."""
        w = self.driven_speed
        return self.drag_torque - self.viscous_drag * w - self.churning_drag * w**1.5

    @property
    def viscosity(self) -> float:
        """μ at the starting oil temperature, Pa s."""
        return float(dynamic_viscosity(self.temperature_c))

    def viscosity_at(self, t):
        """μ(t) (Pa s) at recording times ``t`` (s; before 0 the starting value), array."""
        rise = self.warmup_k * (1 - np.exp(-np.maximum(t, 0.0) / self.warmup_time))
        return dynamic_viscosity(self.temperature_c + rise)

    def mesh_table(self) -> np.ndarray:
        """The mesh table (:meth:`rig_mesh.MeshLaw.table`), cached when given."""
        return self.mesh.table() if self.table is None else self.table


def matrices(rig: Rig, mesh_stiffness: float = 0.0, controller: bool = False):
    """Inertia and stiffness matrices (4×4; order motor, pinion, gear, far end) of the chain
    linearised about a state: ``mesh_stiffness`` (N m⁻¹, along the line of action) while the
    flanks touch, 0 in free flight; ``controller`` adds K_i between the motor and the ground."""
    p = rig.pair
    mass = np.diag([rig.motor_inertia, rig.pinion_inertia, rig.gear_inertia, rig.far_inertia])
    k = np.zeros((4, 4))

    def spring(i, j, value, arm_i=1.0, arm_j=1.0):
        k[i, i] += value * arm_i**2
        k[j, j] += value * arm_j**2
        k[i, j] -= value * arm_i * arm_j
        k[j, i] -= value * arm_i * arm_j

    spring(0, 1, rig.drive_stiffness)
    spring(1, 2, mesh_stiffness, p.rb1, p.rb2)
    spring(2, 3, rig.shaft_stiffness)
    if controller:
        k[0, 0] += rig.gains[1]
    return mass, k


def natural_frequencies(rig: Rig, mesh_stiffness: float = 0.0, controller: bool = False):
    """Natural frequencies (Hz, ascending; rigid-body modes 0) of :func:`matrices`."""
    mass, k = matrices(rig, mesh_stiffness, controller)
    w2 = linalg.eigh(k, mass, eigvals_only=True)
    return np.sqrt(np.maximum(w2, 0.0)) / (2 * math.pi)
