"""The names, symbols and units of every quantity rattlefit fits or reports: one registry that
the fit, its JSON, the ``--prior`` option, the tables, the plots and the report all read.

A quantity has one **name** (in code, in JSON keys, in ``--prior`` and, with dashes, in command
line options), the seed paper's **symbol**, an SI **unit** (every value in code and JSON is
SI) and a **display unit** (tables, plots, the report and command-line input). A fitted
parameter's name is a quantity's name, possibly indexed: ``film_half_length[oil_jet]`` (one
film half-length per lubrication), ``backlash[0]`` (one per recording).
"""

from __future__ import annotations

import dataclasses
import re


@dataclasses.dataclass(frozen=True)
class Quantity:
    """One quantity: ``name``, paper ``symbol``, SI ``unit``, ``display_unit`` with ``scale``
    (display value = ``scale`` × SI value) and its ``meaning`` in words."""

    name: str
    symbol: str
    unit: str
    display_unit: str
    scale: float
    meaning: str

    def shown(self, value: float) -> float:
        """``value`` (SI) in the display unit."""
        return value * self.scale

    @property
    def typed_unit(self) -> str:
        """The display unit as typed on a command line (``um`` for µm)."""
        return self.display_unit.replace("µ", "u")

    def label(self) -> str:
        """An axis label: symbol and display unit, e.g. ``a (mm)``."""
        return f"{self.symbol} ({self.display_unit})" if self.display_unit else self.symbol


#: Every quantity, by name.
QUANTITIES = {
    q.name: q
    for q in (
        Quantity("film_half_length", "a", "m", "mm", 1e3, "oil-film half-length"),
        Quantity("drag_torque", "T_b", "N m", "N m", 1.0, "bearing drag torque on the driven gear"),
        Quantity(
            "viscosity",
            "μ",
            "Pa s",
            "Pa s",
            1.0,
            "effective dynamic viscosity of the oil at the recording's temperature",
        ),
        Quantity(
            "viscosity_scale",
            "μ/μ_oil",
            "1",
            "",
            1.0,
            "the effective viscosity over the stated oil's at the recording's temperature",
        ),
        Quantity("stiffness_scale", "k/k_ISO", "1", "", 1.0, "factor on the mesh stiffness"),
        Quantity(
            "min_film",
            "h_min",
            "m",
            "µm",
            1e6,
            "adsorbed film thickness below which the squeeze force saturates",
        ),
        Quantity("backlash", "j", "m", "mm", 1e3, "backlash on the pitch circle"),
        Quantity(
            "squeeze_momentum",
            "M",
            "N s",
            "N s",
            1.0,
            "momentum the squeeze film takes from one approach of the flanks, whatever the "
            "approach speed (∝ μ·a³/h_min² for a short film)",
        ),
    )
}

#: The film half-length's name (a fit across lubrications indexes it by lubrication).
FILM = "film_half_length"
#: The other fitted quantities' names (every module spells them through these). A prior on the
#: viscosity is given in Pa s under VISCOSITY (at the first recording's oil temperature); the
#: fit's coordinate is the factor VISCOSITY_SCALE on the oil's μ. MOMENTUM is the squeeze-film
#: group's coordinate, the film's momentum per approach (:mod:`rattlefit.inference.group`).
DRAG_TORQUE = "drag_torque"
VISCOSITY = "viscosity"
VISCOSITY_SCALE = "viscosity_scale"
MIN_FILM = "min_film"
STIFFNESS_SCALE = "stiffness_scale"
BACKLASH = "backlash"
MOMENTUM = "squeeze_momentum"
#: What rattlefit identifies, the seed paper's three: the film half-length, the drag torque and
#: the viscosity (tables and campaign reports show them first).
TARGETS = (FILM, DRAG_TORQUE, VISCOSITY)

_INDEX = re.compile(r"\[(.*)\]$")


def base_name(name: str) -> str:
    """A parameter's quantity name: ``film_half_length[boundary]`` → ``film_half_length``,
    ``backlash[0]`` → ``backlash``."""
    return _INDEX.sub("", name)


def index_of(name: str) -> str | None:
    """A parameter's index: ``film_half_length[oil_jet]`` → ``oil_jet``; None if it has none."""
    m = _INDEX.search(name)
    return m.group(1) if m else None


def quantity(name: str) -> Quantity:
    """The quantity of parameter ``name`` (indexed or not); raises KeyError naming it if the
    registry has none."""
    try:
        return QUANTITIES[base_name(name)]
    except KeyError:
        raise KeyError(f"{name!r} is not a quantity rattlefit knows") from None


#: How a value outside the registry (an effect's fitted field, for instance) is shown, by its
#: SI unit: ``(scale, display unit)``.
BY_UNIT = {"m": (1e3, "mm"), "1": (1.0, "")}


def display(name: str, unit: str | None = None) -> tuple[float, str]:
    """``(scale, display unit)`` of parameter ``name``; a name the registry lacks is shown by
    its SI ``unit`` (:data:`BY_UNIT`, else as it is)."""
    try:
        q = quantity(name)
    except KeyError:
        return BY_UNIT.get(unit or "1", (1.0, unit))
    return q.scale, q.display_unit


def axis_label(name: str, unit: str | None = None) -> str:
    """A plot axis for parameter ``name``: the name and its display unit, as the tables show
    them, e.g. ``film_half_length (mm)``."""
    shown = display(name, unit)[1]
    return f"{name} ({shown})" if shown else name
