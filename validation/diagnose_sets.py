"""Calibration sets for ``rattlefit diagnose``: recordings its own fitted model did not make.

Two sets of 3 s recordings in the recording format (version 1), built deterministically from
fixed seeds and cached under ``$RATTLEFIT_DIAGNOSE_SETS/<set>/`` (default
``studies/cache/diagnose_sets`` of the repository) with a ``truth.json`` beside them:

* ``clean`` — no effect outside the seed paper's model, but a model form that differs from
  rattlefit's fitted smoothed model in the small ways a real rig's does: half are made by the
  sharp reference solver (:func:`~rattlefit.simulation.reference.simulate_reference`, event
  location, no smoothing) instead of the smoothed diffrax solver; the primary shaft follows
  another law than the commanded sine (a lag and an amplitude error of the motor, a second
  harmonic of the speed) while ``/operating`` states the command; the mesh-stiffness shape
  C_a, the film saturation h_min and the stiffness scale are off their defaults. Every
  recording's acceptable verdicts are ``none``, ``unexplained`` and ``model_form``.
* ``injected`` — rattlefit's smoothed simulator with one effect (two in two recordings)
  written in another form than the catalogue candidate meant to find it (the classes below:
  Hunt–Crossley contact damping, Coulomb friction with another regularisation or a Stribeck
  coefficient, run-out of one wheel with ovality or with its radial component, a drive ripple
  at another order, a viscosity drift linear in time or through a temperature ramp, a drag
  that grows with a power of the speed, a notch on one tooth of the driven wheel, a flexible
  secondary shaft with a far inertia and part of the drag on it), with some
  of the clean set's model-form differences mixed in. The acceptable verdicts are the
  catalogue names that describe the effect (for dissipation in contact, any of the three
  dissipative candidates; for two effects, each combination joined by ``+``).

Each truth entry has the shared ``truth.json``'s keys (``a_mm``, ``drag_torque_Nm``,
``viscosity_Pa_s`` — the value at t = 0 —, ``unmodelled_effects``), ``expected`` (the
acceptable verdicts), ``form`` (how the recording was made, in words, with each effect's
size), ``model`` (the model-form values in SI units), ``effects`` (each injected effect's
parameters in SI units) and ``seed``.

    python -m rattlefit.testing.diagnose_sets [--set clean|injected|all] [--jobs N]

prints each recording's name and build time (files that exist are skipped). As a module,
:func:`clean_set` and :func:`injected_set` return ``[(path, truth), ...]`` after building what
is missing; :func:`build_case` builds one case into any directory (the tests build 0.5 s ones).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from rattlefit.config import configure
from rattlefit.diagnosis.verdict import NAMES_NOTHING as CLEAN
from rattlefit.io.recording import OperatingPoint, write_recording
from rattlefit.physics.drive import Drive
from rattlefit.physics.effects import EFFECTS, mechanism_of
from rattlefit.physics.geometry import DEFAULT_STIFFNESS_SHAPE, GearGeometry, table2_pair
from rattlefit.physics.model import DEFAULT_MIN_FILM, Effect, RattleModel, RattleParams
from rattlefit.physics.oil import KELVIN, dynamic_viscosity, walther_coefficients
from rattlefit.simulation.reference import simulate_reference
from rattlefit.simulation.synthetic import PAPER_OIL, recording_from_trajectory, synthesize
from rattlefit.testing.shared import recordings_dir

#: Where the sets are built (``$RATTLEFIT_DIAGNOSE_SETS``, else under the working directory).
#: The repository's root (this package lies in its ``validation/`` folder).
REPO = Path(__file__).resolve().parents[1]
CACHE = Path(
    os.environ.get("RATTLEFIT_DIAGNOSE_SETS", REPO / "studies" / "cache" / "diagnose_sets")
)
SETS = ("clean", "injected")

#: Recorded duration, s (after the 0.5 s burn-in of both solvers).
DURATION = 3.0
#: The rig's mean primary speed (500 rpm), rad/s.
MEAN_SPEED = 52.36
#: Film half-length a of each lubrication, m (the shared truth's).
FILM = {"dry": 0.0, "boundary": 0.085e-3, "oil_jet": 1.0e-3}
#: The catalogue's candidates for dissipation in contact: any of them names it rightly.
DISSIPATION = tuple(n for n in EFFECTS if mechanism_of(n) == "dissipation in contact")
#: Impact speed at which a speed-dependent restitution is stated, m/s: the median contact-onset
#: speed of the dry operating points used here (50–110 mm/s).
IMPACT_SPEED = 0.08


def _array(x) -> jax.Array:
    return jnp.asarray(x, dtype=float)


def _wrap(x):
    """``x`` (rad) wrapped to [−π, π)."""
    return jnp.mod(x + jnp.pi, 2 * jnp.pi) - jnp.pi


# --- effects in other forms than the catalogue's ---------------------------------------------


class InjectedEffect(Effect):
    """An injected effect: :meth:`describe` gives its formula and size for the truth entry and
    ``expected`` the catalogue verdicts that name it rightly."""

    expected: ClassVar[tuple[str, ...]] = ()
    #: SI unit of each numeric field, appended to its name in :meth:`sizes`.
    units: ClassVar[dict[str, str]] = {}

    def sizes(self) -> dict[str, float]:
        """The effect's numeric fields as ``"<field>_<unit>"`` → value (SI, 12 digits)."""
        return {
            f"{k}_{self.units[k]}" if self.units.get(k) else k: float(f"{float(v):.12g}")
            for k, v in vars(self).items()
            if isinstance(v, jax.Array | float | int)
        }

    def describe(self) -> str:
        """Formula and size, in words."""
        raise NotImplementedError


