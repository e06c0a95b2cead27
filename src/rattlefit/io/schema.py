"""The declarative schema of the HDF5 recording format and the validation that walks it.

:data:`SCHEMAS` holds one table of :class:`FieldSpec` rows per ``format_version``; reading and
writing both validate by walking that table (:func:`validate_attrs`), so every violation is
reported the same way: one :class:`~rattlefit.errors.RecordingError` naming the file, the
field and the problem.

Field names follow HDF5 paths: ``/gear_pair@teeth_driving`` is an attribute of a group
(``/@format_version`` for the root group), ``/encoders/primary`` is a dataset.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

import h5py
import numpy as np

from rattlefit.errors import RecordingError

__all__ = [
    "AT_LEAST_ONE",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "MEMORY",
    "NON_NEGATIVE",
    "POSITIVE",
    "SCHEMAS",
    "TRUTH_GROUP",
    "V1_FIELDS",
    "Bounds",
    "FieldSpec",
    "Kind",
    "OneOf",
    "Rule",
    "check_rule",
    "coerce_value",
    "guard",
    "validate_attrs",
]

FORMAT_NAME = "rattlefit.recording"
FORMAT_VERSION = 1
TRUTH_GROUP = "/truth"
"""Group holding the parameters a synthetic recording was simulated with (optional)."""
MEMORY = "<memory>"
"""The file name errors use for a recording that was never read from or written to a file."""


@dataclass(frozen=True)
class Bounds:
    """Closed or open interval for a finite number; ``None`` means unbounded on that side."""

    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    hi_open: bool = False

    def describe(self) -> str:
        if self.hi is None:
            return f"{'>' if self.lo_open else '>='} {self.lo:g}"
        if self.lo is None:
            return f"{'<' if self.hi_open else '<='} {self.hi:g}"
        left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
        return f"in {left}{self.lo:g}, {self.hi:g}{right}"

    def accepts(self, v: float) -> bool:
        if not math.isfinite(v):
            return False
        if self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo):
            return False
        return not (self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi))


@dataclass(frozen=True)
class OneOf:
    """The value must be one of a fixed set."""

    values: tuple[Any, ...]

    def describe(self) -> str:
        return "one of " + ", ".join(repr(v) for v in self.values)

    def accepts(self, v: Any) -> bool:
        return v in self.values


Rule = Bounds | OneOf
Kind = Literal["str", "int", "float", "counts"]
_NUMBER = (int, float, np.integer, np.floating)

POSITIVE = Bounds(lo=0, lo_open=True)
NON_NEGATIVE = Bounds(lo=0)
AT_LEAST_ONE = Bounds(lo=1)


@dataclass(frozen=True)
class FieldSpec:
    """One row of the schema: where a field lives, what kind it is and which values are valid.

    ``kind`` is ``"str"``, ``"int"``, ``"float"`` (scalar attributes) or ``"counts"`` (a 1-D
    integer dataset). ``unit`` is informative and appears in error messages.
    """

    group: str
    name: str
    kind: Kind
    rule: Rule | None = None
    unit: str = ""
    required: bool = True

    @property
    def path(self) -> str:
        """Field name used in errors: ``/group@attr`` or ``/group/dataset``."""
        if self.kind == "counts":
            return f"{self.group.rstrip('/')}/{self.name}"
        return f"{self.group}@{self.name}"


V1_FIELDS: tuple[FieldSpec, ...] = (
    FieldSpec("/", "format", "str", OneOf((FORMAT_NAME,))),
    FieldSpec("/", "format_version", "int"),  # dispatched on: must be a key of SCHEMAS
    FieldSpec("/", "title", "str", required=False),
    FieldSpec("/encoders", "sample_rate_hz", "float", POSITIVE, "Hz"),
    FieldSpec("/encoders", "counts_per_rev", "int", AT_LEAST_ONE, "counts"),
    FieldSpec("/encoders", "primary", "counts"),
    FieldSpec("/encoders", "secondary", "counts"),
    FieldSpec("/gear_pair", "teeth_driving", "int", AT_LEAST_ONE),
    FieldSpec("/gear_pair", "teeth_driven", "int", AT_LEAST_ONE),
    FieldSpec("/gear_pair", "pitch_diameter_driving_mm", "float", POSITIVE, "mm"),
    FieldSpec("/gear_pair", "pitch_diameter_driven_mm", "float", POSITIVE, "mm"),
    FieldSpec("/gear_pair", "face_width_driving_mm", "float", POSITIVE, "mm"),
    FieldSpec("/gear_pair", "face_width_driven_mm", "float", POSITIVE, "mm"),
    FieldSpec("/gear_pair", "normal_module_mm", "float", POSITIVE, "mm"),
    FieldSpec("/gear_pair", "normal_pressure_angle_deg", "float", Bounds(0, 45, True, True), "deg"),
    FieldSpec("/gear_pair", "helix_angle_deg", "float", Bounds(0, 60, False, True), "deg"),
    FieldSpec("/gear_pair", "driven_inertia_kg_m2", "float", POSITIVE, "kg m^2"),
    FieldSpec("/gear_pair", "center_distance_mm", "float", POSITIVE, "mm"),
    FieldSpec("/gear_pair", "angular_backlash_rad", "float", POSITIVE, "rad"),
    FieldSpec("/gear_pair", "angular_backlash_std_rad", "float", NON_NEGATIVE, "rad", False),
    FieldSpec("/operating", "lubrication", "str", OneOf(("dry", "boundary", "oil_jet"))),
    FieldSpec("/operating", "oil_temperature_c", "float", Bounds(-60, 250, True, True), "degC"),
    FieldSpec("/operating", "drive_mean_speed_rad_s", "float", POSITIVE, "rad/s"),
    FieldSpec("/operating", "drive_speed_amplitude_rad_s", "float", NON_NEGATIVE, "rad/s"),
    FieldSpec("/operating", "drive_frequency_hz", "float", POSITIVE, "Hz"),
    FieldSpec("/oil", "viscosity_40c_cst", "float", POSITIVE, "cSt"),
    FieldSpec("/oil", "viscosity_100c_cst", "float", POSITIVE, "cSt"),
    FieldSpec("/oil", "density_kg_m3", "float", POSITIVE, "kg/m^3"),
)

SCHEMAS: dict[int, tuple[FieldSpec, ...]] = {1: V1_FIELDS}
"""Schema of every supported ``format_version``: the table validation walks."""


# --- Validation --------------------------------------------------------------------------------


@contextmanager
def guard(file: str, field: str) -> Iterator[None]:
    """Turn any h5py/HDF5 failure (corrupt or truncated file) into a RecordingError."""
    try:
        yield
    except RecordingError:
        raise
    except Exception as exc:  # h5py raises OSError, RuntimeError, KeyError, ValueError, ...
        problem = f"cannot read (file truncated or corrupt?): {exc}"
        raise RecordingError(file, field, problem) from None


def _show(v: Any) -> str:
    return repr(v.item() if isinstance(v, np.generic) else v)


def coerce_value(raw: Any, spec: FieldSpec, file: str) -> str | int | float:
    """Normalise an attribute value (numpy scalar, bytes, size-1 array) to a Python value.

    ``raw`` may be an exception (an attribute that could not be read), reported as such.
    Raises :class:`RecordingError` if the value is not of ``spec.kind``.
    """
    err = lambda problem: RecordingError(file, spec.path, problem)  # noqa: E731
    if isinstance(raw, Exception):  # an unreadable value, as read_recording stores it
        raise err(f"cannot read value (file truncated or corrupt?): {raw}")
    if isinstance(raw, h5py.Empty):
        raise err("attribute has no value (empty dataspace)")
    if isinstance(raw, np.ndarray):
        if raw.size != 1:
            raise err(f"expected a scalar {spec.kind}, got an array of shape {raw.shape}")
        raw = raw.reshape(-1)[0]
    if spec.kind == "str":
        if isinstance(raw, bytes | np.bytes_):
            try:
                return bytes(raw).decode("utf-8")
            except UnicodeDecodeError:
                raise err(f"string {_show(raw)} is not valid UTF-8") from None
        if isinstance(raw, str):
            return str(raw)
        raise err(f"expected a string, got {_show(raw)}")
    if isinstance(raw, bool | np.bool_) or not isinstance(raw, _NUMBER):
        expected = "an integer" if spec.kind == "int" else "a number"
        raise err(f"expected {expected}, got {_show(raw)}")
    if spec.kind == "int":
        if isinstance(raw, int | np.integer):
            return int(raw)
        if not (math.isfinite(raw) and float(raw).is_integer()):
            raise err(f"expected an integer, got non-integer {_show(raw)}")
        return int(raw)
    return float(raw)


def check_rule(value: Any, spec: FieldSpec, file: str) -> None:
    """Raise :class:`RecordingError` if a coerced ``value`` breaks ``spec.rule``."""
    if spec.rule is not None and not spec.rule.accepts(value):
        unit = f" {spec.unit}" if spec.unit else ""
        finite = "finite and " if isinstance(spec.rule, Bounds) else ""
        problem = f"got {value!r}{unit}; must be {finite}{spec.rule.describe()}"
        raise RecordingError(file, spec.path, problem)


def validate_attrs(
    groups: Mapping[str, Mapping[str, Any] | None], file: str
) -> dict[str, dict[str, Any]]:
    """Walk the schema over raw attributes ``{group path: {name: value} or None if missing}``.

    Returns normalised values ``{group path: {name: value}}``; raises on the first violation.
    """
    root = groups.get("/") or {}
    header = {s.name: s for s in V1_FIELDS if s.group == "/"}
    for name in ("format", "format_version"):
        if name not in root:
            raise RecordingError(file, header[name].path, "missing required attribute")
    fmt = coerce_value(root["format"], header["format"], file)
    check_rule(fmt, header["format"], file)
    version = coerce_value(root["format_version"], header["format_version"], file)
    if version not in SCHEMAS:
        supported = ", ".join(str(v) for v in SCHEMAS)
        raise RecordingError(
            file,
            header["format_version"].path,
            f"unsupported format_version {version}; this reader supports {supported}",
        )
    out: dict[str, dict[str, Any]] = {}
    for spec in SCHEMAS[version]:
        if spec.kind == "counts":
            continue
        attrs = groups.get(spec.group)
        if attrs is None:
            raise RecordingError(file, spec.group, "missing required group")
        if spec.name not in attrs:
            if spec.required:
                raise RecordingError(file, spec.path, "missing required attribute")
            continue
        value = coerce_value(attrs[spec.name], spec, file)
        check_rule(value, spec, file)
        out.setdefault(spec.group, {})[spec.name] = value
    return out
