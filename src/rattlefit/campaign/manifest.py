"""A campaign's manifest: which recordings it holds, and which of them are fitted jointly.

A manifest is one of:

* **a directory**: every ``*.h5`` directly in it, each identified alone, in name order;
* **a CSV file** with a header row: column ``recording`` (the file, relative to the
  manifest's directory or absolute) and optionally ``group``;
* **a TOML file**: an array of tables ``[[recording]]``, each with ``path`` and optionally
  ``group``.

Recordings that share a non-empty ``group`` are identified jointly, as one
:func:`rattlefit.identify` of them all: a backlash sweep (one gear pair and lubrication at
several centre distances), or a boundary recording with its oil-jet companion. Every other
recording is identified alone. A group's recordings must be of one gear pair (checked when
they are read). Each identification is a :class:`Unit`, named after its group or, alone,
after its recording's file name.

:func:`read_manifest` checks the manifest before anything runs: a missing or repeated
recording, an unknown column or key, or an empty field is one
:class:`~rattlefit.errors.RattlefitError` naming the manifest, the field (``line 3,
recording`` or ``recording[2].path``) and the problem. Whether each recording is a valid
recording is checked later, on the workers, where a malformed one is reported and the rest
go on.
"""

from __future__ import annotations

import csv
import dataclasses
import os
import re
import tomllib
from pathlib import Path

from ..errors import RattlefitError

#: The columns of a CSV manifest (and the keys of a TOML ``[[recording]]`` table, where the
#: file is ``path``).
CSV_COLUMNS = ("recording", "group")
TOML_KEYS = ("path", "group")
#: The suffix of the recordings a directory manifest holds.
RECORDING_SUFFIX = ".h5"


@dataclasses.dataclass(frozen=True)
class Entry:
    """One recording of the manifest: its ``path`` (absolute), its ``group`` (None: fitted
    alone) and ``where`` the manifest declares it (for messages)."""

    path: Path
    group: str | None
    where: str


@dataclasses.dataclass(frozen=True)
class Unit:
    """One identification of the campaign: its ``name`` (a file-name-safe label, unique in
    the campaign), its recordings' ``paths`` (absolute, in manifest order) and its
    ``group`` (None for a recording fitted alone)."""

    name: str
    paths: tuple[str, ...]
    group: str | None

    @property
    def joint(self) -> bool:
        """Whether the unit is a joint identification of several recordings."""
        return self.group is not None


@dataclasses.dataclass(frozen=True)
class Manifest:
    """A checked manifest: where it came from (``source``) and its ``entries`` in order."""

    source: Path
    entries: tuple[Entry, ...]

    def units(self) -> tuple[Unit, ...]:
        """The campaign's identifications, in the order their first recording appears: one
        per group, one per recording without a group."""
        groups: dict[str, list[str]] = {}
        order: list[tuple[str | None, str]] = []
        for e in self.entries:
            if e.group is None:
                order.append((None, str(e.path)))
            else:
                if e.group not in groups:
                    groups[e.group] = []
                    order.append((e.group, e.group))
                groups[e.group].append(str(e.path))
        taken: set[str] = set()
        units = []
        for group, label in order:
            paths = tuple(groups[group]) if group is not None else (label,)
            stem = group if group is not None else Path(label).name.removesuffix(RECORDING_SUFFIX)
            name = unique_name(safe_name(stem), taken)
            units.append(Unit(name, paths, group))
        return tuple(units)


