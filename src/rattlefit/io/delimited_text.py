"""Delimited text from a rig (CSV, tab-separated ``.txt``), as LabView and spreadsheets write it.

What varies between exports is detected, each overridable by the channel map's ``[text]``
table (:mod:`.channel_map`):

- the **delimiter**: the one of ``,``, ``;`` and tab that splits the header into the columns
  the map names;
- the **decimal mark**: ``,`` when the delimiter is not a comma and the numbers use one;
- the **header row**: the first line that holds the map's column names (lines before it, such
  as a LabView preamble, are skipped);
- a **units row** right after the header (``[s]``, ``counts``): skipped when its cells in the
  wanted columns are not numbers.

A time column is read relative to its first value in decimal arithmetic, so absolute LabView
timestamps (about 3.8·10⁹ s, printed to microseconds) give the sample rate exactly.
"""

from __future__ import annotations

import csv
import decimal
import io
import re

import numpy as np

from ..errors import RecordingError

#: Delimiters tried, in order.
DELIMITERS = (",", ";", "\t")
NUMBER = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")


def read_text(path: str) -> str:
    """The file's text (UTF-8, a byte-order mark dropped; Latin-1 where it is not UTF-8)."""
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except OSError as exc:
        raise RecordingError(path, "/", f"cannot read the file ({exc.strerror})") from None
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def split_lines(text: str, delimiter: str) -> list[list[str]]:
    return [[c.strip() for c in row] for row in csv.reader(io.StringIO(text), delimiter=delimiter)]


def find_header(text: str, names: list[str], options: dict, path: str):
    """(rows, delimiter, header index): the delimiter and header line holding every one of
    ``names``. Raises naming the columns the first line has and a likely cause."""
    delimiters = [options["delimiter"]] if "delimiter" in options else DELIMITERS
    for delimiter in delimiters:
        rows = split_lines(text, delimiter)
        candidates = (
            [options["header_row"] - 1] if "header_row" in options else range(min(50, len(rows)))
        )
        for k in candidates:
            if 0 <= k < len(rows) and all(n in rows[k] for n in names):
                return rows, delimiter, k
    first = text.splitlines()[0] if text.strip() else ""
    hint = ""
    if "delimiter" not in options and not any(d in first for d in DELIMITERS):
        hint = "; the first line has none of the delimiters , ; or tab"
    elif "delimiter" in options:
        hint = f"; the map's [text].delimiter is {options['delimiter']!r}: is it the file's?"
    missing = [n for n in names if n not in first]
    raise RecordingError(
        path,
        missing[0] if missing else "/",
        f"no header line holds the map's columns {names} (the first line is {first[:120]!r})"
        + hint,
    )


def decimal_mark(rows: list[list[str]], columns: list[int], delimiter: str, options) -> str:
    """The decimal mark: the map's, else ``,`` where the delimiter is not a comma and a
    number in the wanted columns uses one."""
    if "decimal" in options:
        return options["decimal"]
    if delimiter == ",":
        return "."
    sample = [r[c] for r in rows[:200] for c in columns if c < len(r)]
    return "," if any("," in s and NUMBER.match(s) for s in sample) else "."


def delimited_columns(
    path: str, names: list[str], time: str | None, options: dict
) -> tuple[list[np.ndarray], float | None]:
    """The columns ``names`` of the delimited text file ``path`` as float arrays, and the
    sample rate its ``time`` column gives (None without one). ``options`` is the map's
    ``[text]`` table. Raises :class:`~rattlefit.errors.RecordingError` naming the file, the
    column and the line of the first value that is no number."""
    wanted = names + ([time] if time else [])
    rows, delimiter, h = find_header(read_text(path), wanted, options, path)
    header = rows[h]
    columns = [header.index(n) for n in wanted]
    mark = decimal_mark(rows[h + 1 :], columns, delimiter, options)
    start = h + 1
    units = options.get("units_row")
    if units is None and start < len(rows):
        units = not all(_is_number(rows[start][c], mark) for c in columns if c < len(rows[start]))
    start += bool(units)
    body = [(k, r) for k, r in enumerate(rows[start:], start + 1) if any(r)]
    if len(body) < 2:
        raise RecordingError(path, "/", "needs a header line and at least two samples")
    texts = [_cells(body, c, name, mark, path) for name, c in zip(wanted, columns, strict=True)]
    rate = _rate(*_seconds(texts.pop()), path, time) if time else None
    return [np.array([float(t) for t in column]) for column in texts], rate


def _is_number(cell: str, mark: str) -> bool:
    return bool(NUMBER.match(cell)) and (mark == "," or "," not in cell)


def _cells(body, c: int, name: str, mark: str, path: str) -> list[str]:
    """Column ``c``'s cells as numbers' text with a decimal point; raises naming the line of
    the first that is no number."""
    out = []
    for line, row in body:
        cell = row[c] if c < len(row) else ""
        if not _is_number(cell, mark):
            raise RecordingError(
                path, name, f"line {line} has {cell!r}, not a number (decimal mark {mark!r})"
            )
        out.append(cell.replace(",", ".") if mark == "," else cell)
    return out


def _seconds(texts: list[str]) -> tuple[np.ndarray, float]:
    """A time column relative to its first value, in decimal arithmetic (absolute LabView
    timestamps keep their microseconds), and its printed resolution (s): 10^exponent of its
    least significant digit."""
    values = [decimal.Decimal(t) for t in texts]
    resolution = float(10 ** min(v.as_tuple().exponent for v in values[:1000]))
    return np.array([float(v - values[0]) for v in values]), resolution


def _rate(t: np.ndarray, resolution: float, path: str, name: str) -> float:
    """The sample rate of a time column ``t`` (seconds from its first value) printed to
    ``resolution``: its steps must agree within twice that resolution."""
    step = np.diff(t)
    mean = (t[-1] - t[0]) / (len(t) - 1)
    if np.any(step <= 0) or np.ptp(step) > 2 * resolution + 1e-9 * mean:
        worst = int(np.argmax(np.abs(step - mean)))
        raise RecordingError(
            path,
            name,
            f"the time column is not evenly increasing (step {step[worst]:.9g} s after sample "
            f"{worst + 1}, against a mean of {mean:.9g} s)",
        )
    return 1.0 / mean
