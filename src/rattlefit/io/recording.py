"""Read, write and check encoder recordings (HDF5 recording format, version 1).

The format is specified in ``recording-format.md`` and described declaratively by
:data:`~rattlefit.io.schema.SCHEMAS`; this module holds the data model (:class:`Recording` and
its metadata groups), the cross-field checks, and reading, writing and inspecting files. Every
violation is reported as one :class:`~rattlefit.errors.RecordingError` naming the file, the
field and the problem. The schema names (:class:`~rattlefit.io.schema.FieldSpec`,
:data:`~rattlefit.io.schema.SCHEMAS`, :data:`~rattlefit.io.schema.FORMAT_NAME`) are
re-exported here.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import numpy.typing as npt

from rattlefit.errors import RecordingError
from rattlefit.io.schema import (
    FORMAT_NAME,
    FORMAT_VERSION,
    MEMORY,
    SCHEMAS,
    TRUTH_GROUP,
    FieldSpec,
    Kind,
    coerce_value,
    guard,
    validate_attrs,
)
from rattlefit.util import atomic_write

__all__ = [
    "FORMAT_NAME",
    "SCHEMAS",
    "FieldSpec",
    "GearPairSpec",
    "OilSpec",
    "OperatingPoint",
    "Recording",
    "check_recording",
    "counts_sha256",
    "inspect_warnings",
    "max_count_jump",
    "read_provenance",
    "read_recording",
    "read_truth",
    "recording_of",
    "write_recording",
]

# --- Data model --------------------------------------------------------------------------------


@dataclass(frozen=True)
class GearPairSpec:
    """Geometry and inertia of the gear pair (``/gear_pair``); lengths in mm, angles as named."""

    teeth_driving: int
    teeth_driven: int
    pitch_diameter_driving_mm: float
    pitch_diameter_driven_mm: float
    face_width_driving_mm: float
    face_width_driven_mm: float
    normal_module_mm: float
    normal_pressure_angle_deg: float
    helix_angle_deg: float
    driven_inertia_kg_m2: float
    center_distance_mm: float
    angular_backlash_rad: float
    angular_backlash_std_rad: float | None = None


@dataclass(frozen=True)
class OperatingPoint:
    """Test conditions (``/operating``); commanded speed ω(t) = Ω_m + ΔΩ sin(2π f t) in rad/s."""

    lubrication: str
    oil_temperature_c: float
    drive_mean_speed_rad_s: float
    drive_speed_amplitude_rad_s: float
    drive_frequency_hz: float


@dataclass(frozen=True)
class OilSpec:
    """Lubricant (``/oil``): kinematic viscosities in cSt (mm²/s) and density in kg/m³."""

    viscosity_40c_cst: float
    viscosity_100c_cst: float
    density_kg_m3: float


@dataclass(frozen=True, eq=False)
class Recording:
    """One test: the two encoder count streams and the metadata needed to simulate it.

    Parameters
    ----------
    primary, secondary : ndarray of int, shape (N,)
        Cumulative counts of the driving and driven shafts, sample k latched at k / fs.
        Stored as read-only int64 copies.
    sample_rate_hz : float
        Trigger rate fs (Hz).
    counts_per_rev : int
        Counts per shaft revolution after quadrature decoding.
    gear_pair, operating, oil
        Metadata groups.
    title : str
        Free text.
    path : str or None
        File the recording was read from; used in error messages.
    """

    primary: npt.NDArray[np.int64]
    secondary: npt.NDArray[np.int64]
    sample_rate_hz: float
    counts_per_rev: int
    gear_pair: GearPairSpec
    operating: OperatingPoint
    oil: OilSpec
    title: str = ""
    path: str | None = None

    def __post_init__(self) -> None:
        file = self.path or MEMORY
        arrays = {}
        for name in ("primary", "secondary"):
            a = np.asarray(getattr(self, name))
            field = f"/encoders/{name}"
            if a.ndim != 1:
                raise RecordingError(file, field, f"must be 1-D, got shape {a.shape}")
            if a.dtype.kind not in "iu":
                raise RecordingError(file, field, f"dtype {a.dtype} is not an integer type")
            arrays[name] = np.array(a, dtype=np.int64)
            arrays[name].setflags(write=False)
            object.__setattr__(self, name, arrays[name])
        n1, n2 = arrays["primary"].size, arrays["secondary"].size
        if n1 != n2:
            raise RecordingError(
                file, "/encoders/secondary", f"length {n2} differs from /encoders/primary ({n1})"
            )
        if n1 < 2:
            raise RecordingError(file, "/encoders/primary", f"needs >= 2 samples, got {n1}")

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return int(self.primary.size)

    @property
    def duration(self) -> float:
        """Recording length N / fs (s)."""
        return self.n_samples / self.sample_rate_hz

    @property
    def time(self) -> npt.NDArray[np.float64]:
        """Sample times k / fs (s), shape (N,)."""
        return np.arange(self.n_samples) / self.sample_rate_hz

    def _theta(self, counts: npt.NDArray[np.int64]) -> npt.NDArray[np.float64]:
        return (2.0 * np.pi / self.counts_per_rev) * (counts - counts[0]).astype(np.float64)

    @property
    def theta_primary(self) -> npt.NDArray[np.float64]:
        """Driving-shaft angle θ1 (rad), zero at the first sample."""
        return self._theta(self.primary)

    @property
    def theta_secondary(self) -> npt.NDArray[np.float64]:
        """Driven-shaft angle θ2 (rad), zero at the first sample, positive in its own sense."""
        return self._theta(self.secondary)

    @property
    def gear_ratio(self) -> float:
        """Tooth ratio z2 / z1 (= r2 / r1 for the pitch radii)."""
        return self.gear_pair.teeth_driven / self.gear_pair.teeth_driving

    @property
    def relative_motion(self) -> npt.NDArray[np.float64]:
        """Relative motion Δθ* = θ1 − θ2 · z2/z1 of the seed paper's eq. (6), median removed (rad).

        Expressed as a primary-shaft angle; its peak-to-peak is bounded by the angular backlash.
        """
        d = self.theta_primary - self.gear_ratio * self.theta_secondary
        return d - np.median(d)

    @property
    def quantisation_std(self) -> float:
        """Standard deviation of encoder quantisation noise in Δθ*, eq. (8) (rad)."""
        return quantisation_std(self.counts_per_rev, self.gear_ratio)


def quantisation_std(counts_per_rev: int, gear_ratio: float) -> float:
    """Standard uncertainty of Δθ* from the two encoders' resolution, eq. (8), rad."""
    return (2 * math.pi / counts_per_rev) / (2 * math.sqrt(3)) * math.sqrt(1 + gear_ratio**2)