class HuntCrossleyDamping(InjectedEffect):
    """Hunt–Crossley damping in contact with a linear spring: ``F = −λ δ v`` (N), δ the
    penetration (m) and v = q̇ (m/s); zero out of contact.

    δ is the model's own contact penetration, ``|F_mesh| / K(θ1)`` (exact for its contact
    law). ``damping`` λ in N s/m². A single impact at speed v0 on a spring of stiffness K
    keeps the energy fraction e² ≈ 1 − (4/3) λ v0 / K (to first order in λ): the restitution
    falls with the impact speed, where the catalogue's mesh damping (a dashpot) and flank
    friction (Coulomb) give one restitution at every speed.
    """

    name: ClassVar[str] = "hunt_crossley_damping"
    expected: ClassVar[tuple[str, ...]] = DISSIPATION

    units: ClassVar[dict[str, str]] = {"damping": "N_s_per_m2", "mean_stiffness": "N_per_m"}

    damping: jax.Array = eqx.field(converter=_array)
    mean_stiffness: float = eqx.field(static=True, default=2e8)  # for the description, N/m

    @classmethod
    def for_restitution(cls, restitution: float, mean_stiffness: float, speed=IMPACT_SPEED):
        """λ that gives ``restitution`` at impact ``speed`` (m/s) on ``mean_stiffness`` (N/m)."""
        lam = 0.75 * (1.0 - restitution**2) * mean_stiffness / speed
        return cls(damping=lam, mean_stiffness=float(mean_stiffness))

    def restitution(self, speed: float) -> float:
        """First-order restitution at impact ``speed`` (m/s) on the mean stiffness."""
        return math.sqrt(
            max(0.0, 1.0 - 4.0 * float(self.damping) * speed / (3 * self.mean_stiffness))
        )

    def describe(self):
        lam, k = float(self.damping), self.mean_stiffness
        return (
            f"Hunt–Crossley contact damping F = −λ δ v, λ = {lam:.3g} N s/m² "
            f"(α = λ/(1.5 K̄) = {lam / (1.5 * k):.2f} s/m on K̄ = {k:.3g} N/m; restitution "
            f"≈ {self.restitution(0.04):.2f} at 40 mm/s, {self.restitution(IMPACT_SPEED):.2f} "
            f"at 80 mm/s, {self.restitution(0.12):.2f} at 120 mm/s)"
        )

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        k = model.mesh_stiffness(drive.angle(t), params.stiffness_scale)
        return -self.damping * (jnp.abs(f_mesh) / k) * v


class ArctanFriction(InjectedEffect):
    """Coulomb friction between flanks in contact regularised by an arctangent:
    ``F = −μ |F_mesh| (2/π) arctan(v / v_s)`` (N). ``coefficient`` μ (dimensionless),
    ``sliding_speed`` v_s (m/s): below v_s the friction is nearly viscous, so slow contacts
    slide with less than μ|F|."""

    name: ClassVar[str] = "sliding_friction_arctan"
    expected: ClassVar[tuple[str, ...]] = DISSIPATION
    units: ClassVar[dict[str, str]] = {"coefficient": "1", "sliding_speed": "m_per_s"}

    coefficient: jax.Array = eqx.field(converter=_array)
    sliding_speed: float = eqx.field(static=True, default=3e-3)

    def describe(self):
        return (
            f"Coulomb flank friction with an arctangent regularisation, "
            f"F = −μ|F_mesh|(2/π)arctan(v/v_s), μ = {float(self.coefficient):.3g}, "
            f"v_s = {self.sliding_speed * 1e3:.3g} mm/s"
        )

    def force(self, t, q, v, f_mesh, model, params, drive):
        return (
            -self.coefficient * jnp.abs(f_mesh) * (2 / jnp.pi) * jnp.arctan(v / self.sliding_speed)
        )


class StribeckFriction(InjectedEffect):
    """Flank friction whose coefficient falls with the sliding speed (Stribeck):
    ``F = −μ(v) |F_mesh| v / √(v² + v_r²)``, ``μ(v) = μ_k + (μ_s − μ_k) exp(−(v/v_st)²)``.
    ``static`` μ_s and ``kinetic`` μ_k dimensionless; ``stribeck_speed`` v_st and
    ``regularisation`` v_r in m/s."""

    name: ClassVar[str] = "sliding_friction_stribeck"
    expected: ClassVar[tuple[str, ...]] = DISSIPATION
    units: ClassVar[dict[str, str]] = {
        "static": "1",
        "kinetic": "1",
        "stribeck_speed": "m_per_s",
        "regularisation": "m_per_s",
    }

    static: jax.Array = eqx.field(converter=_array)
    kinetic: jax.Array = eqx.field(converter=_array)
    stribeck_speed: float = eqx.field(static=True, default=0.02)
    regularisation: float = eqx.field(static=True, default=5e-4)

    def coefficient(self, v):
        """μ(v), dimensionless."""
        return self.kinetic + (self.static - self.kinetic) * jnp.exp(
            -((v / self.stribeck_speed) ** 2)
        )

    def describe(self):
        return (
            f"Stribeck flank friction F = −μ(v)|F_mesh| v/√(v²+v_r²), "
            f"μ(v) = μ_k + (μ_s − μ_k)exp(−(v/v_st)²), μ_s = {float(self.static):.3g}, "
            f"μ_k = {float(self.kinetic):.3g}, v_st = {self.stribeck_speed * 1e3:.3g} mm/s, "
            f"v_r = {self.regularisation * 1e3:.3g} mm/s"
        )

    def force(self, t, q, v, f_mesh, model, params, drive):
        sign = v / jnp.sqrt(v * v + self.regularisation**2)
        return -self.coefficient(v) * jnp.abs(f_mesh) * sign


