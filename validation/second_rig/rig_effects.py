"""Effects outside the seed paper's model, in this rig's own forms.

Each effect is a frozen dataclass with ``name`` (in this model's words), ``expected`` (the
rattlefit diagnose verdicts that name it rightly), :meth:`apply` (the rig with the effect,
a :class:`rig_chain.Rig`), :meth:`describe` (form and size in words), :meth:`sizes` (its
parameters in SI units) and ``reference`` (what makes the size physically plausible).
None of them is a form rattlefit's catalogue or its injected calibration set uses:

=========================  =====================================================================
motor_torque_ripple        cogging of the servo at order 24 (12 slots, 8 poles) and 48 of the
                           motor's rotation, optionally a current-sensor ripple at the electrical
                           order 4, as a torque on the motor rotor inside the speed loop
viscous_and_churning_drag  a far-bearing drag linear in its speed plus gear churning ∝ ω^{3/2},
                           their sum at the mean speed equal to T_b
wheel_eccentricity         geometric eccentricity of pinion and/or driven wheel and ovality of the
                           driven wheel, each shifting the flanks along the line of action and
                           opening the play through its radial part (exact involute slope)
pitted_tooth_with_burr     a pitted band softening the contact line of two adjacent driven teeth
                           and a burr standing proud of the band's edge, a separate contact
                           spring with a kinematic offset, engaged while the helical line
                           crosses it (load sharing with the other pairs)
hysteretic_contact         linear-hysteretic (Walton) contact: unloading K/e² (δ − p), a
                           restitution e independent of the impact speed, no dashpot
flexible_secondary_coupling an elastomer coupling on the secondary shaft with a far inertia
                           (flywheel/brake disc), the mode in band, the encoder on the far end
                           and part of the drag on the far bearing
oil_warm_up                the oil's temperature rising as ΔT (1 − e^{−t/τ}) with the viscosity
                           by the oil's ASTM D341 law
=========================  =====================================================================
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .rig_chain import Rig
from .rig_mesh import MeshLaw, ToothDefect

#: rattlefit's candidates for dissipation in contact.
DISSIPATION = ("flank_friction", "mesh_damping", "pitch_point_friction")
#: rattlefit's candidates for a flexible shaft.
FLEXIBILITY = ("shaft_compliance", "shaft_inertia")


@dataclass(frozen=True)
class Effect:
    """Base class: see the module notes."""

    name: ClassVar[str] = "effect"
    expected: ClassVar[tuple[str, ...]] = ()
    reference: ClassVar[str] = ""

    def apply(self, rig: Rig) -> Rig:
        raise NotImplementedError

    def describe(self, rig: Rig) -> str:
        raise NotImplementedError

    def sizes(self, rig: Rig) -> dict:
        """The effect's fields in SI units (names carry the unit)."""
        return {k: v for k, v in dataclasses.asdict(self).items()}


