"""Plain sentences on how well the data pin each fitted parameter down, and why, for the
HTML report's parameter table; and the numbers as the table shows them."""

from __future__ import annotations

import dataclasses

from ..inference.advice import film_lubrication
from ..inference.result import identified_ratio
from ..quantities import (
    DRAG_TORQUE,
    FILM,
    MOMENTUM,
    TARGETS,
    VISCOSITY,
    base_name,
    display,
    quantity,
)

#: The physical parameters (the others are nuisances), by base name.
PHYSICAL = (*TARGETS, MOMENTUM)


def meaning(name: str) -> str:
    """What parameter ``name`` is, in words, with its symbol (the registry's); empty for a
    name it lacks."""
    try:
        q = quantity(name)
    except KeyError:
        return ""
    return f"{q.meaning} ({q.symbol})"


def shown(value: float, name: str, unit: str | None = None) -> str:
    """``value`` (SI) of parameter ``name`` in its display unit, 4 significant digits."""
    return f"{value * display(name, unit)[0]:.4g}"


def below_optimum_sentence(low: dict) -> str:
    """The words for a fit's ``below_optimum`` (:func:`~rattlefit.inference.result.
    below_optimum`): how far its profiles reach below the optimum's cost, and what it means."""
    return (
        f"the profiles reach {low['depth']:.1f} below the optimum's cost "
        f"({low['parameter']}'s lowest): the optimum is not the lowest point found, and the "
        "intervals about it are rough"
    )


def display_unit(name: str, unit: str | None = None) -> str:
    """The unit the report shows parameter ``name`` in (the registry's)."""
    return display(name, unit)[1]


def estimate_cells(name: str, p: dict) -> tuple[str, str]:
    """``(estimate, 95 % interval)`` as the table shows parameter ``name``'s entry of the fit JSON
    (display units, :func:`shown`): the estimate always (the optimum; a file written before
    every parameter had one shows ``—``), a one-sided interval as ``≥ x`` or ``≤ x``."""
    unit = p["unit"]
    value = p.get("estimate")
    estimate = "—" if value is None else shown(value, name, unit)
    if p["bound"] == "lower":
        return estimate, f"≥ {shown(p['lower'], name, unit)}"
    if p["bound"] == "upper":
        return estimate, f"≤ {shown(p['upper'], name, unit)}"
    return estimate, f"[{shown(p['lower'], name, unit)}, {shown(p['upper'], name, unit)}]"


def verdict_word(name: str, p: dict) -> str:
    """The status of parameter ``name``'s entry ``p`` of the fit JSON, as every table shows
    it: ``identified``, ``as measured`` (a prior the data keep as narrow as identified),
    ``lower bound only``, ``upper bound only``, ``interval too wide (×w > ×r)``, ``prior-dominated``
    or ``not pinned down``."""
    if p["identified"]:
        return "identified"
    ratio = identified_ratio(name)
    if p["bound"] == "prior" and p["upper"] <= ratio * p["lower"]:
        return "as measured"
    if p["bound"] == "interval":
        return f"interval too wide (×{p['upper'] / p['lower']:.2f} > ×{ratio:.3g})"
    return {
        "lower": "lower bound only",
        "upper": "upper bound only",
        "prior": "prior-dominated",
    }.get(p["bound"], "not pinned down")


@dataclasses.dataclass(frozen=True)
class ParameterRow:
    """One parameter as every table shows it (the terminal's, the HTML report's): its name,
    estimate and 95 % interval in display units (:func:`estimate_cells`), display unit,
    status (:func:`verdict_word`), whether identified and whether a physical parameter (the
    films, the drag torque, the viscosity, a squeeze-film group) or a nuisance."""

    name: str
    estimate: str
    interval: str
    unit: str
    status: str
    identified: bool
    physical: bool


def parameter_rows(parameters: dict[str, dict]) -> list[ParameterRow]:
    """The rows of the fit JSON's ``parameters``, the physical parameters first."""
    rows = []
    for name, p in parameters.items():
        estimate, interval = estimate_cells(name, p)
        physical = base_name(name) in PHYSICAL
        unit = display_unit(name, p["unit"])
        status = verdict_word(name, p)
        rows.append(ParameterRow(name, estimate, interval, unit, status, p["identified"], physical))
    return sorted(rows, key=lambda r: not r.physical)


def _why_one_sided(base: str, lub: str | None, bound: str) -> str:
    if base == FILM and bound == "lower" and lub == "oil_jet":
        return (
            "under oil jet the squeeze film saturates once a ≫ √(R·h), so any longer film "
            "fits as well; the data pin μ/√h_min instead."
        )
    if base == FILM and bound == "upper":
        return "the interval runs down to a = 0: dry flanks (no film) fit the data as well."
    if base == DRAG_TORQUE and bound == "upper":
        return (
            "the interval runs down to T_b = 0: the spectrum is explained as well without "
            "bearing drag."
        )
    if bound == "lower":
        return "every value up to the top of the fitted range fits the data as well."
    return "every value down to the bottom of the fitted range fits the data as well."


def explain(name: str, p: dict, lubrications: list[str]) -> str:
    """A plain sentence (or two) on how well the data pin parameter ``name`` down and why.

    ``p`` is its entry in the fit JSON's ``parameters`` (``identified``, ``bound``, ``lower``,
    ``upper``, SI), ``lubrications`` those of the fitted recordings. A boundary film adds
    that it trades against h_min and the viscosity (the data pin μ·a³/h_min²).
    """
    base, bound = base_name(name), p.get("bound")
    lub = film_lubrication(name, lubrications)
    lo, hi = p["lower"], p["upper"]
    if p["identified"]:
        half = 50.0 * (hi - lo) / (hi + lo)
        text = (
            f"Identified: the data pin it to about ±{half:.0f} % (95 % interval a factor "
            f"{hi / lo:.2f} wide, below ×{identified_ratio(name):.3g})."
        )
    elif bound in ("lower", "upper"):
        word = "A lower" if bound == "lower" else "An upper"
        text = f"{word} bound only: {_why_one_sided(base, lub, bound)}"
    elif bound == "prior":
        text = (
            "Prior-dominated: the data barely narrow its prior, so the interval shown is the "
            "prior's central 95 % rather than what the recording says."
        )
    elif bound == "interval":
        text = (
            f"Too wide to count as identified: the interval spans a factor {hi / lo:.2f}, "
            f"more than ×{identified_ratio(name):.3g}."
        )
    else:
        text = "Not pinned down: the interval runs into both ends of the fitted range."
    if lub == "boundary":
        text += (
            " In boundary lubrication the film trades against h_min and the viscosity: the "
            "spectrum pins the squeeze film's momentum per approach (squeeze_momentum, "
            "∝ μ·a³/h_min² for a short film), so a is known only as well as h_min and μ are "
            "(a prior on h_min, --prior min_film=…, sharpens it)."
        )
    elif base == VISCOSITY and "boundary" in lubrications:
        text += (
            " With a boundary film it trades against a and h_min along μ·a³/h_min², the "
            "group the spectrum pins."
        )
    if p.get("would_pin") and lub != "boundary":
        text += f" What would pin it: {p['would_pin']}."
    return text
