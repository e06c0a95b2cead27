"""Load sharing over the contact lines of a helical pair, tabulated against the mesh position.

The plane of action is the rectangle [0, ε_α] (transverse path of contact, in base pitches)
× [0, b] (face width). Tooth pair j's contact line crosses it diagonally: at mesh position u
(the pinion's roll in base pitches, u = z1 θ1 / 2π + u0) the line runs from path position
s = u − j at one face edge to s − ε_β at the other. The pair carries the part of the line that
lies inside the rectangle, [lo, hi] = clip([s − ε_β, s], 0, ε_α), of length
``(hi − lo) · b / (ε_β cos β_b)``.

* **Stiffness.** Per unit length of contact line the flanks are stiffest mid-profile and
  softer at tip and root, ``w(s) = 1 − κ (2 s/ε_α − 1)²``; the pairs in contact act in
  parallel, so the mesh stiffness is the sum over pairs of ``∫_lo^hi w``, scaled so that its
  mean over a base pitch is ISO 6336's c_γα·b. One, two or three pairs share the load as
  their lines enter and leave (rattlefit's eq. (4) is a different law: a product of smoothed
  windows and exp(C_a|·|³)).
* **Film.** Every pair in the mesh zone has a squeeze film along its contact line; the film
  law (:mod:`rig_film`) needs ``Σ ∫ R_n(s)^{3/2} dl`` and the length-weighted curvature.
* **Coast flanks** use the same laws with the pairs offset by ``coast_offset`` base pitches
  and the path run backwards.
* **Tooth defect** (optional): a pitted band across the face on the drive flank of given
  driven teeth softens their line by a factor (1 − softening) where it crosses the band, and
  a raised burr (nick) on the band's edge stands proud of the flank by its height over a
  short stretch of the face: a separate small contact spring with a kinematic offset.

The tables run over z2 base pitches (pair j meshes driven tooth j mod z2), ``per_pitch``
rows a pitch plus one wrap row; they are read by linear interpolation (:mod:`rig_solver`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .rig_geometry import Pair

#: Rows per base pitch of the tables.
PER_PITCH = 128
#: The table columns, in order.
COLUMNS = (
    "k_drive",
    "k_coast",
    "lr_drive",
    "lr_coast",
    "reff_drive",
    "reff_coast",
    "k_burr",
    "e_burr",
)


@dataclass(frozen=True)
class ToothDefect:
    """Pitting band with a raised burr on the drive flank of some driven teeth.

    teeth : driven tooth indices (0 … z2−1) that carry it; heights : burr height on each, m;
    band : (start, end) of the pitted band along the path as fractions of ε_α; softening : the
    fraction of the line's stiffness lost inside the band; burr_face : the burr's centre across
    the face as a fraction of b; burr_length : its extent across the face, m; burr_contact :
    the contact-line length that carries the burr's load, m.
    """

    teeth: tuple[int, ...] = (0, 1)
    heights: tuple[float, ...] = (10e-6, 6e-6)
    band: tuple[float, float] = (0.35, 0.6)
    softening: float = 0.4
    burr_face: float = 0.5
    burr_length: float = 3e-3
    burr_contact: float = 1.5e-3


@dataclass(frozen=True)
class MeshLaw:
    """The pair's load-sharing law: ``kappa`` the stiffness drop at tip and root, and the coast
    flanks' pair offset ``coast_offset`` (base pitches)."""

    pair: Pair
    kappa: float = 0.35
    coast_offset: float = 0.5
    defect: ToothDefect | None = field(default=None)

    @property
    def length_per_pitch(self) -> float:
        """Contact-line length per base pitch of path, b / (ε_β cos β_b), m."""
        p = self.pair
        return p.face_width / (p.eps_beta * math.cos(p.beta_b))

    @property
    def line_stiffness(self) -> float:
        """c_L: stiffness per unit contact-line length at mid-profile, N/m²."""
        p = self.pair
        mean_w = 1.0 - self.kappa / 3.0
        return p.iso_mesh_stiffness / (self.length_per_pitch * p.eps_beta * p.eps_alpha * mean_w)

    def weight_integral(self, s):
        """∫₀^s w, with w(s) = 1 − κ(2s/ε_α − 1)² (base pitches)."""
        ea = self.pair.eps_alpha
        return s - self.kappa * ea * ((2 * s / ea - 1) ** 3 + 1) / 6.0

    def segments(self, u, offset=0.0):
        """(lo, hi, s) per pair of the lines at mesh positions ``u`` (N,): arrays (N, 5)."""
        p = self.pair
        j = np.floor(u + offset)[:, None] - np.arange(5)
        s = u[:, None] + offset - j
        lo = np.clip(s - p.eps_beta, 0.0, p.eps_alpha)
        hi = np.clip(s, 0.0, p.eps_alpha)
        return lo, hi, s, j

    def stiffness(self, lo, hi):
        """Each pair's stiffness, N/m, of its line's part [lo, hi] (arrays)."""
        w = self.weight_integral(hi) - self.weight_integral(lo)
        return self.line_stiffness * self.length_per_pitch * w

    def film_integrals(self, lo, hi, reverse: bool):
        """(Σ ∫ R_n^{3/2} dl in m^{2.5}, Σ length in m) over the pairs (arrays (N,))."""
        ea = self.pair.eps_alpha
        grid = np.linspace(0.0, ea, 2049)
        r = self.pair.curvature(ea - grid if reverse else grid)
        cum = np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] ** 1.5 + r[:-1] ** 1.5))])
        cum *= grid[1] - grid[0]
        lr = np.interp(hi, grid, cum) - np.interp(lo, grid, cum)
        scale = self.length_per_pitch
        return scale * lr.sum(axis=1), scale * (hi - lo).sum(axis=1)

    def defect_terms(self, lo, hi, s, j):
        """(stiffness lost to the pitted band, burr stiffness, burr height) per mesh position,
        from the defect's pairs (arrays (N,))."""
        n = lo.shape[0]
        if self.defect is None:
            return np.zeros(n), np.zeros(n), np.zeros(n)
        d, p = self.defect, self.pair
        tooth = np.mod(j, p.z2).astype(int)
        heights = dict(zip(d.teeth, d.heights, strict=True))
        on = np.isin(tooth, d.teeth)
        b0, b1 = (f * p.eps_alpha for f in d.band)
        cut_lo, cut_hi = np.maximum(lo, b0), np.minimum(hi, b1)
        lost = np.where(on & (cut_hi > cut_lo), self.stiffness(cut_lo, cut_hi), 0.0)
        # the burr sits on the band's upper edge; the line crosses it at face position z
        z = (s - b1) / p.eps_beta * p.face_width
        x = (z - d.burr_face * p.face_width) / (0.5 * d.burr_length)
        bump = np.where(np.abs(x) < 1, 0.5 * (1 + np.cos(np.pi * np.clip(x, -1, 1))), 0.0)
        h = np.array([heights.get(int(t), 0.0) for t in tooth.ravel()]).reshape(tooth.shape)
        height = (h * bump * on).max(axis=1)
        k_burr = np.where(height > 0, self.line_stiffness * d.burr_contact, 0.0)
        return d.softening * lost.sum(axis=1), k_burr, height

    def table(self, per_pitch: int = PER_PITCH) -> np.ndarray:
        """The mesh table over u ∈ [0, z2] (rows z2·per_pitch + 1, columns :data:`COLUMNS`)."""
        u = np.arange(self.pair.z2 * per_pitch + 1) / per_pitch
        lo, hi, s, j = self.segments(u)
        k_drive = self.stiffness(lo, hi).sum(axis=1)
        lr_d, len_d = self.film_integrals(lo, hi, reverse=False)
        lost, k_burr, e_burr = self.defect_terms(lo, hi, s, j)
        clo, chi, _, _ = self.segments(u, self.coast_offset)
        k_coast = self.stiffness(clo, chi).sum(axis=1)
        lr_c, len_c = self.film_integrals(clo, chi, reverse=True)
        reff_d = (lr_d / np.maximum(len_d, 1e-12)) ** (2 / 3)
        reff_c = (lr_c / np.maximum(len_c, 1e-12)) ** (2 / 3)
        return np.column_stack(
            [k_drive - lost, k_coast, lr_d, lr_c, reff_d, reff_c, k_burr, e_burr]
        )