@dataclass(frozen=True)
class MotorTorqueRipple(Effect):
    """Torque on the motor rotor ``Σ A_n sin(n θ_m + φ_n)`` (N m) at orders n of the motor's
    rotation: cogging at 24 and 48, and optionally the electrical order 4."""

    name: ClassVar[str] = "motor_torque_ripple"
    expected: ClassVar[tuple[str, ...]] = ("drive_ripple",)
    reference: ClassVar[str] = (
        "cogging torque of unskewed permanent-magnet servo motors is 1–5 % of the rated "
        "torque, at the least common multiple of slots and poles (12 slots, 8 poles: order 24); "
        "a current-sensor offset gives a ripple at the electrical frequency (order 4 for 8 "
        "poles) of 1–3 % of the peak torque; the paper's motor peaks at 2.2 N m"
    )

    cogging_N_m: float = 0.06
    cogging_phase_rad: float = 0.0
    second_N_m: float = 0.018
    second_phase_rad: float = 0.0
    electrical_N_m: float = 0.0
    electrical_phase_rad: float = 0.0

    def terms(self):
        out = [
            (24, self.cogging_N_m, self.cogging_phase_rad),
            (48, self.second_N_m, self.second_phase_rad),
        ]
        if self.electrical_N_m:
            out.append((4, self.electrical_N_m, self.electrical_phase_rad))
        return tuple(out)

    def apply(self, rig):
        return dataclasses.replace(rig, ripple=rig.ripple + self.terms())

    def acceleration(self, rig: Rig, order: int, amplitude: float) -> float:
        """The primary shaft's acceleration amplitude (rad/s²) at ``order`` for ``amplitude``
        (N m): the rigid chain in the closed speed loop, |s² / (J s² + K_p s + K_i)| · A at
        s = i·order·Ω (an estimate: the chain's modes are far above)."""
        kp, ki, _ = rig.gains
        s = 1j * order * rig.mean_speed
        return float(abs(s * s / (rig.chain_inertia * s * s + kp * s + ki)) * amplitude)

    def describe(self, rig):
        parts = [
            f"{order}: {a * 1e3:.0f} mN m (primary acceleration ≈ "
            f"{self.acceleration(rig, order, a):.0f} rad/s² in the speed loop)"
            for order, a, _ in self.terms()
        ]
        return (
            "motor torque ripple on the servo rotor, inside the speed loop, at orders of the "
            "motor's rotation " + "; ".join(parts)
        )

    def sizes(self, rig):
        out = super().sizes(rig)
        for order, a, _ in self.terms():
            out[f"acceleration_order{order}_rad_s2"] = self.acceleration(rig, order, a)
        return out


@dataclass(frozen=True)
class ViscousChurningDrag(Effect):
    """Drag ``T = T_0 + c_v ω_s + c_ch ω_2^{3/2}``: c_v on the far bearing (its speed ω_s),
    churning c_ch on the gear; shares of T_b at the mean driven speed Ω2 (T_0 takes the
    rest, so the mean drag stays T_b)."""

    name: ClassVar[str] = "viscous_and_churning_drag"
    expected: ClassVar[tuple[str, ...]] = ("speed_dependent_drag",)
    reference: ClassVar[str] = (
        "churning losses of a dip- or jet-lubricated gear grow about as ω^1.5 at these "
        "Reynolds numbers (Changenet's correlations) and viscous seal/bearing drag linearly; "
        "together they are most of an idle shaft's drag, so a slope of about T_b/Ω2"
    )

    viscous_share: float = 0.2
    churning_share: float = 0.65

    def apply(self, rig):
        w = rig.driven_speed
        return dataclasses.replace(
            rig,
            viscous_drag=self.viscous_share * rig.drag_torque / w,
            churning_drag=self.churning_share * rig.drag_torque / w**1.5,
        )

    def slope(self, rig) -> float:
        """dT/dω at the mean driven speed, N m s/rad."""
        return (self.viscous_share + 1.5 * self.churning_share) * rig.drag_torque / rig.driven_speed

    def describe(self, rig):
        slope = self.slope(rig)
        return (
            f"drag T = T_0 + c_v ω_s + c_ch ω_2^1.5: {100 * self.viscous_share:.0f} % of T_b "
            f"viscous on the far bearing, {100 * self.churning_share:.0f} % churning on the "
            f"gear at the mean driven speed {rig.driven_speed:.1f} rad/s; slope "
            f"{slope:.3g} N m s/rad there ({slope * rig.driven_speed / rig.drag_torque:.2f} T_b/Ω2)"
        )

    def sizes(self, rig):
        applied = self.apply(rig)
        return {
            **super().sizes(rig),
            "viscous_N_m_s_per_rad": applied.viscous_drag,
            "churning_N_m_s1.5_per_rad1.5": applied.churning_drag,
            "constant_N_m": applied.constant_drag,
            "slope_N_m_s_per_rad": self.slope(rig),
        }


