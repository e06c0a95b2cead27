"""Rig files in: LabView TDMS and delimited text (CSV, tab-separated ``.txt``) turned into
recording-format v1, through a channel map (:mod:`.channel_map`).

The pipeline: read the map; read the two encoder channels (:mod:`.tdms`,
:mod:`.delimited_text`); settle the sample rate and the unit between the map and the file (a
conflict is an error naming both values); convert degrees or radians to counts; unwrap a
counter's rollover where the map asks; validate everything as a recording; write it
atomically, with the import's provenance in ``/provenance`` (source file, its size, SHA-256
and modification time, the map's text, rattlefit's version).
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import time
from pathlib import Path

import numpy as np

from ..errors import RecordingError
from ..version import __version__
from .channel_map import GROUPS, UNITS, read_channel_map, unit_name
from .delimited_text import delimited_columns
from .recording import Recording, check_recording, max_count_jump, recording_of, write_recording
from .schema import FORMAT_NAME, FORMAT_VERSION, validate_attrs
from .tdms import tdms_channels

#: The file endings read as TDMS and as delimited text.
TDMS_SUFFIXES = (".tdms",)
TEXT_SUFFIXES = (".csv", ".txt", ".tsv", ".dat")
#: Relative difference between the map's and the file's sample rate taken as a conflict.
RATE_TOLERANCE = 1e-6
#: Largest distance from a whole count that a converted angle may have (counts).
COUNT_TOLERANCE = 1e-3


@dataclasses.dataclass(frozen=True)
class RigChannels:
    """The two encoder channels as read, in the file's unit, with the rate and the unit the
    file states (None and "" where it states none)."""

    primary: np.ndarray
    secondary: np.ndarray
    sample_rate_hz: float | None
    unit: str


def read_rig_channels(source: str, doc: dict) -> RigChannels:
    """The encoder channels the map ``doc`` names in the rig file ``source``, by its ending."""
    enc = doc["encoders"]
    names = [str(enc["primary"]), str(enc["secondary"])]
    suffix = Path(source).suffix.lower()
    if suffix in TDMS_SUFFIXES:
        read = tdms_channels(source, names)
        return RigChannels(*read.data, read.sample_rate_hz, read.unit)
    if suffix in TEXT_SUFFIXES:
        (p, s), rate = delimited_columns(source, names, enc.get("time"), doc.get("text", {}))
        return RigChannels(p, s, rate, "")
    known = ", ".join(TDMS_SUFFIXES + TEXT_SUFFIXES)
    raise RecordingError(source, "/", f"not a rig file rattlefit reads ({known})")


def settled_rate(channels: RigChannels, enc: dict, source: str, map_file: str) -> float:
    """The sample rate: the file's or the map's; both must agree where both state one."""
    mapped, found = enc.get("sample_rate_hz"), channels.sample_rate_hz
    if mapped is None and found is None:
        raise RecordingError(
            map_file, "[encoders].sample_rate_hz", "missing, and the source gives none"
        )
    if mapped is not None and found is not None:
        if abs(mapped - found) > RATE_TOLERANCE * found:
            raise RecordingError(
                map_file,
                "[encoders].sample_rate_hz",
                f"{mapped:g} Hz, but {Path(source).name} gives {found:.9g} Hz ("
                + (
                    "its channels' wf_increment"
                    if Path(source).suffix.lower() in TDMS_SUFFIXES
                    else "its time column"
                )
                + "): remove the map's value, or make the two agree",
            )
    return float(found if found is not None else mapped)


def settled_unit(channels: RigChannels, enc: dict, source: str, map_file: str) -> str:
    """The channels' unit (a key of :data:`~.channel_map.UNITS`): the map's ``unit`` or the
    file's; both must name the same unit where both state one."""
    mapped = unit_name(enc["unit"]) if "unit" in enc else None
    found = unit_name(channels.unit) if channels.unit else None
    if channels.unit and found is None:
        raise RecordingError(
            source,
            str(enc["primary"]),
            f"unit_string {channels.unit!r} is no encoder unit rattlefit converts "
            f"({', '.join(UNITS)}): set [encoders].unit if the values are one of these",
        )
    if mapped and found and mapped != found:
        raise RecordingError(
            map_file,
            "[encoders].unit",
            f"{enc['unit']!r}, but {Path(source).name} says {channels.unit!r}",
        )
    return mapped or found or "counts"


