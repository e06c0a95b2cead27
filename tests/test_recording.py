"""Tests of rattlefit.io.recording: the HDF5 recording format, version 1."""

from __future__ import annotations

import dataclasses
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest

from rattlefit.errors import RecordingError
from rattlefit.io.recording import (
    SCHEMAS,
    Recording,
    inspect_warnings,
    max_count_jump,
    read_recording,
    read_truth,
    write_recording,
)
from rattlefit.testing.shared import recordings_dir

SHARED = recordings_dir(Path(__file__).resolve().parents[1])
SHARED_FILES = sorted(SHARED.glob("*.h5")) if SHARED.is_dir() else []
NO_SHARED = f"needs the independent recordings, not at {SHARED}"
# A clean recording: pair II, boundary lubrication, 16 Hz fluctuation, no unmodelled effects.
CLEAN_NAME = "pairII_boundary_65.6_20pct_16Hz.h5"


def _shared_params() -> list:
    if not SHARED_FILES:
        return [pytest.param(None, marks=pytest.mark.skip(reason=NO_SHARED))]
    return [pytest.param(p, id=p.stem) for p in SHARED_FILES]


@pytest.fixture
def clean_file() -> Path:
    path = SHARED / CLEAN_NAME
    if not path.is_file():
        pytest.skip(NO_SHARED)
    return path


@pytest.fixture
def copy_of(clean_file: Path, tmp_path: Path) -> Path:
    """A writable copy of the clean recording."""
    dest = tmp_path / "copy.h5"
    shutil.copyfile(clean_file, dest)
    return dest


def _truth_effects(path: Path) -> list[str]:
    truth_file = path.parent / "truth.json"
    if not truth_file.is_file():
        return []
    return json.loads(truth_file.read_text()).get(path.stem, {}).get("unmodelled_effects", [])


# ------------------------------------------------------------------ reading the shared files


@pytest.mark.parametrize("path", _shared_params())
def test_shared_recordings_are_physically_sensible(path: Path) -> None:
    rec = read_recording(path)
    assert rec.path == str(path)
    assert rec.n_samples == 30000
    assert rec.duration == pytest.approx(3.0)
    assert rec.time[-1] == pytest.approx(3.0 - 1.0 / rec.sample_rate_hz)
    pair = rec.gear_pair
    assert (pair.teeth_driving, pair.teeth_driven) in {(19, 41), (11, 43)}
    assert rec.theta_primary[0] == 0.0 and rec.theta_secondary[0] == 0.0
    assert rec.quantisation_std == pytest.approx(
        np.pi
        / rec.counts_per_rev
        / np.sqrt(3)
        * np.hypot(1, pair.teeth_driven / pair.teeth_driving)
    )

    # The format defines the backlash as the play in Δθ*: the relative motion spans it.
    ratio = np.ptp(rec.relative_motion) / pair.angular_backlash_rad
    if "runout" in _truth_effects(path):
        # Runout adds a once-per-revolution transmission error on top of the play.
        assert 1.0 < ratio < 1.25
    else:
        assert ratio == pytest.approx(1.0, rel=0.10)
    assert abs(np.median(rec.relative_motion)) < 1e-12

    mean_speed = rec.theta_primary[-1] / (rec.time[-1] - rec.time[0])
    assert mean_speed == pytest.approx(rec.operating.drive_mean_speed_rad_s, rel=0.01)
    assert inspect_warnings(rec) == []


def test_attribute_types_are_plain_python(clean_file: Path) -> None:
    rec = read_recording(clean_file)
    assert type(rec.counts_per_rev) is int and type(rec.sample_rate_hz) is float
    assert type(rec.gear_pair.teeth_driving) is int
    assert type(rec.gear_pair.center_distance_mm) is float
    assert type(rec.operating.lubrication) is str and type(rec.title) is str
    assert rec.primary.dtype == np.int64 and not rec.primary.flags.writeable


# ------------------------------------------------------------------ writing


def test_round_trip(clean_file: Path, tmp_path: Path) -> None:
    rec = read_recording(clean_file)
    truth = {"a_mm": 0.085, "drag_torque_Nm": 0.025, "model": "one-dof", "seed": 7}
    out = write_recording(rec, tmp_path / "out.h5", extra_attrs=truth)
    back = read_recording(out)
    np.testing.assert_array_equal(back.primary, rec.primary)
    np.testing.assert_array_equal(back.secondary, rec.secondary)
    for name in ("sample_rate_hz", "counts_per_rev", "gear_pair", "operating", "oil", "title"):
        assert getattr(back, name) == getattr(rec, name), name
    assert read_truth(out) == truth
    assert read_truth(clean_file) is None
    with h5py.File(out) as f:
        assert f["encoders/primary"].dtype == np.int64
        assert f["encoders/primary"].compression == "gzip"
    assert not list(tmp_path.glob("*.tmp"))


