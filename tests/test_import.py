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
        "encoders": dict(encoders),
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


def csv_rows(rec, time_of, fmt, delimiter, decimal=".") -> list[str]:
    """Data lines of ``rec``: time (``time_of(k)``, formatted by ``fmt``), primary, secondary."""
    lines = []
    for k, (p, s) in enumerate(zip(rec.primary, rec.secondary, strict=True)):
        t = fmt(time_of(k))
        lines.append(delimiter.join([t.replace(".", decimal), str(p), str(s)]))
    return lines


CSV_ENCODERS = {"primary": "Enc_Primary_counts", "secondary": "Enc_Secondary_counts"}


def test_a_european_csv_is_read_as_written(bundled, tmp_path):
    # LabView with a German locale: ";" between fields, a decimal comma in the time column
    rate = bundled.sample_rate_hz
    body = csv_rows(bundled, lambda k: k / rate, lambda t: f"{t:.4f}", ";", ",")
    (tmp_path / "runB.csv").write_text("Time [s];Enc_Primary_counts;Enc_Secondary_counts\n"
                                       + "\n".join(body) + "\n")  # fmt: skip
    enc = {**CSV_ENCODERS, "counts_per_rev": 40000, "time": "Time [s]"}
    write_map(tmp_path / "map.toml", bundled, enc)
    import_recording(tmp_path / "runB.csv", tmp_path / "map.toml", tmp_path / "out.h5")
    assert_same_recording(read_recording(tmp_path / "out.h5"), bundled)


def test_absolute_labview_timestamps_and_a_units_row_are_read(bundled, tmp_path):
    # seconds since 1904 to the microsecond: in float64 their steps scatter by 1e-6 s
    start = 3_792_000_000.123456
    rate = bundled.sample_rate_hz
    body = csv_rows(bundled, lambda k: k, lambda k: f"{start + k / rate:.6f}", ",")
    head = "Time,Enc_Primary_counts,Enc_Secondary_counts\ns,counts,counts\n"
    (tmp_path / "abs.csv").write_text(head + "\n".join(body) + "\n")
    enc = {**CSV_ENCODERS, "counts_per_rev": 40000, "time": "Time"}
    write_map(tmp_path / "map.toml", bundled, enc)
    import_recording(tmp_path / "abs.csv", tmp_path / "map.toml", tmp_path / "out.h5")
    assert_same_recording(read_recording(tmp_path / "out.h5"), bundled)


def test_a_tab_separated_txt_with_a_preamble_is_read(bundled, tmp_path):
    preamble = "LabVIEW Measurement\nOperator\tbench 2\n\n"
    body = csv_rows(bundled, lambda k: k, str, "\t")
    head = "Sample\tEnc_Primary_counts\tEnc_Secondary_counts\n"
    (tmp_path / "run.txt").write_text(preamble + head + "\n".join(body) + "\n")
    enc = {**CSV_ENCODERS, "counts_per_rev": 40000, "sample_rate_hz": bundled.sample_rate_hz}
    write_map(tmp_path / "map.toml", bundled, enc)
    import_recording(tmp_path / "run.txt", tmp_path / "map.toml", tmp_path / "out.h5")
    assert_same_recording(read_recording(tmp_path / "out.h5"), bundled)


def write_tdms_channels(path, primary, secondary, **properties) -> None:
    props = {"wf_increment": 1e-4, **properties}
    with TdmsWriter(str(path)) as w:
        w.write_segment(
            [
                ChannelObject("Encoders", "primary", primary, properties=props),
                ChannelObject("Encoders", "secondary", secondary, properties=props),
            ]
        )