class WheelRunout(InjectedEffect):
    """Geometric error of one wheel: eccentricity (first harmonic) and ovality (second).

    The flank gap moves by ``Σ_k e_k sin(k θ_w + φ_k)`` (m on the pitch circle), k = 1, 2, with
    θ_w the wheel's angle (θ1, or θ2 = θ1 r1/r2 for the driven wheel). With ``radial`` the
    same error's radial component also changes the working centre distance by
    ``Σ_k e_k cos(k θ_w + φ_k)``, which opens the backlash by ``2 tan αwt`` times it
    (``play_factor`` = 2 tan αwt): both flanks move apart and together, which the catalogue's
    run-out (both wheels, first harmonic, a shift of both flanks alike) cannot do.
    ``wheel`` is ``"driving"`` or ``"driven"``; amplitudes in m, phases in rad.
    """

    name: ClassVar[str] = "wheel_runout"
    expected: ClassVar[tuple[str, ...]] = ("runout",)
    units: ClassVar[dict[str, str]] = {
        "eccentricity": "m",
        "ovality": "m",
        "eccentricity_phase": "rad",
        "ovality_phase": "rad",
        "play_factor": "1",
    }

    eccentricity: jax.Array = eqx.field(converter=_array)
    ovality: jax.Array = eqx.field(converter=_array, default=0.0)
    eccentricity_phase: jax.Array = eqx.field(converter=_array, default=0.0)
    ovality_phase: jax.Array = eqx.field(converter=_array, default=0.0)
    wheel: str = eqx.field(static=True, default="driven")
    play_factor: float = eqx.field(static=True, default=0.0)

    def angle(self, theta1, model: RattleModel):
        """θ_w: the wheel's nominal angle at primary angle ``theta1``, rad."""
        return theta1 if self.wheel == "driving" else theta1 * model.r1 / model.r2

    def tangential(self, theta1, model: RattleModel):
        """The gap error Σ e_k sin(k θ_w + φ_k), m."""
        th = self.angle(theta1, model)
        return self.eccentricity * jnp.sin(th + self.eccentricity_phase) + self.ovality * jnp.sin(
            2 * th + self.ovality_phase
        )

    def radial(self, theta1, model: RattleModel):
        """Change of the working centre distance Σ e_k cos(k θ_w + φ_k), m."""
        th = self.angle(theta1, model)
        return self.eccentricity * jnp.cos(th + self.eccentricity_phase) + self.ovality * jnp.cos(
            2 * th + self.ovality_phase
        )

    def describe(self):
        text = (
            f"run-out of the {self.wheel} wheel only: eccentricity e1 = "
            f"{float(self.eccentricity) * 1e6:.3g} µm (φ1 = {float(self.eccentricity_phase):.2f}"
            " rad)"
        )
        if float(self.ovality):
            text += (
                f" and ovality (second harmonic) e2 = {float(self.ovality) * 1e6:.3g} µm "
                f"(φ2 = {float(self.ovality_phase):.2f} rad) on the pitch circle"
            )
        if self.play_factor:
            text += (
                f", with its radial component opening the backlash by 2 tan αwt × "
                f"Σ e_k cos(kθ + φ_k) (2 tan αwt = {self.play_factor:.3f}; ±"
                f"{self.play_factor * float(self.eccentricity + self.ovality) * 1e6:.3g} µm)"
            )
        return text

    def gap_error(self, t, theta1, model: RattleModel, params, drive):
        return self.tangential(theta1, model)

    def adjust(self, t, params: RattleParams, model: RattleModel, drive) -> RattleParams:
        if not self.play_factor:
            return params
        opening = self.play_factor * self.radial(drive.angle(t), model)
        return eqx.tree_at(lambda p: p.backlash, params, params.backlash + opening)


class DrivenToothNotch(InjectedEffect):
    """A notch on one tooth of the driven wheel: the flank gap grows while that tooth meshes,
    once per revolution of the driven wheel.

    Gap error ``−depth · b(x)`` (m), ``x = θ2 − position`` wrapped to [−π, π), θ2 = θ1 r1/r2,
    over ``L = width_teeth · 2π / z2`` of θ2 (one driven tooth pitch by default). ``shape``
    ``"triangle"``: ``b = max(0, 1 − |x| / (L/2))`` (a V-shaped notch centred on
    ``position``); ``"step"``: a one-sided step, ``b = σ(x / s) · max(0, 1 − x / L)`` with the
    logistic σ over s = L/200 — the full depth at once when the tooth enters mesh, worn back
    linearly over the tooth. ``depth`` in m, ``position`` in rad of the driven wheel.
    """

    name: ClassVar[str] = "driven_tooth_notch"
    expected: ClassVar[tuple[str, ...]] = ("tooth_defect", "tooth_errors")
    units: ClassVar[dict[str, str]] = {"depth": "m", "position": "rad", "width_teeth": "1"}

    depth: jax.Array = eqx.field(converter=_array)
    position: jax.Array = eqx.field(converter=_array, default=0.0)
    shape: str = eqx.field(static=True, default="triangle")
    width_teeth: float = eqx.field(static=True, default=1.0)

    def bump(self, theta1, model: RattleModel):
        """b at primary angle ``theta1`` (rad): 1 at the notch's deepest, 0 out of it."""
        x = _wrap(theta1 * model.r1 / model.r2 - self.position)
        length = self.width_teeth * model.base_pitch_angle * model.r1 / model.r2  # 2π/z2 each
        if self.shape == "triangle":
            return jnp.maximum(0.0, 1.0 - jnp.abs(x) / (0.5 * length))
        return jax.nn.sigmoid(x / (length / 200)) * jnp.maximum(0.0, 1.0 - x / length)

    def describe(self):
        form = (
            "a V-shaped (triangular) notch"
            if self.shape == "triangle"
            else "a one-sided step notch (full depth at entry, worn back linearly)"
        )
        return (
            f"{form} on one tooth of the driven wheel, depth {float(self.depth) * 1e6:.3g} µm "
            f"on the pitch circle over {self.width_teeth:g} driven tooth pitch, at θ2 = "
            f"{float(self.position):.2f} rad"
        )

    def gap_error(self, t, theta1, model: RattleModel, params, drive):
        return -self.depth * self.bump(theta1, model)


class LinearViscosityDrift(InjectedEffect):
    """The viscosity falls linearly in time: ``μ(t) = μ0 (1 − rate · max(t, 0))`` (the burn-in
    at μ0). ``rate`` in 1/s (below 1/duration)."""

    name: ClassVar[str] = "viscosity_drift_linear"
    expected: ClassVar[tuple[str, ...]] = ("viscosity_drift",)
    units: ClassVar[dict[str, str]] = {"rate": "per_s"}

    rate: jax.Array = eqx.field(converter=_array)

    def describe(self):
        r = float(self.rate)
        return (
            f"viscosity falling linearly in time, μ(t) = μ0 (1 − {r:.3g}/s · t): "
            f"{100 * (1 - r * DURATION):.0f} % of μ0 at {DURATION:g} s"
        )

    def adjust(self, t, params: RattleParams, model, drive) -> RattleParams:
        factor = 1.0 - self.rate * jnp.maximum(t, 0.0)
        return eqx.tree_at(lambda p: p.viscosity, params, params.viscosity * factor)