def test_optional_std_is_omitted_when_none(clean_file: Path, tmp_path: Path) -> None:
    rec = read_recording(clean_file)
    pair = dataclasses.replace(rec.gear_pair, angular_backlash_std_rad=None)
    out = write_recording(dataclasses.replace(rec, gear_pair=pair), tmp_path / "out.h5")
    with h5py.File(out) as f:
        assert "angular_backlash_std_rad" not in f["gear_pair"].attrs
    assert read_recording(out).gear_pair.angular_backlash_std_rad is None


@pytest.fixture
def existing(tmp_path: Path) -> tuple[Path, bytes]:
    dest = tmp_path / "existing.h5"
    dest.write_bytes(b"previous content")
    return dest, dest.read_bytes()


def test_failed_write_leaves_destination_untouched(
    clean_file: Path, existing: tuple[Path, bytes], monkeypatch: pytest.MonkeyPatch
) -> None:
    dest, before = existing
    rec = read_recording(clean_file)

    def boom(*args: object, **kwargs: object) -> None:
        raise RuntimeError("disk on fire")

    monkeypatch.setattr(h5py.Group, "create_dataset", boom)
    with pytest.raises(RuntimeError, match="disk on fire"):
        write_recording(rec, dest)
    assert dest.read_bytes() == before
    assert not list(dest.parent.glob("*.tmp"))


def test_invalid_recording_is_never_written(clean_file: Path, existing: tuple[Path, bytes]) -> None:
    dest, before = existing
    rec = read_recording(clean_file)
    bad = dataclasses.replace(rec, gear_pair=dataclasses.replace(rec.gear_pair, teeth_driven=-41))
    with pytest.raises(RecordingError) as info:
        write_recording(bad, dest)
    assert info.value.field == "/gear_pair@teeth_driven"
    assert str(dest) in str(info.value)
    assert dest.read_bytes() == before
    assert not list(dest.parent.glob("*.tmp"))


def test_no_overwrite(clean_file: Path, existing: tuple[Path, bytes]) -> None:
    dest, before = existing
    with pytest.raises(RecordingError, match="exists"):
        write_recording(read_recording(clean_file), dest, overwrite=False)
    assert dest.read_bytes() == before


def test_in_memory_invariants(clean_file: Path) -> None:
    rec = read_recording(clean_file)
    with pytest.raises(RecordingError) as info:
        dataclasses.replace(rec, secondary=rec.secondary[:-1], path=None)
    assert info.value.file == "<memory>" and info.value.field == "/encoders/secondary"
    with pytest.raises(RecordingError, match="integer"):
        dataclasses.replace(rec, primary=rec.primary.astype(float))
    with pytest.raises(RecordingError, match="1-D"):
        dataclasses.replace(rec, primary=rec.primary.reshape(2, -1))


def test_schema_covers_every_dataclass_field() -> None:
    from rattlefit.io.recording import GearPairSpec, OilSpec, OperatingPoint

    names = {spec.name for spec in SCHEMAS[1]}
    for cls in (GearPairSpec, OperatingPoint, OilSpec):
        assert {f.name for f in dataclasses.fields(cls)} <= names
    assert {"primary", "secondary", "sample_rate_hz", "counts_per_rev", "title"} <= names
    assert {f.name for f in dataclasses.fields(Recording)} - names == {
        "gear_pair",
        "operating",
        "oil",
        "path",
    }


# ------------------------------------------------------------------ bad files

Edit = Callable[[Path], None]


def _attr(group: str, name: str, value: object) -> Edit:
    def edit(path: Path) -> None:
        with h5py.File(path, "r+") as f:
            f[group].attrs[name] = value

    return edit


def _delete(obj: str, attr: str | None = None) -> Edit:
    def edit(path: Path) -> None:
        with h5py.File(path, "r+") as f:
            if attr is None:
                del f[obj]
            else:
                del f[obj].attrs[attr]

    return edit


def _dataset(name: str, transform: Callable[[np.ndarray], np.ndarray]) -> Edit:
    def edit(path: Path) -> None:
        with h5py.File(path, "r+") as f:
            data = transform(f["encoders"][name][()])
            del f["encoders"][name]
            f["encoders"].create_dataset(name, data=data)

    return edit


def _shorten(n: int) -> Edit:
    def edit(path: Path) -> None:
        _dataset("primary", lambda a: a[:n])(path)
        _dataset("secondary", lambda a: a[:n])(path)

    return edit


def _jump(a: np.ndarray) -> np.ndarray:
    a = a.copy()
    a[15000:] += 5000
    return a


def _bytes(make: Callable[[bytes], bytes]) -> Edit:
    def edit(path: Path) -> None:
        path.write_bytes(make(path.read_bytes()))

    return edit