def to_counts(values: np.ndarray, unit: str, counts_per_rev: int, file: str, field: str):
    """Encoder values in ``unit`` as int64 counts. Raises naming the file and channel when they
    are not whole counts, with the likely cause."""
    if unit == "counts" and values.dtype.kind in "iu":
        return values.astype(np.int64)
    scaled = values.astype(np.float64)
    if UNITS[unit] is not None:
        scaled = scaled * UNITS[unit] * counts_per_rev
    off = np.abs(scaled - np.round(scaled)) if np.all(np.isfinite(scaled)) else np.array([np.inf])
    tolerance = 0.0 if unit == "counts" else COUNT_TOLERANCE
    if np.any(off > tolerance):
        hint = (
            '; if they are angles, set [encoders].unit = "deg" or "rad"'
            if unit == "counts"
            else f"; is counts_per_rev = {counts_per_rev} the encoder's?"
        )
        what = "counts must be integers (found fractional values" + (
            ")" if unit == "counts" else f" after converting from {unit}, up to {off.max():.3g})"
        )
        raise RecordingError(file, field, what + hint)
    return np.round(scaled).astype(np.int64)


def unwrapped(counts: np.ndarray, bits: int | None) -> np.ndarray:
    """Counts of a counter that wraps at 2^``bits``, made cumulative (no change without)."""
    if bits is None:
        return counts
    span = 2**bits
    step = np.diff(counts)
    step = step - span * np.round(step / span).astype(np.int64)
    return np.concatenate([counts[:1], counts[0] + np.cumsum(step)])


def wrap_hint(rec: Recording, bits: int | None) -> str:
    """A note for a count jump too large to be motion: most likely a counter that wrapped."""
    if bits is not None:
        return ""
    allowed = max_count_jump(rec.counts_per_rev, rec.sample_rate_hz, rec.operating)
    for counts in (rec.primary, rec.secondary):
        jump = int(np.max(np.abs(np.diff(counts)))) if counts.size > 1 else 0
        if jump > allowed:
            guess = max(8, int(np.ceil(np.log2(jump))))
            return f" (a counter that wraps? set [encoders].rollover_bits = {guess})"
    return ""


def provenance_of(source: str, map_file: str) -> dict[str, str | int]:
    """What the import came from: the source's name, size, SHA-256 and modification time
    (UTC), the channel map's text, and rattlefit's version."""
    digest = hashlib.sha256()
    with open(source, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    stat = os.stat(source)
    return {
        "source": Path(source).name,
        "source_bytes": int(stat.st_size),
        "source_sha256": digest.hexdigest(),
        "source_modified_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(stat.st_mtime)),
        "channel_map": Path(map_file).read_text(encoding="utf-8"),
        "imported_by": f"rattlefit {__version__}",
    }


def import_recording(
    source: str | os.PathLike[str],
    channel_map: str | os.PathLike[str],
    output: str | os.PathLike[str],
    *,
    overwrite: bool = True,
) -> Recording:
    """Turn the rig file ``source`` (TDMS, or CSV and other delimited text) into a
    recording-format v1 file ``output`` through the TOML ``channel_map``
    (:mod:`.channel_map`), written atomically with its provenance (module notes).

    Returns the recording (with ``path`` set to ``output``). Raises
    :class:`~rattlefit.errors.RecordingError`, naming the file (the source or the map) and
    the field, for an unreadable file, a missing channel or map field, a conflict between the
    map and the file, values that are not whole counts, or any value the recording format
    rejects; nothing is written then.
    """
    source, map_file = os.fspath(source), os.fspath(channel_map)
    doc = read_channel_map(map_file)
    enc = doc["encoders"]
    channels = read_rig_channels(source, doc)
    rate = settled_rate(channels, enc, source, map_file)
    unit = settled_unit(channels, enc, source, map_file)
    cpr, bits = int(enc["counts_per_rev"]), enc.get("rollover_bits")
    root = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION}
    if "title" in doc:
        root["title"] = doc["title"]
    groups = {"/": root, "/encoders": {"sample_rate_hz": rate, "counts_per_rev": cpr}}
    groups.update({f"/{g}": doc[g] for g in GROUPS})
    values = validate_attrs(groups, map_file)
    counts = [
        unwrapped(to_counts(getattr(channels, k), unit, cpr, source, str(enc[k])), bits)
        for k in ("primary", "secondary")
    ]
    rec = recording_of(values, *counts, source)
    try:
        check_recording(rec, source)
    except RecordingError as exc:
        raise RecordingError(exc.file, exc.field, exc.problem + wrap_hint(rec, bits)) from None
    write_recording(rec, output, overwrite=overwrite, provenance=provenance_of(source, map_file))
    return dataclasses.replace(rec, path=os.fspath(output))