def test_a_tdms_in_degrees_is_converted_to_counts(bundled, tmp_path):
    deg = 360.0 / bundled.counts_per_rev
    write_tdms_channels(tmp_path / "deg.tdms", bundled.primary * deg, bundled.secondary * deg,
                        unit_string="deg")  # fmt: skip
    write_map(tmp_path / "map.toml", bundled, TDMS_ENCODERS)
    import_recording(tmp_path / "deg.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    assert_same_recording(read_recording(tmp_path / "out.h5"), bundled)
    # the same angles without a unit: refused, with the fix
    write_tdms_channels(tmp_path / "bare.tdms", bundled.primary * deg, bundled.secondary * deg)
    fix = r'counts must be integers.*\[encoders\]\.unit = "deg"'
    with pytest.raises(RecordingError, match=fix):
        import_recording(tmp_path / "bare.tdms", tmp_path / "map.toml", tmp_path / "out2.h5")
    # which the map can then state
    write_map(tmp_path / "map2.toml", bundled, {**TDMS_ENCODERS, "unit": "deg"})
    import_recording(tmp_path / "bare.tdms", tmp_path / "map2.toml", tmp_path / "out2.h5")
    assert_same_recording(read_recording(tmp_path / "out2.h5"), bundled)


def test_a_32_bit_counter_rollover_is_unwrapped_on_request(bundled, tmp_path):
    # a counter preset so that it wraps a tenth into the recording, stored as uint32
    span = 2**32
    offset = span - int(bundled.primary[bundled.n_samples // 10])
    wrapped = [((c.astype(np.int64) + offset) % span).astype(np.uint32)
               for c in (bundled.primary, bundled.secondary)]  # fmt: skip
    assert np.any(np.diff(wrapped[0].astype(np.int64)) < -(2**31))  # it does wrap
    write_tdms_channels(tmp_path / "wrap.tdms", *wrapped)
    write_map(tmp_path / "map.toml", bundled, TDMS_ENCODERS)
    with pytest.raises(RecordingError, match=r"rollover_bits = 32"):
        import_recording(tmp_path / "wrap.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    assert not (tmp_path / "out.h5").exists()
    write_map(tmp_path / "map.toml", bundled, {**TDMS_ENCODERS, "rollover_bits": 32})
    import_recording(tmp_path / "wrap.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    got = read_recording(tmp_path / "out.h5")
    # the same recording but for the encoders' arbitrary zero
    shifted = dataclasses.replace(
        got, primary=got.primary - offset, secondary=got.secondary - got.secondary[0]
        + bundled.secondary[0], path=None,
    )  # fmt: skip
    assert_same_recording(shifted, bundled)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"sample_rate_hz": 20000}, r"20000 Hz, but rig\.tdms gives 10000 Hz"),
        ({"unit": "rad"}, r"'rad', but rig\.tdms says 'deg'"),
    ],
)
def test_a_map_that_contradicts_the_file_is_refused(bundled, tmp_path, change, message):
    deg = 360.0 / bundled.counts_per_rev
    write_tdms_channels(tmp_path / "rig.tdms", bundled.primary * deg, bundled.secondary * deg,
                        unit_string="deg")  # fmt: skip
    write_map(tmp_path / "map.toml", bundled, {**TDMS_ENCODERS, **change})
    with pytest.raises(RecordingError, match=message) as err:
        import_recording(tmp_path / "rig.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    assert err.value.file.endswith("map.toml")
    assert not (tmp_path / "out.h5").exists()


def test_an_import_keeps_its_provenance(bundled, tmp_path):
    import hashlib

    from rattlefit.io.recording import read_provenance

    write_tdms(tmp_path / "rig.tdms", bundled)
    write_map(tmp_path / "map.toml", bundled, TDMS_ENCODERS)
    import_recording(tmp_path / "rig.tdms", tmp_path / "map.toml", tmp_path / "out.h5")
    prov = read_provenance(tmp_path / "out.h5")
    assert prov["source"] == "rig.tdms"
    assert prov["source_sha256"] == hashlib.sha256((tmp_path / "rig.tdms").read_bytes()).hexdigest()
    assert prov["channel_map"] == (tmp_path / "map.toml").read_text()
    assert prov["imported_by"].startswith("rattlefit ")
    assert read_provenance(BOUNDARY) is None  # a simulated recording has none


@pytest.mark.parametrize(
    ("text", "field", "problem"),
    [
        ("Time [s];Enc_Primary_counts\n0;1\n", "Enc_Secondary_counts", "no header line"),
        ("t,Enc_Primary_counts,Enc_Secondary_counts\n0,1,2\n0.0001,x,3\n0.0002,3,4\n",
         "Enc_Primary_counts", "line 3 has 'x'"),
    ],
)  # fmt: skip
def test_a_bad_text_file_names_the_column_and_the_line(bundled, tmp_path, text, field, problem):
    (tmp_path / "bad.csv").write_text(text)
    enc = {**CSV_ENCODERS, "counts_per_rev": 40000, "sample_rate_hz": 10000.0}
    write_map(tmp_path / "map.toml", bundled, enc)
    with pytest.raises(RecordingError) as err:
        import_recording(tmp_path / "bad.csv", tmp_path / "map.toml", tmp_path / "out.h5")
    assert err.value.field == field and problem in err.value.problem


def _bad_rig_files(tmp_path, rec):
    """(rig file, map) pairs, each refused for one reason, with a word its line must hold."""
    deg = 360.0 / rec.counts_per_rev
    write_tdms_channels(tmp_path / "deg.tdms", rec.primary * deg, rec.secondary * deg,
                        unit_string="deg")  # fmt: skip
    write_tdms_channels(tmp_path / "bare.tdms", rec.primary * deg, rec.secondary * deg)
    span = 2**32
    offset = span - int(rec.primary[rec.n_samples // 10])
    wrapped = [((c + offset) % span).astype(np.uint32) for c in (rec.primary, rec.secondary)]
    write_tdms_channels(tmp_path / "wrap.tdms", *wrapped)
    (tmp_path / "cell.csv").write_text(
        "t,Enc_Primary_counts,Enc_Secondary_counts\n0,1,2\n0.0001,x,3\n0.0002,3,4\n"
    )
    maps = {
        "rate": {**TDMS_ENCODERS, "sample_rate_hz": 20000},
        "unit": {**TDMS_ENCODERS, "unit": "rad"},
        "plain": dict(TDMS_ENCODERS),
        "csv": {**CSV_ENCODERS, "counts_per_rev": 40000, "time": "t"},
    }
    for name, enc in maps.items():
        write_map(tmp_path / f"{name}.toml", rec, enc)
    (tmp_path / "unversioned.toml").write_text(
        "\n".join((tmp_path / "plain.toml").read_text().splitlines()[2:])
    )
    return [
        ("deg.tdms", "rate.toml", "gives 10000 Hz"),
        ("deg.tdms", "unit.toml", "says 'deg'"),
        ("bare.tdms", "plain.toml", 'unit = "deg"'),
        ("wrap.tdms", "plain.toml", "rollover_bits = 32"),
        ("cell.csv", "csv.toml", "line 3 has 'x'"),
        ("deg.tdms", "unversioned.toml", "version = 1"),
    ]


def test_every_bad_rig_file_is_one_line_exit_2_and_nothing_written(bundled, tmp_path):
    from click.testing import CliRunner

    from rattlefit.cli import main

    for source, channel_map, words in _bad_rig_files(tmp_path, bundled):
        out = tmp_path / "out.h5"
        result = CliRunner().invoke(
            main, ["import", str(tmp_path / source), "--map", str(tmp_path / channel_map),
                   "-o", str(out)],
        )  # fmt: skip
        lines = [x for x in result.output.splitlines() if x.startswith("rattlefit: error")]
        assert result.exit_code == 2 and len(lines) == 1, (source, channel_map, result.output)
        assert words in lines[0], lines[0]
        assert not out.exists() and not list(tmp_path.glob("*.tmp"))