def safe_name(text: str) -> str:
    """``text`` with every character outside ``[A-Za-z0-9._-]`` replaced by ``_``."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", text).strip(".") or "unit"


def unique_name(name: str, taken: set[str]) -> str:
    """``name``, or ``name-2``, ``name-3``, … whichever is not in ``taken`` (which it joins)."""
    candidate, k = name, 1
    while candidate in taken:
        k += 1
        candidate = f"{name}-{k}"
    taken.add(candidate)
    return candidate


def read_manifest(source: str | os.PathLike[str]) -> Manifest:
    """The checked :class:`Manifest` of ``source``: a directory, a ``.csv`` or a ``.toml``
    file (see the module's description). Raises :class:`~rattlefit.errors.RattlefitError`
    naming the manifest, the field and the problem: a source that is none of these, an
    unreadable or empty manifest, an unknown column or key, an empty or non-text field, a
    recording that does not exist, or one listed twice."""
    source = Path(source).expanduser().resolve()
    if source.is_dir():
        entries = directory_entries(source)
    elif not source.exists():
        raise RattlefitError(f"{source}: manifest: no such file or directory")
    elif source.suffix.lower() == ".csv":
        entries = csv_entries(source)
    elif source.suffix.lower() == ".toml":
        entries = toml_entries(source)
    else:
        raise RattlefitError(
            f"{source}: manifest: expected a directory of recordings, a .csv or a .toml file, "
            f"got a {source.suffix or 'suffix-less'} file"
        )
    if not entries:
        raise RattlefitError(f"{source}: manifest: lists no recordings")
    check_unique(source, entries)
    return Manifest(source, tuple(entries))


def directory_entries(directory: Path) -> list[Entry]:
    """Every ``*.h5`` directly in ``directory``, alone, in name order."""
    paths = sorted(p for p in directory.iterdir() if p.suffix == RECORDING_SUFFIX and p.is_file())
    if not paths:
        raise RattlefitError(f"{directory}: manifest: no recordings (*{RECORDING_SUFFIX}) in it")
    return [Entry(p.resolve(), None, p.name) for p in paths]


def recording_path(manifest: Path, where: str, value: object) -> Path:
    """The recording ``value`` names, resolved against the manifest's directory; raises
    naming ``where`` when it is empty, not text, or not an existing file."""
    if not isinstance(value, str) or not value.strip():
        raise RattlefitError(f"{manifest}: {where}: empty; expected a recording's file name")
    path = Path(value.strip()).expanduser()
    path = (manifest.parent / path if not path.is_absolute() else path).resolve()
    if not path.is_file():
        raise RattlefitError(f"{manifest}: {where}: {value.strip()!r}: no such file ({path})")
    return path


def group_name(manifest: Path, where: str, value: object) -> str | None:
    """A group's name (None when empty or absent); raises naming ``where`` for non-text."""
    if value is None:
        return None
    if not isinstance(value, str):
        raise RattlefitError(f"{manifest}: {where}: expected text, got {value!r}")
    return value.strip() or None


def csv_entries(manifest: Path) -> list[Entry]:
    """The entries of a CSV manifest (header row, then one recording a row)."""
    try:
        with open(manifest, newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise RattlefitError(f"{manifest}: manifest: unreadable ({exc})") from exc
    if not rows:
        raise RattlefitError(f"{manifest}: line 1: empty; expected a header naming the columns")
    header = [h.strip() for h in rows[0]]
    unknown = [h for h in header if h not in CSV_COLUMNS]
    if unknown:
        raise RattlefitError(
            f"{manifest}: line 1, {unknown[0]}: unknown column; expected "
            f"{' and '.join(CSV_COLUMNS)}"
        )
    if "recording" not in header:
        raise RattlefitError(f"{manifest}: line 1: no column 'recording' (the recordings' files)")
    entries = []
    for n, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue  # blank lines
        if len(row) > len(header):
            raise RattlefitError(
                f"{manifest}: line {n}: {len(row)} fields, but the header names {len(header)}"
            )
        cells = dict(zip(header, row, strict=False))
        path = recording_path(manifest, f"line {n}, recording", cells.get("recording", ""))
        group = group_name(manifest, f"line {n}, group", cells.get("group"))
        entries.append(Entry(path, group, f"line {n}"))
    return entries


def toml_entries(manifest: Path) -> list[Entry]:
    """The entries of a TOML manifest (``[[recording]]`` tables)."""
    try:
        doc = tomllib.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise RattlefitError(f"{manifest}: manifest: not valid TOML ({exc})") from exc
    unknown = [k for k in doc if k != "recording"]
    if unknown:
        raise RattlefitError(
            f"{manifest}: {unknown[0]}: unknown key; a manifest holds [[recording]] tables"
        )
    tables = doc.get("recording")
    if not isinstance(tables, list) or not tables:
        raise RattlefitError(
            f"{manifest}: recording: missing; expected [[recording]] tables with path (and group)"
        )
    entries = []
    for i, table in enumerate(tables):
        where = f"recording[{i}]"
        if not isinstance(table, dict):
            raise RattlefitError(f"{manifest}: {where}: expected a table with path (and group)")
        extra = [k for k in table if k not in TOML_KEYS]
        if extra:
            raise RattlefitError(
                f"{manifest}: {where}.{extra[0]}: unknown key; expected {' and '.join(TOML_KEYS)}"
            )
        path = recording_path(manifest, f"{where}.path", table.get("path", ""))
        group = group_name(manifest, f"{where}.group", table.get("group"))
        entries.append(Entry(path, group, where))
    return entries


def check_unique(manifest: Path, entries: list[Entry]) -> None:
    """Raise naming both places when a recording is listed twice."""
    seen: dict[Path, str] = {}
    for e in entries:
        if e.path in seen:
            raise RattlefitError(
                f"{manifest}: {e.where}: {e.path.name} is listed twice (also at {seen[e.path]})"
            )
        seen[e.path] = e.where


def write_manifest(path: str | os.PathLike[str], rows: list[tuple[str, str | None]]) -> Path:
    """Write a CSV manifest of ``rows`` (recording, group or None) to ``path`` atomically;
    recordings inside the manifest's directory are written relative to it."""
    from ..util import atomic_write

    path = Path(path)
    base = path.parent.resolve()

    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            out = csv.writer(fh)
            out.writerow(CSV_COLUMNS)
            for recording, group in rows:
                p = Path(recording).resolve()
                shown = p.relative_to(base) if p.is_relative_to(base) else p
                out.writerow([shown.as_posix(), group or ""])

    return atomic_write(path, write)
