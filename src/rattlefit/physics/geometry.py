"""Gear-pair geometry of a helical involute pair, from a recording's metadata.

Everything the one-dof model of the seed paper needs and that follows from the drawing of the
gears: radii, transverse pressure angles, contact ratios, the relative curvature radius ``R``
and axial width ``Z`` of eq. (5), the circumferential backlash, the driven gear's equivalent
mass, and a default mesh stiffness after ISO 6336-1 (method B) so that the mesh mode lands
where the paper estimates it (about 3400 Hz).

Conventions (SI throughout, lengths in m):

* ``r1``, ``r2`` are the reference pitch radii of the driving and driven gear; the model's
  coordinate is the relative displacement on the pitch circle ``q = r2·θ2 − r1·θ1``, i.e. the
  paper's ``r2·Δθ`` of eq. (1).
* The recording's ``angular_backlash_rad`` is the total play expressed as primary-shaft angle
  Δθ* (eq. 6); the circumferential backlash is ``r1`` times it (the paper's Fig. 7), and the
  flank gap on either side of the centred position is half of that.
* Tip radii assume standard addendum (ha* = 1, no profile shift): the recorded pitch diameters
  add up to the design centre distance of 65 mm for both pairs of Table 2.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

from ..errors import ParameterError

if TYPE_CHECKING:  # pragma: no cover
    from ..io.recording import GearPairSpec

#: ISO 6336-1 factors for solid gear blanks and a standard basic rack.
_ISO_CM = 0.8  # theoretical-to-measured correction
#: Shape coefficient of the single-pair stiffness law, eq. (4) of the seed paper. The paper
#: leaves it to its Ref. [11]; −1.8 makes a pair's stiffness at the ends of its engagement about
#: half the pitch-point value for both pairs of Table 2. The fit scales the whole stiffness.
DEFAULT_STIFFNESS_SHAPE = -1.8


@dataclasses.dataclass(frozen=True)
class GearGeometry:
    """Derived geometry of one helical gear pair (immutable; all lengths in m, angles in rad).

    Build it with :meth:`from_spec` (from a recording) or :func:`table2_pair` (the seed paper's
    Table 2); the constructor checks that the values are physical.
    """

    teeth_driving: int
    teeth_driven: int
    pitch_radius_driving: float  #: r1, m
    pitch_radius_driven: float  #: r2, m
    normal_module: float  #: m
    normal_pressure_angle: float  #: rad
    helix_angle: float  #: rad
    face_width: float  #: Z of eq. (5): the common (smaller) face width, m
    center_distance: float  #: operating centre distance, m
    driven_inertia: float  #: I2, kg m²
    angular_backlash: float  #: total play as primary-shaft angle Δθ*, rad
    angular_backlash_std: float | None = None  #: its standard uncertainty, rad
    stiffness_shape: float = DEFAULT_STIFFNESS_SHAPE  #: C_a of eq. (4), dimensionless

    def __post_init__(self) -> None:
        checks = {
            "teeth_driving": self.teeth_driving >= 5,
            "teeth_driven": self.teeth_driven >= 5,
            "pitch_radius_driving": self.pitch_radius_driving > 0,
            "pitch_radius_driven": self.pitch_radius_driven > 0,
            "normal_module": self.normal_module > 0,
            "normal_pressure_angle": 0 < self.normal_pressure_angle < math.pi / 4,
            "helix_angle": 0 <= self.helix_angle < math.pi / 3,
            "face_width": self.face_width > 0,
            "driven_inertia": self.driven_inertia > 0,
            "angular_backlash": self.angular_backlash > 0,
            "stiffness_shape": self.stiffness_shape < 0,
        }
        for name, ok in checks.items():
            if not (ok and np.isfinite(getattr(self, name))):
                raise ParameterError(
                    f"gear geometry: {name}={getattr(self, name)!r} is not physical"
                )
        if self.center_distance < 0.98 * self.reference_center_distance:
            raise ParameterError(
                f"gear geometry: centre distance {self.center_distance * 1e3:.3f} mm is below "
                f"the reference {self.reference_center_distance * 1e3:.3f} mm: the gears "
                "would interfere"
            )
        if not (self.transverse_contact_ratio > 0.5 and self.total_contact_ratio > 1.0):
            raise ParameterError(
                f"gear geometry: contact ratios εα={self.transverse_contact_ratio:.3f}, "
                f"ε={self.total_contact_ratio:.3f} at centre distance "
                f"{self.center_distance * 1e3:.3f} mm: the pair would lose contact"
            )

    # -- construction ---------------------------------------------------------------------
    @classmethod
    def from_spec(cls, spec: GearPairSpec) -> GearGeometry:
        """Geometry from the ``/gear_pair`` metadata of a recording."""
        return cls(
            teeth_driving=int(spec.teeth_driving),
            teeth_driven=int(spec.teeth_driven),
            pitch_radius_driving=spec.pitch_diameter_driving_mm * 0.5e-3,
            pitch_radius_driven=spec.pitch_diameter_driven_mm * 0.5e-3,
            normal_module=spec.normal_module_mm * 1e-3,
            normal_pressure_angle=math.radians(spec.normal_pressure_angle_deg),
            helix_angle=math.radians(spec.helix_angle_deg),
            face_width=min(spec.face_width_driving_mm, spec.face_width_driven_mm) * 1e-3,
            center_distance=spec.center_distance_mm * 1e-3,
            driven_inertia=spec.driven_inertia_kg_m2,
            angular_backlash=spec.angular_backlash_rad,
            angular_backlash_std=spec.angular_backlash_std_rad,
        )

    def replace(self, **changes) -> GearGeometry:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    # -- radii and angles -------------------------------------------------------------------
    @property
    def gear_ratio(self) -> float:
        """z2 / z1 = r2 / r1 (the paper's transmission ratio ε of Table 2)."""
        return self.teeth_driven / self.teeth_driving

    @property
    def reference_center_distance(self) -> float:
        """(r1 + r2), m: the centre distance at which the pitch circles roll."""
        return self.pitch_radius_driving + self.pitch_radius_driven

    @property
    def transverse_pressure_angle(self) -> float:
        """αt = atan(tan αn / cos β), rad."""
        return math.atan(math.tan(self.normal_pressure_angle) / math.cos(self.helix_angle))

    @property
    def operating_pressure_angle(self) -> float:
        """Working transverse pressure angle αwt at the operating centre distance, rad."""
        c = self.reference_center_distance * math.cos(self.transverse_pressure_angle)
        return math.acos(min(1.0, c / self.center_distance))

    @property
    def base_radii(self) -> tuple[float, float]:
        """Base-circle radii (rb1, rb2), m."""
        c = math.cos(self.transverse_pressure_angle)
        return self.pitch_radius_driving * c, self.pitch_radius_driven * c

    @property
    def tip_radii(self) -> tuple[float, float]:
        """Tip radii (ra1, ra2) for a standard addendum of one normal module, m."""
        return (
            self.pitch_radius_driving + self.normal_module,
            self.pitch_radius_driven + self.normal_module,
        )

    @property
    def transverse_base_pitch(self) -> float:
        """pbt = π mn cos αt / cos β, m."""
        return (
            math.pi
            * self.normal_module
            * math.cos(self.transverse_pressure_angle)
            / math.cos(self.helix_angle)
        )

    @property
    def base_pitch_angle(self) -> float:
        """Θp = 2π / z1: the driving-shaft angle of one mesh cycle, rad."""
        return 2.0 * math.pi / self.teeth_driving

    @property
    def transverse_contact_ratio(self) -> float:
        """εα at the operating centre distance (the paper's ε_x)."""
        (rb1, rb2), (ra1, ra2) = self.base_radii, self.tip_radii
        path = (
            math.sqrt(ra1**2 - rb1**2)
            + math.sqrt(ra2**2 - rb2**2)
            - self.center_distance * math.sin(self.operating_pressure_angle)
        )
        return path / self.transverse_base_pitch

    @property
    def overlap_contact_ratio(self) -> float:
        """εβ = Z sin β / (π mn)."""
        return self.face_width * math.sin(self.helix_angle) / (math.pi * self.normal_module)

    @property
    def total_contact_ratio(self) -> float:
        """ε = εα + εβ (the paper's ε in eq. 4)."""
        return self.transverse_contact_ratio + self.overlap_contact_ratio

    # -- squeeze film (eq. 5) -------------------------------------------------------------
    @property
    def curvature_radius(self) -> float:
        """Relative curvature radius R of the flanks at the operating pitch point, m.

        Each flank is the cylinder of the involute's radius of curvature there,
        ρi = rwi · sin αwt (the paper's assumptions for eq. 5); R = ρ1ρ2/(ρ1+ρ2).
        """
        s = math.sin(self.operating_pressure_angle)
        rw1 = self.center_distance / (1.0 + self.gear_ratio)
        rho1, rho2 = rw1 * s, rw1 * self.gear_ratio * s
        return rho1 * rho2 / (rho1 + rho2)

    @property
    def axial_width(self) -> float:
        """Z of eq. (5): the common face width, m."""
        return self.face_width

    # -- backlash and inertia -------------------------------------------------------------
    @property
    def backlash(self) -> float:
        """Total circumferential backlash on the pitch circle, r1 · angular backlash, m."""
        return self.pitch_radius_driving * self.angular_backlash

    @property
    def backlash_std(self) -> float | None:
        """Standard uncertainty of :attr:`backlash`, m (None when the recording has none)."""
        if self.angular_backlash_std is None:
            return None
        return self.pitch_radius_driving * self.angular_backlash_std

    @property
    def equivalent_mass(self) -> float:
        """Driven gear inertia reduced to its pitch circle, I2 / r2², kg."""
        return self.driven_inertia / self.pitch_radius_driven**2

    # -- mesh stiffness (ISO 6336-1, method B) ----------------------------------------------
    @property
    def single_pair_stiffness_iso(self) -> float:
        """c′ of ISO 6336-1 per unit face width, N/(m·m) (c′th · C_M · cos β, C_R = C_B = 1)."""
        cb = math.cos(self.helix_angle)
        zn1 = self.teeth_driving / cb**3
        zn2 = self.teeth_driven / cb**3
        q = 0.04723 + 0.15551 / zn1 + 0.25791 / zn2  # mm·µm/N, no profile shift
        return (1.0 / q) * _ISO_CM * cb * 1e9  # N/(mm·µm) → N/m²

    @property
    def mesh_stiffness_iso(self) -> float:
        """Mean mesh stiffness cγα · Z = c′ (0.75 εα + 0.25) · Z, N/m."""
        eps_a = self.transverse_contact_ratio
        return self.single_pair_stiffness_iso * (0.75 * eps_a + 0.25) * self.face_width

    @property
    def pitch_point_stiffness(self) -> float:
        """k_p of eq. (4), N/m, chosen so that the mesh-cycle mean of K(θ1) is the ISO value."""
        eps, eps_a = self.total_contact_ratio, self.transverse_contact_ratio
        u = np.linspace(0.0, eps, 4001)  # engagement angle in base pitches
        shape = np.exp(self.stiffness_shape * np.abs((u - eps / 2) / (1.125 * eps_a)) ** 3)
        mean_per_pitch = np.trapezoid(shape, u)  # ∫ over one engagement / Θp
        return self.mesh_stiffness_iso / mean_per_pitch

    @property
    def mesh_frequency_hz(self) -> float:
        """Natural frequency of the mesh mode, sqrt(K̄/m)/(2π), Hz (the paper: ≈ 3400 Hz)."""
        return math.sqrt(self.mesh_stiffness_iso / self.equivalent_mass) / (2 * math.pi)

    def describe(self) -> dict[str, float]:
        """The derived quantities as a flat dict (SI units), for reports."""
        return {
            "gear_ratio": self.gear_ratio,
            "transverse_pressure_angle_deg": math.degrees(self.transverse_pressure_angle),
            "operating_pressure_angle_deg": math.degrees(self.operating_pressure_angle),
            "transverse_contact_ratio": self.transverse_contact_ratio,
            "overlap_contact_ratio": self.overlap_contact_ratio,
            "curvature_radius_m": self.curvature_radius,
            "axial_width_m": self.axial_width,
            "backlash_m": self.backlash,
            "equivalent_mass_kg": self.equivalent_mass,
            "mesh_stiffness_N_per_m": self.mesh_stiffness_iso,
            "mesh_frequency_hz": self.mesh_frequency_hz,
        }


#: Circumferential backlash of both pairs at their reference centre distance, m.
DESIGN_BACKLASH = 0.33e-3

#: The two gear pairs of the seed paper's Table 2. The paper gives z, face width and pitch
#: diameter; module, pressure and helix angle and the driven inertia are those of the rig's
#: recordings (mn = 2 mm, αn = 20°, β from d = z·mn / cos β).
TABLE2 = {
    "I": dict(
        teeth=(11, 43),
        face_width_mm=(17.0, 13.8),
        pitch_diameter_mm=(26.477, 103.501),
        driven_inertia_kg_m2=0.0016,
    ),
    "II": dict(
        teeth=(19, 41),
        face_width_mm=(13.5, 12.8),
        pitch_diameter_mm=(41.173, 88.847),
        driven_inertia_kg_m2=0.0009,
    ),
}


def table2_pair(
    pair: str,
    *,
    center_distance_mm: float = 65.0,
    angular_backlash_rad: float | None = None,
    angular_backlash_std_rad: float | None = 2e-4,
) -> GearGeometry:
    """Geometry of gear pair ``"I"`` or ``"II"`` of the seed paper's Table 2.

    When ``angular_backlash_rad`` is not given it follows from the centre distance by
    :func:`backlash_from_center_distance`.
    """
    if pair not in TABLE2:
        raise ParameterError(f"unknown gear pair {pair!r}: Table 2 has 'I' and 'II'")
    t = TABLE2[pair]
    z1, z2 = t["teeth"]
    d1, d2 = t["pitch_diameter_mm"]
    beta = math.acos(2.0 * z1 / d1)
    geometry = GearGeometry(
        teeth_driving=z1,
        teeth_driven=z2,
        pitch_radius_driving=d1 * 0.5e-3,
        pitch_radius_driven=d2 * 0.5e-3,
        normal_module=2e-3,
        normal_pressure_angle=math.radians(20.0),
        helix_angle=beta,
        face_width=min(t["face_width_mm"]) * 1e-3,
        center_distance=center_distance_mm * 1e-3,
        driven_inertia=t["driven_inertia_kg_m2"],
        angular_backlash=angular_backlash_rad or 1.0,
        angular_backlash_std=angular_backlash_std_rad,
    )
    if angular_backlash_rad is None:
        geometry = geometry.replace(angular_backlash=backlash_from_center_distance(geometry))
    return geometry


def backlash_from_center_distance(
    geometry: GearGeometry, design_backlash_m: float = DESIGN_BACKLASH
) -> float:
    """Angular backlash (primary-shaft angle, rad) at the geometry's centre distance.

    Opening the centre distance by Δa opens the circumferential backlash by 2·Δa·tan αt
    (the usual linearised involute relation); the pair has ``design_backlash_m`` at its
    reference centre distance. With the default this reproduces the paper's 0.092 rad for pair
    I at 66.0 mm and 0.038 rad for pair II at 65.6 mm (Section 5).
    """
    delta = geometry.center_distance - geometry.reference_center_distance
    jt = design_backlash_m + 2.0 * delta * math.tan(geometry.transverse_pressure_angle)
    return jt / geometry.pitch_radius_driving
