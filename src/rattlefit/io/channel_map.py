"""The channel map: which channels of a rig file hold the encoders, and the metadata of the
recording format.

A channel map is a small TOML file. Its first two keys are required::

    format = "rattlefit.channel-map"
    version = 1
    title = "pair II, 65.6 mm, boundary"          # optional

    [encoders]
    primary = "Encoders/primary"      # TDMS: "group/channel"; CSV: the column's header
    secondary = "Encoders/secondary"
    counts_per_rev = 40000
    sample_rate_hz = 10000            # optional when the file gives it (TDMS wf_increment, a
                                      # CSV time column); must agree with the file's if both do
    # time = "t"                      # CSV only: a time column (s)
    # unit = "deg"                    # counts (default), deg or rad: the channels' unit; a TDMS
                                      # channel's unit_string is read, and must agree
    # rollover_bits = 32              # unwrap a counter that wraps at 2^bits

    [text]                            # optional, CSV and text files only: what is otherwise
    # delimiter = ";"                 # detected (",", ";", tab) ...
    # decimal = ","                   # ... the decimal mark ...
    # header_row = 1                  # ... the header's line (1-based) ...
    # units_row = true                # ... and whether a units row follows it

    [gear_pair]                       # every attribute of the format's /gear_pair
    [operating]                       # every attribute of /operating
    [oil]                             # every attribute of /oil

The ``[gear_pair]``, ``[operating]`` and ``[oil]`` tables carry the format's attributes under
their own names and are validated by the recording format's schema (:mod:`.schema`).
"""

from __future__ import annotations

import math
import os
import tomllib
from typing import Any

from ..errors import RecordingError

#: Format tag and version of a channel map.
MAP_FORMAT, MAP_VERSION = "rattlefit.channel-map", 1
#: The recording groups a map carries as TOML tables.
GROUPS = ("gear_pair", "operating", "oil")
#: Encoder units a map or a TDMS channel may state, and the revolutions one unit is.
UNITS = {"counts": None, "deg": 1 / 360, "rad": 1 / (2 * math.pi)}
#: How units are spelt in the wild (TDMS ``unit_string``), by the name rattlefit uses.
UNIT_SPELLINGS = {
    "counts": ("", "count", "counts", "cts", "ticks", "increments"),
    "deg": ("deg", "degree", "degrees", "°"),
    "rad": ("rad", "radian", "radians"),
}
#: The optional keys of ``[encoders]`` and ``[text]``, with the type each takes.
ENCODER_KEYS = {
    "primary": str,
    "secondary": str,
    "counts_per_rev": int,
    "sample_rate_hz": (int, float),
    "time": str,
    "unit": str,
    "rollover_bits": int,
}
TEXT_KEYS = {"delimiter": str, "decimal": str, "header_row": int, "units_row": bool}


def unit_name(spelt: str) -> str | None:
    """The encoder unit (a key of :data:`UNITS`) that ``spelt`` names, or None."""
    key = spelt.strip().lower()
    return next((u for u, names in UNIT_SPELLINGS.items() if key in names), None)


def read_channel_map(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The channel map in the TOML file ``path``: its format and version, its tables and the
    type of every ``[encoders]`` and ``[text]`` key checked. Raises
    :class:`~rattlefit.errors.RecordingError` naming the file and the field."""
    file = os.fspath(path)
    try:
        with open(file, "rb") as f:
            doc = tomllib.load(f)
    except OSError as exc:
        raise RecordingError(file, "/", f"cannot read the channel map ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise RecordingError(file, "/", f"not valid TOML ({exc})") from None
    if doc.get("format") != MAP_FORMAT or doc.get("version") != MAP_VERSION:
        raise RecordingError(
            file,
            "format",
            f"expected format = {MAP_FORMAT!r} and version = {MAP_VERSION} as the map's first "
            f"lines, got {doc.get('format')!r} and {doc.get('version')!r}",
        )
    for table in ("encoders", *GROUPS):
        if not isinstance(doc.get(table), dict):
            raise RecordingError(file, f"[{table}]", "missing table")
    for name in ("primary", "secondary", "counts_per_rev"):
        if name not in doc["encoders"]:
            raise RecordingError(file, f"[encoders].{name}", "missing")
    check_keys(doc["encoders"], ENCODER_KEYS, "encoders", file)
    check_keys(doc.get("text", {}), TEXT_KEYS, "text", file)
    unit = doc["encoders"].get("unit")
    if unit is not None and unit_name(unit) is None:
        raise RecordingError(
            file, "[encoders].unit", f"{unit!r} is not an encoder unit: one of {', '.join(UNITS)}"
        )
    bits = doc["encoders"].get("rollover_bits")
    if bits is not None and not 8 <= bits <= 64:
        raise RecordingError(file, "[encoders].rollover_bits", f"{bits} is not 8 to 64")
    return doc


def check_keys(table: dict, kinds: dict, name: str, file: str) -> None:
    """Every key of ``table`` is one of ``kinds`` and of its type (bool is no int)."""
    for key, value in table.items():
        if key not in kinds:
            raise RecordingError(file, f"[{name}].{key}", f"unknown key; known: {', '.join(kinds)}")
        if isinstance(value, bool) != (kinds[key] is bool) or not isinstance(value, kinds[key]):
            raise RecordingError(file, f"[{name}].{key}", f"{value!r} has the wrong type")