# --- Cross-field checks --------------------------------------------------------------------------


def max_count_jump(counts_per_rev: int, sample_rate_hz: float, operating: OperatingPoint) -> int:
    """Largest physically plausible change of either encoder between two samples (counts).

    ``ceil(counts_per_rev / (2π) · (3 · (Ω_m + ΔΩ) + 100 rad/s) / fs) + 2``: three times the
    peak commanded primary speed plus 100 rad/s of margin for rattle impacts, converted to
    counts per sample, plus 2 counts of quantisation slack. Applied to both shafts (the driven
    shaft is slower whenever z2 >= z1, and rattles within the backlash).
    """
    peak = 3.0 * (operating.drive_mean_speed_rad_s + operating.drive_speed_amplitude_rad_s)
    return math.ceil(counts_per_rev / (2.0 * np.pi) * (peak + 100.0) / sample_rate_hz) + 2


def _check_consistency(rec: Recording, file: str) -> None:
    """Cross-field checks that the per-field schema cannot express."""
    op = rec.operating
    period = 1.0 / op.drive_frequency_hz
    if rec.duration < period:
        raise RecordingError(
            file,
            "/encoders/primary",
            f"N = {rec.n_samples} samples ({rec.duration:g} s) is shorter than one period of "
            f"the drive fluctuation (1 / drive_frequency_hz = {period:g} s)",
        )
    allowed = max_count_jump(rec.counts_per_rev, rec.sample_rate_hz, op)
    for name in ("primary", "secondary"):
        steps = np.abs(np.diff(getattr(rec, name)))
        k = int(np.argmax(steps))
        if steps[k] > allowed:
            raise RecordingError(
                file,
                f"/encoders/{name}",
                f"counts jump by {int(steps[k])} between samples {k} and {k + 1}, more than "
                f"the physically possible {allowed} counts per sample",
            )
    if rec.oil.viscosity_100c_cst >= rec.oil.viscosity_40c_cst:
        raise RecordingError(
            file,
            "/oil@viscosity_100c_cst",
            f"got {rec.oil.viscosity_100c_cst!r} cSt; must be below viscosity_40c_cst "
            f"= {rec.oil.viscosity_40c_cst!r} cSt (oil thins as it warms)",
        )