class TemperatureRamp(InjectedEffect):
    """The oil warms linearly in time, ``T(t) = T0 + rate · max(t, 0)`` (°C), and its viscosity
    follows the ASTM D341 (Walther) law of the oil: ``μ(t) = μ0 ν(T(t)) / ν(T0)``.
    ``rate`` in K/s; ``start_c`` T0 in °C; ``walther`` the oil's (A, B)."""

    name: ClassVar[str] = "oil_temperature_ramp"
    expected: ClassVar[tuple[str, ...]] = ("viscosity_drift",)
    units: ClassVar[dict[str, str]] = {"rate": "K_per_s", "start_c": "degC"}

    rate: jax.Array = eqx.field(converter=_array)
    start_c: float = eqx.field(static=True, default=20.0)
    walther: tuple[float, float] = eqx.field(
        static=True,
        default=walther_coefficients(PAPER_OIL.viscosity_40c_cst, PAPER_OIL.viscosity_100c_cst),
    )

    def kinematic(self, temperature_c):
        """ν(T) in cSt by ASTM D341."""
        a, b = self.walther
        return 10.0 ** (10.0 ** (a - b * jnp.log10(temperature_c + KELVIN))) - 0.7

    def describe(self):
        end = self.start_c + float(self.rate) * DURATION
        ratio = float(self.kinematic(end) / self.kinematic(self.start_c))
        return (
            f"oil warming linearly from {self.start_c:g} °C at {float(self.rate):.3g} K/s "
            f"(to {end:.3g} °C at {DURATION:g} s), viscosity by the oil's ASTM D341 law: "
            f"{100 * ratio:.0f} % of μ0 at {DURATION:g} s"
        )

    def adjust(self, t, params: RattleParams, model, drive) -> RattleParams:
        temperature = self.start_c + self.rate * jnp.maximum(t, 0.0)
        factor = self.kinematic(temperature) / self.kinematic(self.start_c)
        return eqx.tree_at(lambda p: p.viscosity, params, params.viscosity * factor)


class PowerLawDrag(InjectedEffect):
    """A drag torque that grows with a power of the driven wheel's speed,
    ``T(ω2) = T_b (ω2 / Ω2)^p`` (N m), T_b the recording's drag torque at the mean speed
    Ω2 = Ω r1/r2: the extra force on the pitch circle is ``−(T_b/r2)((ω2/Ω2)^p − 1)``.
    ``exponent`` p (0.5: square root; 2: churning), static."""

    name: ClassVar[str] = "power_law_drag"
    expected: ClassVar[tuple[str, ...]] = ("speed_dependent_drag",)
    units: ClassVar[dict[str, str]] = {"exponent": "1"}

    exponent: float = eqx.field(static=True, default=0.5)

    def describe(self):
        law = {0.5: "the square root of", 2.0: "the square of"}.get(self.exponent, "a power of")
        return (
            f"drag torque growing with {law} the driven wheel's speed, "
            f"T = T_b (ω2/Ω2)^{self.exponent:g} (T_b at the mean speed; slope "
            f"{self.exponent:g} T_b/Ω2 there)"
        )

    def force(self, t, q, v, f_mesh, model: RattleModel, params, drive):
        omega2 = (v + model.r1 * drive.speed(t)) / model.r2
        mean = drive.mean_speed * model.r1 / model.r2
        ratio = jnp.maximum(omega2 / mean, 1e-6)
        return -(params.drag_torque / model.r2) * (ratio**self.exponent - 1.0)


class FlexibleShaft(InjectedEffect):
    """The driven gear on a torsionally flexible secondary shaft that ends in an inertia, in
    the rig's terms: torsional stiffness ``stiffness`` (N m/rad), the far inertia ``inertia``
    (kg m²), structural damping of loss factor ``loss_factor`` (a dashpot η k/ω at the mode)
    and a share ``drag_share`` of the bearing drag acting on the far inertia instead of the
    gear. State: the far inertia's lead over the gear on the pitch circle and its rate."""

    name: ClassVar[str] = "flexible_shaft"
    expected: ClassVar[tuple[str, ...]] = ("shaft_inertia", "shaft_compliance")
    units: ClassVar[dict[str, str]] = {
        "stiffness": "Nm/rad",
        "inertia": "kgm2",
        "loss_factor": "1",
        "drag_share": "1",
    }
    states: ClassVar[int] = 2
    state_units: ClassVar[tuple[str, ...]] = ("m", "m/s")

    stiffness: jax.Array = eqx.field(converter=_array)
    inertia: jax.Array = eqx.field(converter=_array)
    loss_factor: float = eqx.field(static=True, default=0.05)
    drag_share: float = eqx.field(static=True, default=0.3)

    @classmethod
    def for_mode(cls, pair: str, cd: float, frequency: float, inertia_ratio: float, **kw):
        """The shaft whose mode (mesh open) is at ``frequency`` (Hz), its far inertia
        ``inertia_ratio`` times the driven gear's."""
        g = table2_pair(pair, center_distance_mm=cd)
        m, r2 = g.equivalent_mass, g.pitch_radius_driven
        m_s = inertia_ratio * m
        kappa = (2 * math.pi * frequency) ** 2 * m * m_s / (m + m_s)
        return cls(stiffness=kappa * r2**2, inertia=m_s * r2**2, **kw)

    def describe(self):
        return (
            f"a flexible secondary shaft: torsional stiffness {float(self.stiffness):.4g} N m/rad "
            f"to a far inertia {float(self.inertia):.4g} kg m², loss factor {self.loss_factor:g}, "
            f"{100 * self.drag_share:.0f} % of the drag on the far inertia"
        )

    def coupled(self, t, q, v, state, f_gear, model: RattleModel, params, drive):
        kappa = self.stiffness / model.r2**2
        m_s = self.inertia / model.r2**2
        omega = jnp.sqrt(kappa * (1 / model.mass + 1 / m_s))
        f_shaft = kappa * state[0] + self.loss_factor * kappa / omega * state[1]
        moved = self.drag_share * params.drag_torque / model.r2  # from the gear to the far end
        phi_ddot = -(f_shaft + moved) / m_s - (f_gear + moved + f_shaft) / model.mass
        return f_shaft + moved, jnp.stack([state[1], phi_ddot])


