"""Lubricant viscosity from temperature: the ASTM D341 (Walther) viscosity–temperature chart.

ASTM D341 states that for mineral oils

    log10(log10(ν + 0.7)) = A − B · log10(T)

with ν the kinematic viscosity in cSt (mm²/s) and T the absolute temperature in K. Two
catalogue points (40 °C and 100 °C) fix A and B; the dynamic (absolute) viscosity that enters
the squeeze-film law, eq. (5) of the seed paper, is μ = ρ · ν.
"""

from __future__ import annotations

import math

from ..errors import ParameterError

KELVIN = 273.15


def walther_coefficients(
    viscosity_40c_cst: float, viscosity_100c_cst: float
) -> tuple[float, float]:
    """ASTM D341 coefficients ``(A, B)`` through two catalogue viscosities (cSt)."""
    if not (viscosity_40c_cst > viscosity_100c_cst > 0):
        raise ParameterError(
            "catalogue viscosities must satisfy ν40 > ν100 > 0, got "
            f"ν40={viscosity_40c_cst} cSt, ν100={viscosity_100c_cst} cSt"
        )
    y40 = math.log10(math.log10(viscosity_40c_cst + 0.7))
    y100 = math.log10(math.log10(viscosity_100c_cst + 0.7))
    x40 = math.log10(40.0 + KELVIN)
    x100 = math.log10(100.0 + KELVIN)
    slope = (y40 - y100) / (x100 - x40)
    return y40 + slope * x40, slope


def kinematic_viscosity_cst(
    temperature_c: float, viscosity_40c_cst: float, viscosity_100c_cst: float
) -> float:
    """Kinematic viscosity (cSt = mm²/s) at ``temperature_c`` (°C) by ASTM D341."""
    if not (-60.0 < temperature_c < 250.0):
        raise ParameterError(f"oil temperature {temperature_c} °C is outside (-60, 250) °C")
    a, b = walther_coefficients(viscosity_40c_cst, viscosity_100c_cst)
    return 10.0 ** (10.0 ** (a - b * math.log10(temperature_c + KELVIN))) - 0.7


def dynamic_viscosity(
    temperature_c: float,
    viscosity_40c_cst: float,
    viscosity_100c_cst: float,
    density_kg_m3: float,
) -> float:
    """Dynamic viscosity μ (Pa s) at ``temperature_c`` (°C): ρ · ν with ν from ASTM D341.

    The density is taken as constant (the format gives one value); its thermal expansion
    (≈ 0.07 % per K) is far below the uncertainty the fit gives the effective viscosity.
    """
    if not density_kg_m3 > 0:
        raise ParameterError(f"oil density must be positive, got {density_kg_m3} kg/m³")
    nu = kinematic_viscosity_cst(temperature_c, viscosity_40c_cst, viscosity_100c_cst)
    return density_kg_m3 * nu * 1e-6