BAD_FILES = {
    # kind: (edit, field blamed, key word of the problem)
    "file missing": (lambda p: p.unlink(), "/", "no such file"),
    "not HDF5": (_bytes(lambda b: b"time,primary,secondary\n0,0,0\n"), "/", "not an HDF5"),
    "truncated": (_bytes(lambda b: b[: len(b) // 2]), "/", "truncated"),
    "missing group": (_delete("oil"), "/oil", "missing required group"),
    "missing attribute": (
        _delete("gear_pair", "center_distance_mm"),
        "/gear_pair@center_distance_mm",
        "missing",
    ),
    "missing dataset": (_delete("encoders/secondary"), "/encoders/secondary", "missing"),
    "float counts": (
        _dataset("primary", lambda a: a.astype(np.float64)),
        "/encoders/primary",
        "float64",
    ),
    "2-D counts": (_dataset("secondary", lambda a: a.reshape(2, -1)), "/encoders/secondary", "1-D"),
    "lengths differ": (_dataset("secondary", lambda a: a[:-10]), "/encoders/secondary", "length"),
    "NaN value": (
        _attr("gear_pair", "driven_inertia_kg_m2", np.nan),
        "/gear_pair@driven_inertia_kg_m2",
        "nan",
    ),
    "negative value": (
        _attr("gear_pair", "pitch_diameter_driving_mm", -41.173),
        "/gear_pair@pitch_diameter_driving_mm",
        "-41.173",
    ),
    "zero sample rate": (
        _attr("encoders", "sample_rate_hz", 0.0),
        "/encoders@sample_rate_hz",
        "> 0",
    ),
    "string for number": (_attr("oil", "density_kg_m3", "heavy"), "/oil@density_kg_m3", "'heavy'"),
    "non-integer teeth": (
        _attr("gear_pair", "teeth_driving", 19.5),
        "/gear_pair@teeth_driving",
        "integer",
    ),
    "pressure angle": (
        _attr("gear_pair", "normal_pressure_angle_deg", 45.0),
        "/gear_pair@normal_pressure_angle_deg",
        "(0, 45)",
    ),
    "unknown lubrication": (
        _attr("operating", "lubrication", "wet"),
        "/operating@lubrication",
        "'wet'",
    ),
    "viscosity order": (
        _attr("oil", "viscosity_100c_cst", 200.0),
        "/oil@viscosity_100c_cst",
        "below",
    ),
    "counts jump": (
        _dataset("primary", _jump),
        "/encoders/primary",
        "between samples 14999 and 15000",
    ),
    "wrong format": (_attr("/", "format", "other.format"), "/@format", "'other.format'"),
    "wrong format_version": (
        _attr("/", "format_version", 2),
        "/@format_version",
        "unsupported format_version 2; this reader supports 1",
    ),
    "too short": (_shorten(500), "/encoders/primary", "period"),
}


@pytest.mark.parametrize("kind", list(BAD_FILES))
def test_bad_file_is_refused_naming_file_field_and_problem(kind: str, copy_of: Path) -> None:
    edit, field, keyword = BAD_FILES[kind]
    edit(copy_of)
    with pytest.raises(RecordingError) as info:
        read_recording(copy_of)
    message = str(info.value)
    assert info.value.field == field
    assert f"{copy_of}: {field}: " in message
    assert keyword in message


def test_unknown_extras_are_ignored(copy_of: Path) -> None:
    with h5py.File(copy_of, "r+") as f:
        f.attrs["operator"] = "somebody"
        f["gear_pair"].attrs["colour"] = "green"
        f.create_group("notes").attrs["x"] = 1.0
    assert read_recording(copy_of).gear_pair.teeth_driving == 19


def test_bytes_attributes_and_int32_counts_are_accepted(copy_of: Path) -> None:
    with h5py.File(copy_of, "r+") as f:
        f["operating"].attrs["lubrication"] = np.bytes_(b"oil_jet")
    _dataset("primary", lambda a: a.astype(np.int32))(copy_of)
    _dataset("secondary", lambda a: a.astype(np.int32))(copy_of)
    rec = read_recording(copy_of)
    assert rec.operating.lubrication == "oil_jet"
    assert rec.primary.dtype == np.int64


def test_jump_bound_formula() -> None:
    from rattlefit.io.recording import OperatingPoint

    op = OperatingPoint("dry", 20.0, 52.36, 10.472, 16.0)
    expected = int(np.ceil(40000 / (2 * np.pi) * (3 * (52.36 + 10.472) + 100) / 10000)) + 2
    assert max_count_jump(40000, 10000.0, op) == expected == 186


# ------------------------------------------------------------------ soft warnings


def test_warning_when_backlash_disagrees_with_motion(copy_of: Path) -> None:
    with h5py.File(copy_of, "r+") as f:
        f["gear_pair"].attrs["angular_backlash_rad"] *= 3
    notes = inspect_warnings(read_recording(copy_of))
    assert any("backlash" in note for note in notes)


def test_warnings_for_backwards_slow_and_stationary(clean_file: Path) -> None:
    rec = read_recording(clean_file)
    op = dataclasses.replace(rec.operating, drive_mean_speed_rad_s=60.0, drive_frequency_hz=0.5)
    primary = rec.primary.copy()
    primary[100] = primary[99] - 3
    odd = dataclasses.replace(
        rec, primary=primary, secondary=np.zeros_like(rec.secondary), operating=op
    )
    text = " ".join(inspect_warnings(odd))
    for word in ("backwards", "mean primary speed", "periods", "never moves"):
        assert word in text
