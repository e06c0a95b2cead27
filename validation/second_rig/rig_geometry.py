"""Involute geometry of the seed paper's two helical pairs (Table 2) and the paper's oil.

Everything here is derived independently of rattlefit, from the drawing data: Table 2's tooth
counts, face widths and pitch diameters, a normal module of 2 mm and a normal pressure angle
of 20° (the helix angle follows from d = z·mn/cos β). Lengths are in m, angles in rad.

* The backlash at a centre distance is the exact involute one (not a linearisation):
  ``j_wt = (a_w/a_0)·Δs + 2 a_w (inv α_wt − inv α_t)`` on the working pitch circle, with the
  pair's total tooth thinning Δs fitted to the paper's two stated backlashes (0.092 rad for
  pair I at 66.0 mm, 0.038 rad for pair II at 65.6 mm, Section 5).
* The relative motion is taken along the transverse line of action, ``x = rb2·θ2 − rb1·θ1``
  (base-circle arcs); the recorded Δθ* of eq. (6) is ``−x / rb1``.
* The mean mesh stiffness is ISO 6336-1's c_γα·b (method B, C_M = 0.8), applied along the
  line of action.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

KELVIN = 273.15

#: The paper's Table 2 (z, face width in mm, pitch diameter in mm) and the driven inertia the
#: rig's recordings state (kg m²).
TABLE2 = {
    "I": dict(z=(11, 43), b_mm=(17.0, 13.8), d_mm=(26.477, 103.501), driven_inertia=0.0016),
    "II": dict(z=(19, 41), b_mm=(13.5, 12.8), d_mm=(41.173, 88.847), driven_inertia=0.0009),
}
#: The paper's stated backlashes (Section 5): (centre distance in mm, angular backlash in rad).
PAPER_BACKLASH = {"I": (66.0, 0.092), "II": (65.6, 0.038)}
#: The paper's oil (Table 3): ν40, ν100 in cSt and density in kg/m³.
OIL = dict(viscosity_40c_cst=156.5, viscosity_100c_cst=15.7, density_kg_m3=890.0)
#: ISO 6336-1 theoretical-to-measured stiffness correction for solid blanks.
ISO_CM = 0.8


def involute(alpha):
    """inv α = tan α − α (rad)."""
    return np.tan(alpha) - alpha


@dataclass(frozen=True)
class Pair:
    """One gear pair of Table 2 at an operating centre distance ``cd`` (m)."""

    name: str
    cd: float

    # -- drawing data -----------------------------------------------------------------------
    @property
    def z1(self) -> int:
        return TABLE2[self.name]["z"][0]

    @property
    def z2(self) -> int:
        return TABLE2[self.name]["z"][1]

    @property
    def ratio(self) -> float:
        """z2 / z1."""
        return self.z2 / self.z1

    @property
    def mn(self) -> float:
        """Normal module, m."""
        return 2e-3

    @property
    def alpha_n(self) -> float:
        return math.radians(20.0)

    @property
    def r1(self) -> float:
        return TABLE2[self.name]["d_mm"][0] * 0.5e-3

    @property
    def r2(self) -> float:
        return TABLE2[self.name]["d_mm"][1] * 0.5e-3

    @property
    def face_width(self) -> float:
        """b: the common (smaller) face width, m."""
        return min(TABLE2[self.name]["b_mm"]) * 1e-3

    @property
    def driven_inertia(self) -> float:
        """Total inertia turning with the driven gear (the recordings' I2), kg m²."""
        return TABLE2[self.name]["driven_inertia"]

    @property
    def beta(self) -> float:
        """Helix angle at the reference circle, rad (d = z mn / cos β)."""
        return math.acos(2 * self.z1 * self.mn * 0.5 / (2 * self.r1))

    @property
    def alpha_t(self) -> float:
        """Transverse pressure angle at the reference circle, rad."""
        return math.atan(math.tan(self.alpha_n) / math.cos(self.beta))

    @property
    def beta_b(self) -> float:
        """Base helix angle, rad."""
        return math.atan(math.tan(self.beta) * math.cos(self.alpha_t))

    @property
    def rb1(self) -> float:
        return self.r1 * math.cos(self.alpha_t)

    @property
    def rb2(self) -> float:
        return self.r2 * math.cos(self.alpha_t)

    @property
    def a0(self) -> float:
        """Reference centre distance r1 + r2, m."""
        return self.r1 + self.r2

    @property
    def base_pitch(self) -> float:
        """Transverse base pitch p_bt = 2π rb1 / z1, m."""
        return 2 * math.pi * self.rb1 / self.z1

    # -- at the operating centre distance ------------------------------------------------------
    @property
    def alpha_w(self) -> float:
        """Working transverse pressure angle at ``cd``, rad."""
        return math.acos(self.a0 * math.cos(self.alpha_t) / self.cd)

    @property
    def path_start(self) -> float:
        """Distance from the pinion's base tangent point to the start of the active path, m."""
        ra2 = self.r2 + self.mn
        return self.cd * math.sin(self.alpha_w) - math.sqrt(ra2**2 - self.rb2**2)

    @property
    def eps_alpha(self) -> float:
        """Transverse contact ratio ε_α at ``cd``."""
        ra1 = self.r1 + self.mn
        return (math.sqrt(ra1**2 - self.rb1**2) - self.path_start) / self.base_pitch

    @property
    def eps_beta(self) -> float:
        """Overlap ratio ε_β = b sin β / (π mn)."""
        return self.face_width * math.sin(self.beta) / (math.pi * self.mn)

    def curvature(self, s):
        """Normal relative curvature radius R_n (m) of the flanks at path position ``s``
        (base pitches from the start of the active path; array): the transverse involute
        radii ρ1 = path_start + s·p_bt and ρ2 = a_w sin α_w − ρ1, combined as ρ1ρ2/(ρ1+ρ2)
        and divided by cos β_b (the section normal to the contact line)."""
        rho1 = self.path_start + np.asarray(s) * self.base_pitch
        rho2 = self.cd * math.sin(self.alpha_w) - rho1
        return rho1 * rho2 / (rho1 + rho2) / math.cos(self.beta_b)

    # -- backlash -----------------------------------------------------------------------------
    def backlash_angle(self, thinning: float | None = None) -> float:
        """True angular backlash at ``cd`` as the primary-shaft angle Δθ* (rad), for a total
        tooth thinning ``thinning`` (m; default the one fitted to the paper)."""
        ds = fitted_thinning(self.name) if thinning is None else thinning
        jwt = (self.cd / self.a0) * ds + 2 * self.cd * (
            involute(self.alpha_w) - involute(self.alpha_t)
        )
        rw1 = self.cd * self.z1 / (self.z1 + self.z2)
        return jwt / rw1

    @property
    def play(self) -> float:
        """Total play along the transverse line of action, rb1 × angular backlash, m."""
        return self.rb1 * self.backlash_angle()

    def play_slope(self) -> float:
        """d(play)/d(centre distance) at ``cd`` (dimensionless; about 2 sin α_w)."""
        h = 1e-7
        up, down = Pair(self.name, self.cd + h), Pair(self.name, self.cd - h)
        return (up.play - down.play) / (2 * h)

    # -- stiffness -------------------------------------------------------------------------
    @property
    def iso_mesh_stiffness(self) -> float:
        """c_γα·b of ISO 6336-1 (method B, C_M = 0.8, no profile shift), N/m."""
        cb = math.cos(self.beta)
        zn1, zn2 = self.z1 / cb**3, self.z2 / cb**3
        q = 0.04723 + 0.15551 / zn1 + 0.25791 / zn2  # mm·µm/N
        c_single = (1.0 / q) * ISO_CM * cb * 1e9  # N/m per m of face width
        return c_single * (0.75 * self.eps_alpha + 0.25) * self.face_width

    def rattlefit_curvature(self) -> float:
        """The relative curvature radius rattlefit's eq. (5) uses (transverse, at the working
        pitch point): ρi = r_wi sin α_w, R = ρ1ρ2/(ρ1+ρ2), m. For the film mapping only."""
        rw1 = self.cd / (1 + self.ratio)
        s = math.sin(self.alpha_w)
        rho1, rho2 = rw1 * s, rw1 * self.ratio * s
        return rho1 * rho2 / (rho1 + rho2)


def fitted_thinning(name: str) -> float:
    """Total tooth thinning Δs (m) of pair ``name`` that gives the paper's stated backlash."""
    cd_mm, angle = PAPER_BACKLASH[name]
    pair = Pair(name, cd_mm * 1e-3)
    return optimize.brentq(lambda ds: pair.backlash_angle(ds) - angle, -1e-3, 2e-3, xtol=1e-14)


def kinematic_viscosity_cst(temperature_c, nu40=OIL["viscosity_40c_cst"], nu100=None):
    """ν (cSt) of the paper's oil at ``temperature_c`` (°C, array) by ASTM D341 (Walther)."""
    nu100 = OIL["viscosity_100c_cst"] if nu100 is None else nu100
    x40, x100 = math.log10(40 + KELVIN), math.log10(100 + KELVIN)
    y40 = math.log10(math.log10(nu40 + 0.7))
    y100 = math.log10(math.log10(nu100 + 0.7))
    slope = (y40 - y100) / (x100 - x40)
    y = y40 - slope * (np.log10(np.asarray(temperature_c) + KELVIN) - x40)
    return 10.0 ** (10.0**y) - 0.7


def dynamic_viscosity(temperature_c):
    """μ (Pa s) of the paper's oil at ``temperature_c`` (°C, array): ρ ν."""
    return OIL["density_kg_m3"] * kinematic_viscosity_cst(temperature_c) * 1e-6