def _groups_of(rec: Recording) -> dict[str, dict[str, Any]]:
    """The attributes a recording is written as, keyed by group path."""
    gear = {k: v for k, v in asdict(rec.gear_pair).items() if v is not None}
    return {
        "/": {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "title": rec.title},
        "/encoders": {"sample_rate_hz": rec.sample_rate_hz, "counts_per_rev": rec.counts_per_rev},
        "/gear_pair": gear,
        "/operating": asdict(rec.operating),
        "/oil": asdict(rec.oil),
    }


def check_recording(recording: Recording, file: str | None = None) -> None:
    """Apply every check :func:`read_recording` applies; raise :class:`RecordingError` if any fails.

    ``file`` names the file in the error (default: ``recording.path`` or ``"<memory>"``).
    """
    file = file or recording.path or MEMORY
    validate_attrs(_groups_of(recording), file)
    _check_consistency(recording, file)


# --- Reading -----------------------------------------------------------------------------------


def _open(path: Path, file: str) -> h5py.File:
    if not path.exists():
        raise RecordingError(file, "/", "no such file")
    if path.is_dir():
        raise RecordingError(file, "/", "is a directory, not a recording file")
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        msg = str(exc)
        if "signature" in msg:
            raise RecordingError(file, "/", "not an HDF5 file (no HDF5 signature)") from None
        if "truncated" in msg:
            raise RecordingError(file, "/", f"file is truncated ({msg})") from None
        raise RecordingError(file, "/", f"cannot open as HDF5: {msg}") from None


def _raw_attrs(obj: h5py.Group, file: str) -> dict[str, Any]:
    """Attributes of a group; an unreadable value is stored as its exception (reported only
    if the schema needs that attribute)."""
    out: dict[str, Any] = {}
    with guard(file, obj.name):
        for name in obj.attrs:
            try:
                out[name] = obj.attrs[name]
            except Exception as exc:
                out[name] = exc
    return out


def _read_counts(f: h5py.File, spec: FieldSpec, file: str) -> np.ndarray:
    obj = f.get(spec.group)
    if not isinstance(obj, h5py.Group):
        raise RecordingError(file, spec.group, "missing required group")
    ds = obj.get(spec.name)
    if ds is None:
        raise RecordingError(file, spec.path, "missing required dataset")
    if not isinstance(ds, h5py.Dataset):
        raise RecordingError(file, spec.path, "expected a dataset, found a group")
    if ds.dtype not in (np.dtype(np.int64), np.dtype(np.int32)):
        raise RecordingError(file, spec.path, f"dtype {ds.dtype} not allowed; must be int64/int32")
    if ds.ndim != 1:
        raise RecordingError(file, spec.path, f"must be 1-D, got shape {ds.shape}")
    with guard(file, spec.path):
        return np.asarray(ds[()], dtype=np.int64)


def read_recording(path: str | os.PathLike[str]) -> Recording:
    """Read and validate a recording file.

    Every field of :data:`SCHEMAS` is checked (presence, kind, range), then the cross-field
    rules: equal lengths, N / fs >= 1 / drive_frequency_hz, viscosity_40c > viscosity_100c,
    and no encoder step larger than :func:`max_count_jump`. Unknown groups and attributes are
    ignored.

    Parameters
    ----------
    path : path-like
        HDF5 file in the recording format.

    Returns
    -------
    Recording
        With ``path`` set to ``str(path)``.

    Raises
    ------
    RecordingError
        Exactly one, naming the file, the field and the problem, for any unreadable or invalid
        file (missing, not HDF5, truncated, missing field, wrong type or out of range).
    """
    file = os.fspath(path)
    with _open(Path(file), file) as f, guard(file, "/"):
        groups: dict[str, dict[str, Any] | None] = {"/": _raw_attrs(f, file)}
        for group in {s.group for schema in SCHEMAS.values() for s in schema} - {"/"}:
            obj = f.get(group)
            groups[group] = _raw_attrs(obj, file) if isinstance(obj, h5py.Group) else None
        values = validate_attrs(groups, file)
        schema = SCHEMAS[values["/"]["format_version"]]
        counts = {s.name: _read_counts(f, s, file) for s in schema if s.kind == "counts"}
    rec = recording_of(values, counts["primary"], counts["secondary"], file)
    _check_consistency(rec, file)
    return rec