class RippleDrive(Drive):
    """A drive whose primary shaft carries an angle ripple locked to its rotation:
    ``θ1 = θb + A sin(n θb + φ)``, θb(t) the Fourier drive's angle (rad). The ripple is in the
    shaft's real motion, so the primary encoder records it and the driven wheel feels its
    acceleration, about ``n² Ω² A`` (rad/s²) at the mean speed Ω. ``ripple_angle`` A (rad),
    ``ripple_phase`` φ (rad), ``ripple_order`` n (static)."""

    ripple_angle: jax.Array
    ripple_phase: jax.Array
    ripple_order: int = eqx.field(static=True)

    def __init__(self, base: Drive, order: int, acceleration: float, phase: float = 0.0):
        super().__init__(
            base.mean_speed, base.frequency, base.cos_coeffs, base.sin_coeffs, base.offset
        )
        self.ripple_order = int(order)
        self.ripple_angle = _array(acceleration / (order * float(base.mean_speed)) ** 2)
        self.ripple_phase = _array(phase)

    def _base(self):
        return Drive(self.mean_speed, self.frequency, self.cos_coeffs, self.sin_coeffs, self.offset)

    @property
    def ripple_acceleration(self) -> float:
        """n² Ω² A, rad/s²."""
        return float(self.ripple_angle) * (self.ripple_order * float(self.mean_speed)) ** 2

    def describe(self):
        return (
            f"an angle ripple of the primary shaft at order {self.ripple_order} of its rotation, "
            f"θ1 = θb + A sin({self.ripple_order} θb + φ), A = {float(self.ripple_angle) * 1e3:.3g}"
            f" mrad, φ = {float(self.ripple_phase):.2f} rad (acceleration amplitude "
            f"{self.ripple_acceleration:.0f} rad/s² at the mean speed; in the primary encoder and "
            "in the forcing)"
        )

    def angle(self, t):
        tb = self._base().angle(t)
        return tb + self.ripple_angle * jnp.sin(self.ripple_order * tb + self.ripple_phase)

    def speed(self, t):
        base = self._base()
        tb, wb = base.angle(t), base.speed(t)
        n = self.ripple_order
        return wb * (1.0 + n * self.ripple_angle * jnp.cos(n * tb + self.ripple_phase))

    def acceleration(self, t):
        base = self._base()
        tb, wb, ab = base.angle(t), base.speed(t), base.acceleration(t)
        n, a = self.ripple_order, self.ripple_angle
        ph = n * tb + self.ripple_phase
        return ab * (1.0 + n * a * jnp.cos(ph)) - n * n * a * wb * wb * jnp.sin(ph)

    def angle_and_acceleration(self, t):
        return self.angle(t), self.acceleration(t)


# --- drives ---------------------------------------------------------------------------------


def speed_law_drive(mean_speed: float, frequency: float, harmonics) -> Drive:
    """The drive of the speed law ``ω(t) = Ω + Σ_k a_k sin(2π k f t + ψ_k)`` with θ1(0) = 0.

    ``harmonics`` is ``[(k, a_k in rad/s, ψ_k in rad), ...]``; ``[(1, ΔΩ, 0)]`` is the
    commanded law of eq. (9) (:meth:`Drive.commanded`). A motor that lags its command by φ
    has ψ_1 = −φ.
    """
    order = max(k for k, _, _ in harmonics)
    cos_c, sin_c = np.zeros(order), np.zeros(order)
    w = 2 * math.pi * frequency
    for k, amplitude, phase in harmonics:
        cos_c[k - 1] += -amplitude * math.cos(phase) / (k * w)
        sin_c[k - 1] += amplitude * math.sin(phase) / (k * w)
    return Drive(mean_speed, frequency, cos_c, sin_c, offset=-float(cos_c.sum()))