@dataclass(frozen=True)
class WheelEccentricity(Effect):
    """Geometric run-out: pinion eccentricity e1, driven eccentricity e2 and ovality e3 (m),
    phases in rad. The flanks shift along the line of action by Σ e sin(k θ_w + φ) and the
    play opens by d(play)/d(cd) · Σ e cos(k θ_w + φ) (k = 1, 1, 2)."""

    name: ClassVar[str] = "wheel_eccentricity"
    expected: ClassVar[tuple[str, ...]] = ("runout",)
    reference: ClassVar[str] = (
        "ISO 1328-2 radial run-out tolerance F_r for m_n = 2 mm, d = 25–105 mm is about "
        "20–30 µm at grade 7; the paper's Fig. 3 shows the pinion's eccentricity as the larger "
        "once-per-revolution pattern; a locking device clamps a wheel slightly oval"
    )

    pinion_m: float = 15e-6
    pinion_phase_rad: float = 0.0
    driven_m: float = 0.0
    driven_phase_rad: float = 0.0
    ovality_m: float = 5e-6
    ovality_phase_rad: float = 0.0

    def apply(self, rig):
        values = (
            self.pinion_m,
            self.pinion_phase_rad,
            self.driven_m,
            self.driven_phase_rad,
            self.ovality_m,
            self.ovality_phase_rad,
        )
        return dataclasses.replace(rig, runout=values)

    def describe(self, rig):
        slope = rig.pair.play_slope()
        return (
            f"eccentricity of the pinion {self.pinion_m * 1e6:.1f} µm and of the driven wheel "
            f"{self.driven_m * 1e6:.1f} µm, ovality of the driven wheel "
            f"{self.ovality_m * 1e6:.1f} µm (second order): flanks shifted along the line of "
            f"action by Σ e sin(kθ + φ), play opened by {slope:.3f} × Σ e cos(kθ + φ)"
        )


@dataclass(frozen=True)
class PittedToothWithBurr(Effect):
    """A pitted band on the drive flank of driven teeth k, k+1 that softens their contact line
    by ``softening``, with a burr on its edge ``heights`` (m) high (see
    :class:`rig_mesh.ToothDefect`)."""

    name: ClassVar[str] = "pitted_tooth_with_burr"
    expected: ClassVar[tuple[str, ...]] = ("tooth_defect", "tooth_errors")
    reference: ClassVar[str] = (
        "a handling nick raises a burr of 5–20 µm beside the dent; ISO 1328-1 profile form "
        "tolerance f_fα for m_n = 2 mm, d ≈ 90 mm is about 10 µm at grade 7; the paper's "
        "Fig. 3 shows spikes from defects on two driven teeth"
    )

    first_tooth: int = 0
    heights_m: tuple[float, float] = (10e-6, 6e-6)
    softening: float = 0.4
    band_start: float = 0.4

    def defect(self, rig: Rig) -> ToothDefect:
        z2 = rig.pair.z2
        teeth = (self.first_tooth % z2, (self.first_tooth + 1) % z2)
        return ToothDefect(
            teeth=teeth,
            heights=self.heights_m,
            softening=self.softening,
            band=(self.band_start, self.band_start + 0.25),
        )

    def apply(self, rig):
        mesh = MeshLaw(rig.pair, rig.mesh.kappa, rig.mesh.coast_offset, self.defect(rig))
        return dataclasses.replace(rig, mesh=mesh, table=None)

    def describe(self, rig):
        d = self.defect(rig)
        return (
            f"drive flanks of driven teeth {d.teeth[0]} and {d.teeth[1]} pitted over "
            f"{d.band[0]:.2f}–{d.band[1]:.2f} of the path of contact (their contact line "
            f"{100 * self.softening:.0f} % softer there) with burrs of "
            f"{self.heights_m[0] * 1e6:.1f} and {self.heights_m[1] * 1e6:.1f} µm on the band's "
            f"edge over {d.burr_length * 1e3:.0f} mm of the face (contact spring "
            f"{rig.mesh.line_stiffness * d.burr_contact:.3g} N/m)"
        )


@dataclass(frozen=True)
class HystereticContact(Effect):
    """Linear-hysteretic contact of restitution e (:mod:`rig_solver`)."""

    name: ClassVar[str] = "hysteretic_contact"
    expected: ClassVar[tuple[str, ...]] = DISSIPATION
    reference: ClassVar[str] = (
        "measured coefficients of restitution of steel gear-tooth impacts at 0.05–0.5 m/s lie "
        "between 0.6 and 0.9 (dry flanks; local plasticity of asperities and friction)"
    )

    restitution: float = 0.75

    def apply(self, rig):
        return dataclasses.replace(rig, restitution=self.restitution)

    def describe(self, rig):
        return (
            f"linear-hysteretic flank contact (loading K δ, unloading K/e² (δ − p)): "
            f"restitution e = {self.restitution:.2f} at every impact speed, "
            f"{100 * (1 - self.restitution**2):.0f} % of the impact energy lost"
        )