def recording_of(
    values: Mapping[str, Mapping[str, Any]], primary, secondary, path: str
) -> Recording:
    """The :class:`Recording` of validated attribute ``values`` (``{group path: {name:
    value}}``, as :func:`~rattlefit.io.schema.validate_attrs` returns them) and the two
    encoders' counts (N,), read from ``path``."""
    enc = values["/encoders"]
    return Recording(
        primary=primary,
        secondary=secondary,
        sample_rate_hz=enc["sample_rate_hz"],
        counts_per_rev=enc["counts_per_rev"],
        gear_pair=GearPairSpec(**values["/gear_pair"]),
        operating=OperatingPoint(**values["/operating"]),
        oil=OilSpec(**values["/oil"]),
        title=values["/"].get("title", ""),
        path=path,
    )


def counts_sha256(recording: Recording) -> str:
    """SHA-256 of the two count streams (little-endian int64): which recording a result was
    computed from, independent of the file's name, place and HDF5 layout."""
    h = hashlib.sha256(np.asarray(recording.primary).astype("<i8").tobytes())
    h.update(np.asarray(recording.secondary).astype("<i8").tobytes())
    return h.hexdigest()


#: The optional group in which an imported recording keeps where it came from
#: (:mod:`rattlefit.io.rig_files`).
PROVENANCE_GROUP = "/provenance"


def read_truth(path: str | os.PathLike[str]) -> dict[str, str | int | float] | None:
    """Attributes of the optional ``/truth`` group (parameters of a synthetic recording).

    Returns ``None`` when the file has no such group. Values are plain Python str/int/float.
    """
    return read_attribute_group(path, TRUTH_GROUP)


def read_provenance(path: str | os.PathLike[str]) -> dict[str, str | int | float] | None:
    """Attributes of the optional ``/provenance`` group (what an imported recording came
    from: source file, its SHA-256, the channel map, …); ``None`` when the file has none."""
    return read_attribute_group(path, PROVENANCE_GROUP)


def read_attribute_group(
    path: str | os.PathLike[str], group: str
) -> dict[str, str | int | float] | None:
    """The attributes of the optional ``group`` as plain Python str/int/float, or ``None``
    when the file has no such group."""
    file = os.fspath(path)
    with _open(Path(file), file) as f, guard(file, group):
        obj = f.get(group)
        if not isinstance(obj, h5py.Group):
            return None
        out: dict[str, str | int | float] = {}
        for name, raw in _raw_attrs(obj, file).items():
            kind: Kind = "int" if isinstance(raw, np.integer) else "float"
            if isinstance(raw, str | bytes | np.bytes_):
                kind = "str"
            out[name] = coerce_value(raw, FieldSpec(group, name, kind), file)
        return out


# --- Writing -----------------------------------------------------------------------------------


def _write_h5(rec: Recording, target: str, extras: Mapping[str, Mapping]) -> None:
    groups = _groups_of(rec)
    with h5py.File(target, "w") as f:
        for group, attrs in groups.items():
            obj = f if group == "/" else f.create_group(group)
            for name, value in attrs.items():
                obj.attrs[name] = value
        for name in ("primary", "secondary"):
            data = getattr(rec, name)
            f["/encoders"].create_dataset(
                name, data=data, dtype=np.int64, compression="gzip", shuffle=True
            )
        for group, attrs in extras.items():
            if attrs:
                obj = f.create_group(group)
                for name, value in attrs.items():
                    obj.attrs[name] = value


