"""Squeeze film between approaching flanks: Reynolds' cylinder–plane film with cavitation.

Each contact line is a cylinder of the flanks' normal relative curvature radius R_n near a
plane, at normal gap h (m); the gap across the film is h + x²/(2R). Reynolds' equation for a
pure squeeze at approach speed V, with zero pressure at the film's edges x = ±a, gives the
force per unit line length (the textbook long-cylinder result, not the paper's eq. (5))

    F' = 6√2 μ R^{3/2} h^{-3/2} G(y) V,   y = a / √(2 R h),
    G(y) = arctan y + y (y² − 1)/(1 + y²)²          (G → π/2 long film, (8/3) y³ short film).

* **Cavitation** (half-Sommerfeld / Reynolds condition): on separation the pressure would be
  negative everywhere; the oil cavitates and the film carries nothing. The film resists
  approach only.
* **Saturation**: below the adsorbed layer h_min the film is evaluated at h_min.
* **Wetted length**: flooded (oil jet) the film wets a fixed half-length a_max; starved
  (boundary lubrication) the oil on the flanks is a layer of total thickness h_oil, and the
  film is bounded by its meniscus, where the gap equals h_oil: ``a(h) = √(2R(h_oil − h))``,
  so ``y² = h_oil/h − 1`` and nothing resists before the gap closes to h_oil. In general
  ``y² = min(a_max²/(2 R h), h_oil/h − 1)``.
* The films of all pairs in the mesh zone act together: the force is summed along every
  contact line (:mod:`rig_mesh` tabulates Σ ∫ R^{3/2} dl and the length-weighted R).

**Mapping to rattlefit's a.** rattlefit's film (the paper's eq. (5)) acts on the pitch-circle
gap with R at the pitch point and width Z = b; a boundary recording pins its squeeze
momentum ``M = ∫_{h_min}^∞ S dh`` (the impulse one approach costs). This film's momentum on
the pitch circle is ``M = g ∫_{g h_min}^∞ S_n dh_n`` with g = cos α_t cos β_b (the normal gap
is g times the pitch-circle gap, and the force and speed project by g each), averaged over
the mesh position. :func:`equivalent_film` returns the rattlefit ``a`` whose momentum
(rattlefit's closed form, at the same μ and rattlefit's h_min = 2 µm) equals it; when this
film's momentum exceeds the most rattlefit's saturated film can take, no ``a`` matches and
it returns None with the viscosity factor that would.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import integrate, optimize

from .rig_geometry import Pair

SQRT2 = math.sqrt(2.0)
#: rattlefit's default h_min (pitch circle), m: where its squeeze momentum is stated.
RATTLEFIT_MIN_FILM = 2e-6


def film_shape(y):
    """G(y) = arctan y + y(y² − 1)/(1 + y²)² (array), by its series (8/3)y³(1 − 9y²/5) below
    y = 10⁻², where the closed form cancels."""
    y = np.asarray(y, dtype=float)
    small = y < 1e-2
    ys = np.where(small, 0.5, y)
    y2 = ys * ys
    full = np.arctan(ys) + ys * (y2 - 1.0) / (1.0 + y2) ** 2
    return np.where(small, (8.0 / 3.0) * y**3 * (1.0 - 1.8 * y * y), full)


def film_y2(h, reff, a_max, h_oil):
    """y² of the film at normal gap ``h`` (m, already saturated at h_min), arrays."""
    flooded = a_max * a_max / (2.0 * reff * h)
    starved = h_oil / h - 1.0
    return np.maximum(np.minimum(flooded, starved), 0.0)


def film_coefficient(h, viscosity, lr, reff, a_max, h_oil, h_min):
    """S (N s/m): the film force per unit normal approach speed at normal gap ``h`` (m).

    ``viscosity`` μ (Pa s); ``lr`` Σ ∫ R^{3/2} dl over the contact lines (m^{2.5}); ``reff``
    their length-weighted R (m); ``a_max`` the flooded half-length (m; ∞ for a starved film);
    ``h_oil`` the oil layer's thickness (m; ∞ for a flooded film); ``h_min`` the adsorbed
    layer (m). Arrays broadcast.
    """
    hs = np.maximum(h, h_min)
    y = np.sqrt(film_y2(hs, reff, a_max, h_oil))
    return 6.0 * SQRT2 * viscosity * lr * hs**-1.5 * film_shape(y)


def flooded_momentum(h1, viscosity, lr, reff, a):
    """∫_{h1}^∞ S dh (N s) of a flooded film of half-length ``a`` without saturation, in
    closed form: ``6√2 μ lr (2R)^{3/2}/(a R) · [y1 arctan y1 − y1²/(1 + y1²)]``,
    y1 = a/√(2 R h1) (∫₀^y G = y arctan y + 1/(1+y²) − 1)."""
    y1 = a / math.sqrt(2.0 * reff * h1)
    inner = y1 * math.atan(y1) - y1 * y1 / (1.0 + y1 * y1)
    return 6.0 * SQRT2 * viscosity * lr * (2.0 * reff) ** 1.5 / (a * reff) * inner


def own_momentum(pair: Pair, table, viscosity, a_max, h_oil, h_min, h1=RATTLEFIT_MIN_FILM):
    """This film's squeeze momentum on the pitch circle from the pitch-circle gap ``h1`` (m),
    N s, at the drive flank's mean Σ ∫ R^{3/2} dl and R (``table`` from :mod:`rig_mesh`)."""
    g = math.cos(pair.alpha_t) * math.cos(pair.beta_b)
    lr, reff = float(np.mean(table[:-1, 2])), float(np.mean(table[:-1, 4]))

    def s(h):
        return float(film_coefficient(h, viscosity, lr, reff, a_max, h_oil, h_min))

    lower = g * h1
    total = s(h_min) * max(0.0, h_min - lower)
    start = max(lower, h_min)
    if math.isfinite(h_oil):
        total += integrate.quad(s, start, max(h_oil, start), limit=200)[0]
    else:
        total += flooded_momentum(start, viscosity, lr, reff, a_max)
    return g * total


