"""Rig files in: LabView TDMS and CSV turned into recording-format v1, through a channel map.

A channel map is a small TOML file (format ``rattlefit.channel-map``, version 1) that says
which channels hold the two encoders' counts and everything else the format needs::

    format = "rattlefit.channel-map"
    version = 1
    title = "pair II, 65.6 mm, boundary"          # optional

    [encoders]
    primary = "Encoders/primary"      # TDMS: "group/channel"; CSV: the column's header
    secondary = "Encoders/secondary"
    counts_per_rev = 40000
    sample_rate_hz = 10000            # optional for TDMS channels with wf_increment, and for
                                      # CSV with a time column
    # time = "t"                      # CSV only: a time column (s), for the sample rate

    [gear_pair]                       # every attribute of the format's /gear_pair
    [operating]                       # every attribute of /operating
    [oil]                             # every attribute of /oil

The ``[gear_pair]``, ``[operating]`` and ``[oil]`` tables carry the format's attributes under
their own names (``../shared/recording-format.md``, ``docs/recording-format.md``), and are
validated by the same schema and cross-field checks as :func:`~rattlefit.io.recording.
read_recording`, so an error names the map file and the format's field
(``/operating@lubrication``). Counts may be stored as integers or as floats holding integers.
"""

from __future__ import annotations

import csv
import dataclasses
import os
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import RecordingError
from .recording import Recording, check_recording, recording_of, write_recording
from .schema import FORMAT_NAME, FORMAT_VERSION, validate_attrs

#: Format tag and version of a channel map.
MAP_FORMAT, MAP_VERSION = "rattlefit.channel-map", 1
#: The recording groups a map carries as TOML tables.
GROUPS = ("gear_pair", "operating", "oil")


def read_channel_map(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The channel map in the TOML file ``path``, its format and version checked. Raises
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
            f"expected format = {MAP_FORMAT!r} and version = {MAP_VERSION}, got "
            f"{doc.get('format')!r} and {doc.get('version')!r}",
        )
    for table in ("encoders", *GROUPS):
        if not isinstance(doc.get(table), dict):
            raise RecordingError(file, f"[{table}]", "missing table")
    for name in ("primary", "secondary", "counts_per_rev"):
        if name not in doc["encoders"]:
            raise RecordingError(file, f"[encoders].{name}", "missing")
    return doc


def tdms_channels(path: str, names: list[str]) -> tuple[list[np.ndarray], float | None]:
    """The channels ``names`` ("group/channel") of the TDMS file ``path``, and the sample
    rate their ``wf_increment`` property gives (None without one)."""
    from nptdms import TdmsFile

    try:
        tdms = TdmsFile.read(path)
    except (OSError, ValueError, KeyError) as exc:
        raise RecordingError(path, "/", f"cannot read the TDMS file ({exc})") from None
    data, rates = [], set()
    for name in names:
        group, _, channel = name.partition("/")
        try:
            ch = tdms[group][channel]
        except KeyError:
            raise RecordingError(path, name, "no such group/channel in the TDMS file") from None
        data.append(np.asarray(ch[:]))
        if "wf_increment" in ch.properties:
            rates.add(1.0 / float(ch.properties["wf_increment"]))
    if len(rates) > 1:
        raise RecordingError(path, names[1], f"sample rates differ between channels: {rates}")
    return data, rates.pop() if rates else None


def csv_channels(
    path: str, names: list[str], time: str | None
) -> tuple[list[np.ndarray], float | None]:
    """The columns ``names`` of the CSV file ``path`` (a header row, then one row per
    sample), and the sample rate from the ``time`` column (s) when given."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as exc:
        raise RecordingError(path, "/", f"cannot read the CSV file ({exc.strerror})") from None
    if len(rows) < 3:
        raise RecordingError(path, "/", "needs a header row and at least two samples")
    header = [h.strip() for h in rows[0]]
    wanted = names + ([time] if time else [])
    columns = []
    for name in wanted:
        if name not in header:
            raise RecordingError(path, name, f"no such column (the header has {header})")
        k = header.index(name)
        try:
            columns.append(np.array([float(r[k]) for r in rows[1:]]))
        except (ValueError, IndexError):
            raise RecordingError(path, name, "a row has no number in this column") from None
    rate = None
    if time:
        step = np.diff(columns.pop())
        if np.any(step <= 0) or np.ptp(step) > 1e-6 * np.mean(step):
            raise RecordingError(path, time, "the time column is not evenly increasing")
        rate = 1.0 / float(np.mean(step))
    return columns, rate


def as_counts(values: np.ndarray, file: str, field: str) -> np.ndarray:
    """Encoder counts as int64; floats must hold integers."""
    if values.dtype.kind in "iu":
        return values.astype(np.int64)
    if not np.all(np.isfinite(values)) or np.any(values != np.round(values)):
        raise RecordingError(file, field, "counts must be integers (found fractional values)")
    return np.round(values).astype(np.int64)


def import_recording(
    source: str | os.PathLike[str],
    channel_map: str | os.PathLike[str],
    output: str | os.PathLike[str],
    *,
    overwrite: bool = True,
) -> Recording:
    """Turn the rig file ``source`` (``.tdms`` or ``.csv``) into a recording-format v1 file
    ``output`` through the TOML ``channel_map`` (module docstring), written atomically.

    Returns the recording (with ``path`` set to ``output``). Raises
    :class:`~rattlefit.errors.RecordingError`, naming the file (the source or the map) and
    the field, for an unreadable file, a missing channel or map field, fractional counts, or
    any value the recording format rejects; nothing is written then.
    """
    source, map_file = os.fspath(source), os.fspath(channel_map)
    doc = read_channel_map(map_file)
    enc = doc["encoders"]
    names = [str(enc["primary"]), str(enc["secondary"])]
    suffix = Path(source).suffix.lower()
    if suffix == ".tdms":
        (primary, secondary), rate = tdms_channels(source, names)
    elif suffix == ".csv":
        (primary, secondary), rate = csv_channels(source, names, enc.get("time"))
    else:
        raise RecordingError(source, "/", "not a rig file rattlefit reads (.tdms or .csv)")
    rate = enc.get("sample_rate_hz", rate)
    if rate is None:
        raise RecordingError(
            map_file, "[encoders].sample_rate_hz", "missing, and the source gives none"
        )
    root = {"format": FORMAT_NAME, "format_version": FORMAT_VERSION}
    if "title" in doc:
        root["title"] = doc["title"]
    groups = {
        "/": root,
        "/encoders": {"sample_rate_hz": rate, "counts_per_rev": enc["counts_per_rev"]},
    }
    groups.update({f"/{g}": doc[g] for g in GROUPS})
    values = validate_attrs(groups, map_file)
    primary = as_counts(primary, source, names[0])
    rec = recording_of(values, primary, as_counts(secondary, source, names[1]), source)
    check_recording(rec, source)
    write_recording(rec, output, overwrite=overwrite)
    return dataclasses.replace(rec, path=os.fspath(output))