# --- cases ----------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Case:
    """One recording of a set: operating point, model form, effects and seed.

    ``motor`` is the primary shaft's real speed law against the command, as ``[(k, a_k / ΔΩ,
    ψ_k in degrees), ...]`` (see :func:`speed_law_drive`); ``shape_factor`` multiplies the
    default C_a; ``min_film`` is h_min in m; ``ripple`` is ``(order, acceleration in rad/s²,
    phase in rad)`` of a :class:`RippleDrive`, or None.
    """

    pair: str
    lubrication: str
    center_distance_mm: float
    fluctuation_pct: float
    frequency_hz: float
    drag_torque: float
    oil_temperature_c: float
    seed: int
    tag: str
    solver: str = "smoothed"
    motor: tuple[tuple[int, float, float], ...] = ((1, 1.0, 0.0),)
    shape_factor: float = 1.0
    min_film: float = DEFAULT_MIN_FILM
    stiffness_scale: float = 1.0
    effects: tuple[InjectedEffect, ...] = field(default=())
    ripple: tuple[int, float, float] | None = None

    @property
    def name(self) -> str:
        lub = self.lubrication.replace("_", "")
        return (
            f"pair{self.pair}_{lub}_{self.center_distance_mm:.1f}_{self.fluctuation_pct:g}pct_"
            f"{self.frequency_hz:g}Hz_{self.tag}"
        )

    def geometry(self) -> GearGeometry:
        """The pair as built (C_a scaled); the file's metadata are the same pair's."""
        g = table2_pair(self.pair, center_distance_mm=self.center_distance_mm)
        return g.replace(stiffness_shape=DEFAULT_STIFFNESS_SHAPE * self.shape_factor)

    def operating(self) -> OperatingPoint:
        return OperatingPoint(
            self.lubrication,
            self.oil_temperature_c,
            MEAN_SPEED,
            MEAN_SPEED * self.fluctuation_pct / 100.0,
            self.frequency_hz,
        )

    def viscosity(self) -> float:
        """μ at the oil temperature (the paper's oil), Pa s."""
        o = PAPER_OIL
        return dynamic_viscosity(
            self.oil_temperature_c, o.viscosity_40c_cst, o.viscosity_100c_cst, o.density_kg_m3
        )

    def params(self) -> RattleParams:
        return RattleParams(
            FILM[self.lubrication],
            self.drag_torque,
            self.viscosity(),
            self.geometry().backlash,
            min_film=self.min_film,
            stiffness_scale=self.stiffness_scale,
        )

    def drive(self) -> Drive:
        """The primary shaft's real motion (not the commanded law the file states)."""
        amp = MEAN_SPEED * self.fluctuation_pct / 100.0
        laws = [(k, a * amp, math.radians(p)) for k, a, p in self.motor]
        drive = speed_law_drive(MEAN_SPEED, self.frequency_hz, laws)
        if self.ripple is not None:
            drive = RippleDrive(drive, *self.ripple)
        return drive

    def expected(self) -> list[str]:
        if not self.effects and self.ripple is None:
            return list(CLEAN)
        names = [list(e.expected) for e in self.effects]
        if self.ripple is not None:
            names.append(["drive_ripple"])
        return ["+".join(combo) for combo in itertools.product(*names)]

    def motor_text(self) -> str:
        if self.motor == ((1, 1.0, 0.0),):
            return "the commanded speed law"
        parts = []
        for k, a, p in self.motor:
            if k == 1:
                lag = f" lagging the command by {-p:g}°" if p else ""
                parts.append(f"{100 * a:g} % of the commanded ΔΩ{lag}")
            else:
                parts.append(f"a harmonic {k} of {100 * a:g} % of ΔΩ (phase {p:g}°)")
        return "a motor that does not follow its command: " + ", ".join(parts)

    def truth(self) -> dict:
        """The truth entry (see the module notes)."""
        g = self.geometry()
        solver = (
            "the sharp reference solver (scipy DOP853, contact switches located as events, "
            "rtol 1e-8)"
            if self.solver == "reference"
            else "rattlefit's smoothed diffrax solver (rtol 1e-7)"
        )
        model = (
            f"C_a = {g.stiffness_shape:.3g} ({self.shape_factor:g} × default), h_min = "
            f"{self.min_film * 1e6:.3g} µm, stiffness scale {self.stiffness_scale:g}"
        )
        parts = [f"{solver}; drive: {self.motor_text()}; {model}"]
        parts += [e.describe() for e in self.effects]
        drive = self.drive()
        if isinstance(drive, RippleDrive):
            parts.append(drive.describe())
        effects = [{"name": e.name, **e.sizes()} for e in self.effects]
        omega2 = MEAN_SPEED * g.pitch_radius_driving / g.pitch_radius_driven
        for e, entry in zip(self.effects, effects, strict=True):
            if isinstance(e, PowerLawDrag):  # the catalogue's coefficient at the mean speed
                entry["slope_N_m_s_per_rad"] = e.exponent * self.drag_torque / omega2
        if isinstance(drive, RippleDrive):
            effects.append(
                {
                    "name": f"drive_ripple_order{drive.ripple_order}",
                    "order": drive.ripple_order,
                    "ripple_angle_rad": float(drive.ripple_angle),
                    "ripple_phase_rad": float(drive.ripple_phase),
                    "acceleration_rad_s2": drive.ripple_acceleration,
                }
            )
        return {
            "a_mm": FILM[self.lubrication] * 1e3,
            "drag_torque_Nm": self.drag_torque,
            "viscosity_Pa_s": round(self.viscosity(), 4),
            "unmodelled_effects": [e["name"] for e in effects],
            "expected": self.expected(),
            "form": "; ".join(parts) + f"; backlash {g.backlash * 1e6:.0f} µm; seed {self.seed}",
            "model": {
                "solver": self.solver,
                "stiffness_shape": g.stiffness_shape,
                "min_film_m": self.min_film,
                "stiffness_scale": self.stiffness_scale,
                "motor": [list(m) for m in self.motor],
                "backlash_m": g.backlash,
            },
            "effects": effects,
            "seed": self.seed,
        }


def _mean_stiffness(pair: str, cd: float, scale: float = 1.0) -> float:
    """K̄ of the pair at centre distance ``cd`` (mm), N/m."""
    return table2_pair(pair, center_distance_mm=cd).mesh_stiffness_iso * scale


def clean_cases() -> list[Case]:
    """The clean set: no unmodelled effect, the model form off rattlefit's fitted one.

    Nine by the sharp reference solver, nine by the smoothed one; ``motor`` entries are
    (harmonic, amplitude / ΔΩ, phase in degrees) of the real speed law.
    """
    um = 1e-6
    ref = dict(solver="reference", tag="ref")
    smooth = dict(solver="smoothed", tag="smooth")
    return [
        Case("II", "boundary", 65.2, 15, 12, 0.025, 20.0, 101, **ref),
        Case("I", "boundary", 65.6, 20, 8, 0.030, 21.0, 102, **ref, motor=((1, 0.97, -25),)),
        Case(
            "II", "oil_jet", 65.8, 10, 16, 0.022, 23.0, 103, **ref,
            shape_factor=1.25, min_film=4 * um, stiffness_scale=0.85,
        ),
        Case(
            "I", "oil_jet", 65.0, 15, 4, 0.035, 25.0, 104, **ref,
            motor=((1, 1.0, 0), (2, 0.06, 40)), min_film=1.2 * um, stiffness_scale=1.2,
        ),
        Case(
            "II", "dry", 65.4, 20, 8, 0.028, 20.0, 105, **ref,
            shape_factor=0.75, stiffness_scale=1.15,
        ),
        Case("I", "dry", 65.8, 15, 12, 0.032, 20.0, 106, **ref, motor=((1, 1.0, -40),)),
        Case(
            "II", "boundary", 66.0, 12, 6, 0.020, 22.0, 107, **ref,
            motor=((1, 1.0, 0), (2, 0.04, -60)), min_film=5 * um,
        ),
        Case(
            "I", "boundary", 65.3, 18, 10, 0.027, 20.0, 108, **ref,
            shape_factor=1.3, min_film=3 * um, stiffness_scale=0.75,
        ),
        Case(
            "I", "oil_jet", 65.5, 10, 8, 0.034, 23.0, 109, **ref,
            motor=((1, 1.0, -15),), shape_factor=1.1, min_film=2.5 * um,
        ),
        Case(
            "II", "boundary", 65.5, 20, 14, 0.024, 20.0, 110, **smooth,
            motor=((1, 0.95, -30),), shape_factor=0.8,
        ),
        Case(
            "I", "boundary", 65.9, 10, 16, 0.030, 20.0, 111, **smooth,
            motor=((1, 1.0, 0), (2, 0.05, 90)), min_film=1.0 * um, stiffness_scale=1.25,
        ),
        Case(
            "II", "oil_jet", 65.1, 18, 8, 0.030, 24.0, 112, **smooth,
            shape_factor=1.2, min_film=6 * um, stiffness_scale=0.7,
        ),
        Case(
            "I", "oil_jet", 65.7, 12, 12, 0.025, 22.0, 113, **smooth,
            motor=((1, 1.03, -20),), shape_factor=0.7,
        ),
        Case(
            "II", "dry", 65.0, 16, 16, 0.035, 20.0, 114, **smooth,
            motor=((1, 1.0, 0), (2, 0.03, 0)), stiffness_scale=0.8,
        ),
        Case(
            "I", "dry", 66.0, 20, 6, 0.020, 20.0, 115, **smooth,
            shape_factor=1.3, stiffness_scale=1.3,
        ),
        Case(
            "II", "boundary", 65.7, 14, 4, 0.033, 21.0, 116, **smooth,
            motor=((1, 0.98, -35), (2, 0.04, 30)), min_film=1.5 * um,
        ),
        Case(
            "I", "boundary", 65.1, 16, 14, 0.021, 20.0, 117, **smooth,
            shape_factor=0.85, min_film=4 * um, stiffness_scale=0.9,
        ),
        Case(
            "II", "oil_jet", 65.3, 20, 10, 0.027, 25.0, 118, **smooth,
            motor=((1, 1.0, 0), (2, 0.06, -120)), stiffness_scale=1.1,
        ),
    ]  # fmt: skip