@dataclass(frozen=True)
class FlexibleSecondaryCoupling(Effect):
    """The far end carries ``inertia_share`` of the stated driven inertia on a coupling whose
    mode (mesh open) is at ``frequency_hz``, damping ratio ``damping``; the far bearing takes
    ``drag_share`` of the drag."""

    name: ClassVar[str] = "flexible_secondary_coupling"
    expected: ClassVar[tuple[str, ...]] = FLEXIBILITY
    reference: ClassVar[str] = (
        "elastomer jaw couplings of 10–20 N m rating have torsional stiffnesses of "
        "1–5 kN m/rad and relative damping ψ ≈ 0.8 (ζ ≈ 0.06); a brake disc or flywheel on "
        "the secondary shaft carries a third of its inertia or more"
    )

    inertia_share: float = 0.35
    frequency_hz: float = 500.0
    damping: float = 0.06
    drag_share: float = 0.6

    def stiffness(self, rig: Rig) -> float:
        """k_s (N m/rad) of the mode: (2π f)² J_2 J_s / (J_2 + J_s)."""
        js = self.inertia_share * rig.pair.driven_inertia
        j2 = rig.pair.driven_inertia - js
        return (2 * math.pi * self.frequency_hz) ** 2 * j2 * js / (j2 + js)

    def apply(self, rig):
        return dataclasses.replace(
            rig,
            far_inertia=self.inertia_share * rig.pair.driven_inertia,
            shaft_stiffness=self.stiffness(rig),
            shaft_damping=self.damping,
            drag_gear_share=1.0 - self.drag_share,
        )

    def describe(self, rig):
        js = self.inertia_share * rig.pair.driven_inertia
        return (
            f"flexible coupling on the secondary shaft: {self.stiffness(rig):.0f} N m/rad to a "
            f"far inertia {js:.3g} kg m² ({100 * self.inertia_share:.0f} % of the driven "
            f"inertia), mode {self.frequency_hz:.0f} Hz with the mesh open, ζ = "
            f"{self.damping:.2f}; the secondary encoder on the far end; "
            f"{100 * self.drag_share:.0f} % of the drag on the far bearing"
        )

    def sizes(self, rig):
        js = self.inertia_share * rig.pair.driven_inertia
        return {
            **super().sizes(rig),
            "stiffness_N_m_per_rad": self.stiffness(rig),
            "far_inertia_kg_m2": js,
        }


@dataclass(frozen=True)
class OilWarmUp(Effect):
    """Oil temperature T(t) = T_0 + ΔT (1 − e^{−t/τ}) over the recording (t ≥ 0)."""

    name: ClassVar[str] = "oil_warm_up"
    expected: ClassVar[tuple[str, ...]] = ("viscosity_drift",)
    reference: ClassVar[str] = (
        "oil reaching the mesh warms by 5–15 K within seconds when the jet's supply line or "
        "the churned flank film heats up; the paper's oil loses about 3 % of its viscosity "
        "per kelvin near 20 °C"
    )

    rise_K: float = 10.0
    time_constant_s: float = 1.5

    def apply(self, rig):
        return dataclasses.replace(rig, warmup_k=self.rise_K, warmup_time=self.time_constant_s)

    def describe(self, rig, duration: float = 3.0):
        end = self.apply(rig).viscosity_at(np.array([duration]))[0]
        return (
            f"oil warming by {self.rise_K:.1f} K (1 − e^(−t/{self.time_constant_s:.2f} s)) from "
            f"{rig.temperature_c:.1f} °C: viscosity {rig.viscosity:.3f} → {end:.3f} Pa s "
            f"({100 * end / rig.viscosity:.0f} %) at {duration:g} s (ASTM D341)"
        )