def rattlefit_momentum(a, viscosity, radius, width, h_min=RATTLEFIT_MIN_FILM):
    """rattlefit's squeeze momentum (its closed form, re-derived from eq. (5)), N s:
    ``6 μ Z R^{3/2} h_min^{-1/2} ψ(a/√(R h_min))``, ψ(y) = arctan y − y/(1 + y²)."""
    y = a / math.sqrt(radius * h_min)
    psi = math.atan(y) - y / (1.0 + y * y)
    return 6.0 * viscosity * width * radius**1.5 / math.sqrt(h_min) * psi


def equivalent_film(pair: Pair, table, viscosity, a_max, h_oil, h_min) -> dict:
    """rattlefit's film half-length with this film's squeeze momentum (see the module notes).

    Returns ``{"squeeze_momentum_N_s", "a_equivalent_m" (None if saturated),
    "viscosity_factor"}``: the factor on μ at which rattlefit's saturated film (a → ∞) would
    take this momentum (1 when an ``a`` matches).
    """
    m = own_momentum(pair, table, viscosity, a_max, h_oil, h_min)
    radius, width = pair.rattlefit_curvature(), pair.face_width
    ceiling = rattlefit_momentum(1.0, viscosity, radius, width)  # a = 1 m: saturated
    if m >= 0.999 * ceiling:
        return {"squeeze_momentum_N_s": m, "a_equivalent_m": None, "viscosity_factor": m / ceiling}
    if m <= rattlefit_momentum(1e-9, viscosity, radius, width):  # an oil layer of nothing
        return {"squeeze_momentum_N_s": m, "a_equivalent_m": 1e-9, "viscosity_factor": 1.0}
    a = optimize.brentq(
        lambda a: rattlefit_momentum(a, viscosity, radius, width) - m, 1e-9, 1.0, xtol=1e-12
    )
    return {"squeeze_momentum_N_s": m, "a_equivalent_m": a, "viscosity_factor": 1.0}