def injected_cases() -> list[Case]:
    """The injected set: effects in other forms than the catalogue's, by the smoothed solver,
    with some of the clean set's model-form differences mixed in."""
    um = 1e-6

    def play(pair, cd):  # 2 tan αwt: backlash opened per metre of centre distance
        return 2 * math.tan(table2_pair(pair, center_distance_mm=cd).operating_pressure_angle)

    def hunt_crossley(pair, cd, restitution):
        return HuntCrossleyDamping.for_restitution(restitution, _mean_stiffness(pair, cd))

    return [
        Case(
            "II", "dry", 65.6, 20, 16, 0.025, 20.0, 201, "huntcrossley",
            effects=(hunt_crossley("II", 65.6, 0.8),),
        ),
        Case(
            "I", "dry", 65.2, 15, 12, 0.030, 20.0, 202, "huntcrossley",
            motor=((1, 1.0, -20),), shape_factor=1.15,
            effects=(hunt_crossley("I", 65.2, 0.75),),
        ),
        Case(
            "II", "dry", 65.3, 18, 10, 0.028, 20.0, 203, "friction_arctan",
            stiffness_scale=0.9, effects=(ArctanFriction(coefficient=0.2),),
        ),
        Case(
            "I", "dry", 65.8, 20, 16, 0.030, 20.0, 204, "friction_stribeck",
            effects=(StribeckFriction(static=0.3, kinetic=0.12),),
        ),
        Case(
            "II", "boundary", 65.4, 20, 16, 0.025, 20.0, 205, "runout_driven_oval",
            min_film=3 * um,
            effects=(WheelRunout(
                eccentricity=20 * um, ovality=8 * um, eccentricity_phase=0.7,
                ovality_phase=2.0, wheel="driven",
            ),),
        ),
        Case(
            "I", "boundary", 65.6, 15, 8, 0.030, 21.0, 206, "runout_driving_oval",
            motor=((1, 1.0, -25),),
            effects=(WheelRunout(
                eccentricity=10 * um, ovality=5 * um, eccentricity_phase=-1.2,
                ovality_phase=0.4, wheel="driving",
            ),),
        ),
        Case(
            "II", "oil_jet", 65.8, 20, 12, 0.025, 24.0, 207, "runout_driven_radial",
            shape_factor=0.8,
            effects=(WheelRunout(
                eccentricity=15 * um, eccentricity_phase=2.5, wheel="driven",
                play_factor=play("II", 65.8),
            ),),
        ),
        Case(
            "II", "boundary", 65.2, 15, 12, 0.025, 20.0, 208, "ripple_order3",
            ripple=(3, 150.0, 0.5),
        ),
        Case(
            "I", "boundary", 65.9, 20, 16, 0.030, 20.0, 209, "ripple_order1",
            motor=((1, 1.0, 0), (2, 0.04, 45)), ripple=(1, 150.0, -1.0),
        ),
        Case(
            "II", "oil_jet", 65.5, 20, 16, 0.025, 22.0, 210, "drift_linear",
            effects=(LinearViscosityDrift(rate=1 / 6),),
        ),
        Case(
            "I", "boundary", 65.4, 20, 8, 0.030, 20.0, 211, "drift_temperature",
            min_film=1.5 * um, effects=(TemperatureRamp(rate=6.0, start_c=20.0),),
        ),
        Case(
            "I", "oil_jet", 65.2, 20, 12, 0.030, 23.0, 212, "drag_sqrt",
            effects=(PowerLawDrag(exponent=0.5),),
        ),
        Case(
            "II", "boundary", 65.6, 18, 8, 0.025, 20.0, 213, "drag_churning",
            stiffness_scale=1.15, effects=(PowerLawDrag(exponent=2.0),),
        ),
        Case(
            "II", "boundary", 65.4, 20, 16, 0.025, 20.0, 214, "notch_triangle",
            effects=(DrivenToothNotch(depth=25 * um, position=1.0, shape="triangle"),),
        ),
        Case(
            "II", "oil_jet", 65.0, 15, 8, 0.025, 22.0, 215, "notch_step",
            motor=((1, 0.96, -30),),
            effects=(DrivenToothNotch(depth=20 * um, position=-2.0, shape="step"),),
        ),
        Case(
            "II", "dry", 65.2, 20, 12, 0.025, 20.0, 216, "runout_huntcrossley",
            effects=(
                WheelRunout(
                    eccentricity=16 * um, ovality=6 * um, eccentricity_phase=0.3,
                    ovality_phase=-1.0, wheel="driven",
                ),
                hunt_crossley("II", 65.2, 0.8),
            ),
        ),
        Case(
            "I", "oil_jet", 65.6, 20, 16, 0.030, 22.0, 217, "runout_drift",
            effects=(
                WheelRunout(
                    eccentricity=10 * um, eccentricity_phase=1.5, wheel="driving",
                    play_factor=play("I", 65.6),
                ),
                LinearViscosityDrift(rate=1 / 6),
            ),
        ),
        Case(
            "II", "boundary", 65.6, 20, 16, 0.025, 20.0, 218, "flexible_shaft",
            effects=(FlexibleShaft.for_mode("II", 65.6, 350.0, 1.0),),
        ),
    ]  # fmt: skip


