"""What extra data would pin a parameter that one fit leaves as a bound or a wide interval."""

from __future__ import annotations

from ..quantities import DRAG_TORQUE, FILM, VISCOSITY, base_name, index_of

#: Advice per parameter (base name, lubrication of its film or None): what would pin it.
ADVICE = {
    (FILM, "boundary"): (
        "a boundary recording pins the squeeze film's momentum per approach "
        "(squeeze_momentum, ∝ μ·a³/h_min² for a short film), not a alone: fit it "
        "jointly with an oil-jet recording of the same pair (rattlefit identify FILE "
        "OILJET_FILE), or give h_min as known (--prior min_film=2um:0.1 for 10 %)"
    ),
    (FILM, "oil_jet"): (
        "under oil jet the film saturates: fit it jointly with a boundary recording of the "
        "same pair"
    ),
    (DRAG_TORQUE, None): (
        "a longer recording, or a backlash sweep (recordings at other centre distances) "
        "fitted jointly"
    ),
    (VISCOSITY, None): (
        "the oil's viscosity at the test temperature, as a prior "
        "(--prior viscosity_scale=1:0.05 when the stated value is good to 5 %)"
    ),
}


def film_lubrication(name: str, lubrications: list[str]) -> str | None:
    """The lubrication a film parameter belongs to: ``film_half_length[oil_jet]`` →
    ``oil_jet``, ``film_half_length`` → the recordings' one lubrication; None for a parameter
    that is not a film half-length."""
    if base_name(name) != FILM:
        return None
    if index_of(name) is not None:
        return index_of(name)
    return lubrications[0] if len(set(lubrications)) == 1 else None


def what_would_pin(name: str, lubrications: list[str], identified: bool) -> str:
    """What would pin parameter ``name`` of a fit of recordings with ``lubrications``, in
    words; empty when it is identified or is a nuisance (whose prior is expected to
    dominate)."""
    if identified:
        return ""
    base = base_name(name)
    return ADVICE.get((base, film_lubrication(name, lubrications)), "")
