"""Rig files in: LabView TDMS (written by npTDMS itself) and CSV turned into recordings through
a channel map, against the bundled recording they were made from."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest
from nptdms import ChannelObject, TdmsWriter

from rattlefit.errors import RecordingError
from rattlefit.io.recording import read_recording
from rattlefit.io.rig_files import import_recording

BOUNDARY = "data/pairII_boundary_65.6_20pct_16Hz.h5"


@pytest.fixture(scope="module")
def bundled():
    return read_recording(BOUNDARY)


def toml_value(v) -> str:
    return json.dumps(v) if isinstance(v, str) else repr(v)


def write_map(path, rec, encoders: dict, **changes) -> None:
    """A channel map of ``rec``'s metadata with the ``encoders`` table, fields replaced by
    ``changes`` ("group.name": value)."""
    tables = {
        "encoders": encoders,
        "gear_pair": {k: v for k, v in dataclasses.asdict(rec.gear_pair).items() if v is not None},
        "operating": dataclasses.asdict(rec.operating),
        "oil": dataclasses.asdict(rec.oil),
    }
    for key, value in changes.items():
        group, name = key.split(".")
        tables[group][name] = value
    lines = ['format = "rattlefit.channel-map"', "version = 1", 'title = "imported"']
    for name, table in tables.items():
        lines.append(f"[{name}]")
        lines += [f"{k} = {toml_value(v)}" for k, v in table.items()]
    path.write_text("\n".join(lines) + "\n")


def write_tdms(path, rec, dtype=np.float64) -> None:
    props = {"wf_increment": 1.0 / rec.sample_rate_hz}
    with TdmsWriter(str(path)) as w:
        w.write_segment(
            [
                ChannelObject("Encoders", "primary", rec.primary.astype(dtype), properties=props),
                ChannelObject(
                    "Encoders", "secondary", rec.secondary.astype(dtype), properties=props
                ),
            ]
        )


TDMS_ENCODERS = {
    "primary": "Encoders/primary",
    "secondary": "Encoders/secondary",
    "counts_per_rev": 40000,
}


def assert_same_recording(got, ref):
    np.testing.assert_array_equal(got.primary, ref.primary)
    np.testing.assert_array_equal(got.secondary, ref.secondary)
    assert got.sample_rate_hz == pytest.approx(ref.sample_rate_hz, rel=1e-9)
    assert got.counts_per_rev == ref.counts_per_rev
    assert got.gear_pair == ref.gear_pair
    assert got.operating == ref.operating
    assert got.oil == ref.oil


@pytest.mark.parametrize("dtype", [np.float64, np.int32])
def test_a_tdms_file_becomes_the_recording_it_was_made_from(bundled, tmp_path, dtype):
    write_tdms(tmp_path / "rig.tdms", bundled, dtype)
    write_map(tmp_path / "map.toml", bundled, TDMS_ENCODERS)  # the rate from wf_increment
    import_recording(tmp_path / "rig.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    got = read_recording(tmp_path / "out.h5")
    assert_same_recording(got, bundled)
    assert got.title == "imported"


def test_a_csv_file_with_a_time_column_becomes_the_recording(bundled, tmp_path):
    t = np.arange(bundled.n_samples) / bundled.sample_rate_hz
    rows = ["t,enc1,enc2"] + [
        f"{ti:.9f},{p},{s}" for ti, p, s in zip(t, bundled.primary, bundled.secondary, strict=True)
    ]
    (tmp_path / "rig.csv").write_text("\n".join(rows) + "\n")
    enc = {"primary": "enc1", "secondary": "enc2", "counts_per_rev": 40000, "time": "t"}
    write_map(tmp_path / "map.toml", bundled, enc)
    import_recording(tmp_path / "rig.csv", tmp_path / "map.toml", tmp_path / "out.h5")
    assert_same_recording(read_recording(tmp_path / "out.h5"), bundled)


def test_a_bad_map_value_names_the_map_and_the_field_and_writes_nothing(bundled, tmp_path):
    write_tdms(tmp_path / "rig.tdms", bundled)
    write_map(tmp_path / "map.toml", bundled, TDMS_ENCODERS, **{"operating.lubrication": "wet"})
    (tmp_path / "out.h5").write_bytes(b"what was there")
    with pytest.raises(RecordingError) as err:
        import_recording(tmp_path / "rig.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    assert err.value.file.endswith("map.toml") and err.value.field == "/operating@lubrication"
    assert (tmp_path / "out.h5").read_bytes() == b"what was there"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.toml", "out.h5", "rig.tdms"]


def test_a_missing_channel_and_fractional_counts_are_refused(bundled, tmp_path):
    write_tdms(tmp_path / "rig.tdms", bundled)
    enc = {**TDMS_ENCODERS, "secondary": "Encoders/driven"}
    write_map(tmp_path / "map.toml", bundled, enc)
    with pytest.raises(RecordingError, match=r"rig\.tdms: Encoders/driven: no such"):
        import_recording(tmp_path / "rig.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    props = {"wf_increment": 1e-4}
    with TdmsWriter(str(tmp_path / "half.tdms")) as w:
        w.write_segment(
            [
                ChannelObject("Encoders", "primary", bundled.primary + 0.5, properties=props),
                ChannelObject("Encoders", "secondary", bundled.secondary * 1.0, properties=props),
            ]
        )
    write_map(tmp_path / "map.toml", bundled, TDMS_ENCODERS)
    with pytest.raises(RecordingError, match="Encoders/primary: counts must be integers"):
        import_recording(tmp_path / "half.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    assert not (tmp_path / "out.h5").exists()


def test_rattlefit_import_exits_2_with_one_line(bundled, tmp_path):
    write_tdms(tmp_path / "rig.tdms", bundled)
    write_map(tmp_path / "map.toml", bundled, TDMS_ENCODERS, **{"encoders.counts_per_rev": -4})
    cmd = [sys.executable, "-m", "rattlefit.cli", "import", str(tmp_path / "rig.tdms")]
    out = subprocess.run(
        [*cmd, "--map", str(tmp_path / "map.toml"), "-o", str(tmp_path / "out.h5")],
        capture_output=True,
        text=True,
    )
    lines = [x for x in out.stderr.splitlines() if x.startswith("rattlefit: error")]
    assert out.returncode == 2 and len(lines) == 1
    assert "map.toml" in lines[0] and "counts_per_rev" in lines[0]


def test_the_bundled_example_map_describes_the_bundled_recording(bundled, tmp_path):
    write_tdms(tmp_path / "rig.tdms", bundled)
    rec = import_recording(
        tmp_path / "rig.tdms", "data/channel-map.example.toml", tmp_path / "out.h5"
    )
    assert_same_recording(read_recording(rec.path), bundled)