CASES = {"clean": clean_cases, "injected": injected_cases}


# --- building -------------------------------------------------------------------------------


def title(case: Case) -> str:
    """The file's title, as the shared recordings word theirs."""
    return f"pair {case.pair}, {case.lubrication}, centre distance {case.center_distance_mm:.1f} mm"


def build_case(case: Case, directory: Path, *, duration: float = DURATION) -> Path:
    """Simulate ``case`` and write ``<directory>/<case.name>.h5`` (no ``/truth`` group: the
    truth is in the set's ``truth.json``). Returns the path."""
    g, op, params, drive = case.geometry(), case.operating(), case.params(), case.drive()
    if case.solver == "reference":
        if case.effects or case.ripple is not None:
            raise ValueError(f"{case.name}: the reference solver takes no effects")
        # released across the gap from the case's seed, as synthesize does
        rng = np.random.default_rng(case.seed)
        c = 0.5 * g.backlash
        y0 = (rng.uniform(-c, c), 0.0)
        sol = simulate_reference(
            g,
            drive,
            film_half_length=float(params.film_half_length),
            drag_torque=float(params.drag_torque),
            viscosity=float(params.viscosity),
            backlash=float(params.backlash),
            min_film=float(params.min_film),
            stiffness_scale=float(params.stiffness_scale),
            duration=duration,
            initial_state=y0,
        )
        theta1 = jax.vmap(drive.angle)(jnp.asarray(sol.time))
        rec = recording_from_trajectory(
            g,
            op,
            theta1,
            sol.q,
            zeros=rng.integers(-(10**6), 10**6, size=2),
            title=title(case),
        )
    else:
        rec, _ = synthesize(
            g,
            op,
            params,
            drive=drive,
            duration=duration,
            seed=case.seed,
            title=title(case),
            effects=case.effects,
        )
    path = Path(directory) / f"{case.name}.h5"
    write_recording(rec, path)
    return path


def configure_one_core() -> None:
    """A worker's set-up: rattlefit's configuration on one JAX device."""
    configure(cpu_cores=1)


def _build_named(which: str, name: str, directory: str) -> tuple[str, float]:
    """Build the case ``name`` of set ``which`` (a worker's job); returns (name, seconds)."""
    case = next(c for c in CASES[which]() if c.name == name)
    t0 = time.perf_counter()
    build_case(case, Path(directory))
    return name, time.perf_counter() - t0


def truth_entries(which: str) -> dict[str, dict]:
    """Name → truth entry of every case of set ``which``."""
    cases = CASES[which]()
    names = [c.name for c in cases]
    if len(set(names)) != len(names):
        raise ValueError(f"set {which}: duplicate names")
    return {c.name: c.truth() for c in cases}


def build_set(which: str, *, jobs: int = 1, say=None) -> list[tuple[Path, dict]]:
    """Build what is missing of set ``which``, write its ``truth.json``, and return
    ``[(path, truth), ...]`` in the set's order. A recording whose truth entry differs from
    the one in the existing ``truth.json`` is built again. ``say`` receives progress lines."""
    say = say or (lambda s: None)
    directory = CACHE / which
    directory.mkdir(parents=True, exist_ok=True)
    truth = truth_entries(which)
    text = json.dumps(truth, indent=2, ensure_ascii=False) + "\n"
    truth_file = directory / "truth.json"
    old = json.loads(truth_file.read_text()) if truth_file.is_file() else None
    if old != truth:
        for n, entry in truth.items():  # a case whose truth changed is built again
            if old is not None and old.get(n) != entry:
                (directory / f"{n}.h5").unlink(missing_ok=True)
        truth_file.write_text(text)
    missing = [n for n in truth if not (directory / f"{n}.h5").is_file()]
    for n in truth:
        if n not in missing:
            say(f"{which}/{n}: exists")
    if jobs > 1 and len(missing) > 1:
        with ProcessPoolExecutor(
            jobs, mp_context=get_context("spawn"), initializer=configure_one_core
        ) as pool:
            futures = [pool.submit(_build_named, which, n, str(directory)) for n in missing]
            for f in futures:
                n, seconds = f.result()
                say(f"{which}/{n}: {seconds:.1f} s")
    else:
        for n in missing:
            _, seconds = _build_named(which, n, str(directory))
            say(f"{which}/{n}: {seconds:.1f} s")
    return [(directory / f"{n}.h5", entry) for n, entry in truth.items()]


def shared_clean() -> list[tuple[Path, dict]]:
    """The shared 3 s recordings without an unmodelled effect (not ``long/``), with their
    truth, ``expected`` and ``form``."""
    path = recordings_dir(REPO) / "truth.json"
    if not path.is_file():
        return []
    out = []
    for name, entry in json.loads(path.read_text()).items():
        file = recordings_dir(REPO) / f"{name}.h5"
        if entry["unmodelled_effects"] or not file.is_file():
            continue
        form = "the independent simulator's recording (../shared/recordings)"
        out.append((file, {**entry, "expected": list(CLEAN), "form": form}))
    return out


def clean_set(include_shared: bool = False, *, jobs: int = 1, say=None):
    """The clean set as ``[(path, truth), ...]``, built first where missing; with
    ``include_shared`` the shared clean 3 s recordings follow."""
    out = build_set("clean", jobs=jobs, say=say)
    return out + shared_clean() if include_shared else out


def injected_set(*, jobs: int = 1, say=None):
    """The injected set as ``[(path, truth), ...]``, built first where missing."""
    return build_set("injected", jobs=jobs, say=say)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", choices=("clean", "injected", "all"), default="all")
    ap.add_argument("--jobs", type=int, default=1, help="processes building at once")
    args = ap.parse_args()
    configure()
    say = lambda s: print(s, file=sys.stderr, flush=True)  # noqa: E731
    which = SETS if args.set == "all" else (args.set,)
    t0 = time.perf_counter()
    for w in which:
        for path, truth in build_set(w, jobs=args.jobs, say=say):
            print(f"{w}/{path.name}\t{' | '.join(truth['expected'])}")
    say(f"done in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