def write_recording(
    recording: Recording,
    path: str | os.PathLike[str],
    *,
    overwrite: bool = True,
    extra_attrs: Mapping[str, str | int | float] | None = None,
    provenance: Mapping[str, str | int | float] | None = None,
) -> Path:
    """Validate ``recording`` and write it atomically in format version 1.

    The file is written to a temporary ``*.tmp`` file in the destination directory, flushed to
    disk and moved into place with :func:`os.replace`; if anything fails the temporary file is
    removed and an existing file at ``path`` is left untouched.

    Parameters
    ----------
    recording : Recording
        Checked with :func:`check_recording` first, so an invalid file is never written.
    path : path-like
        Destination.
    overwrite : bool
        If False and ``path`` exists, raise :class:`RecordingError` instead.
    extra_attrs : mapping of str to str, int or float, optional
        Written as attributes of a ``/truth`` group (e.g. the parameters a synthetic
        recording was simulated with); read back with :func:`read_truth`.
    provenance : mapping of str to str, int or float, optional
        Written as attributes of a ``/provenance`` group (what an imported recording came
        from); read back with :func:`read_provenance`.

    Returns
    -------
    Path
        ``path``.
    """
    dest = Path(path)
    file = os.fspath(dest)
    check_recording(recording, file)
    extras = {TRUTH_GROUP: dict(extra_attrs or {}), PROVENANCE_GROUP: dict(provenance or {})}
    for group, attrs in extras.items():
        for name, value in attrs.items():
            if not name or "/" in name:
                raise RecordingError(file, f"{group}@{name}", "invalid attribute name")
            if isinstance(value, bool) or not isinstance(value, str | int | float):
                raise RecordingError(
                    file, f"{group}@{name}", f"expected a str, int or float, got {value!r}"
                )
    if not overwrite and dest.exists():
        raise RecordingError(file, "/", "file exists and overwrite=False")
    if not dest.parent.is_dir():
        raise RecordingError(file, "/", f"directory {dest.parent} does not exist")
    try:
        atomic_write(dest, lambda tmp: _write_h5(recording, os.fspath(tmp), extras))
    except OSError as exc:
        raise RecordingError(file, "/", f"cannot write the file: {exc}") from None
    return dest


# --- Soft checks -------------------------------------------------------------------------------


def inspect_warnings(recording: Recording) -> list[str]:
    """Notes on anything suspicious that does not make the recording invalid.

    Checks: peak-to-peak of Δθ* against the stated backlash (outside 0.5x-1.5x), primary shaft
    running backwards, measured mean primary speed more than 5 % from the commanded
    Ω_m, fewer than 3 fluctuation periods recorded, secondary shaft stationary.

    Returns
    -------
    list of str
        One full sentence per note; empty if nothing looks wrong.
    """
    rec, notes = recording, []
    op, bl = recording.operating, recording.gear_pair.angular_backlash_rad
    ptp = float(np.ptp(rec.relative_motion))
    if not 0.5 <= ptp / bl <= 1.5:
        notes.append(
            f"The peak-to-peak relative motion Δθ* is {ptp:.4g} rad, {ptp / bl:.2f} times the "
            f"stated angular backlash of {bl:.4g} rad; check angular_backlash_rad and the encoders."
        )
    steps = np.diff(rec.primary)
    back = np.flatnonzero(steps < 0)
    if back.size:
        notes.append(
            f"The primary shaft runs backwards in {back.size} of {steps.size} sample steps "
            f"(first between samples {back[0]} and {back[0] + 1}); the drive should turn one way."
        )
    mean_speed = float(rec.theta_primary[-1] / ((rec.n_samples - 1) / rec.sample_rate_hz))
    rel = mean_speed / op.drive_mean_speed_rad_s - 1.0
    if abs(rel) > 0.05:
        notes.append(
            f"The measured mean primary speed is {mean_speed:.4g} rad/s, {100 * rel:+.1f} % from "
            f"the commanded drive_mean_speed_rad_s of {op.drive_mean_speed_rad_s:.4g} rad/s."
        )
    periods = rec.duration * op.drive_frequency_hz
    if periods < 3:
        notes.append(
            f"The recording lasts {rec.duration:.3g} s, only {periods:.2f} periods of the "
            f"{op.drive_frequency_hz:g} Hz drive fluctuation; at least 3 are advisable."
        )
    if np.all(rec.secondary == rec.secondary[0]):
        notes.append(
            f"The secondary shaft never moves (all {rec.n_samples} counts equal "
            f"{int(rec.secondary[0])}); the gears may be out of mesh or the encoder disconnected."
        )
    return notes
