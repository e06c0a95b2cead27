"""The command line: clean errors, atomic outputs, and what it prints."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from rattlefit.cli import main
from rattlefit.documents import FIT
from rattlefit.io.recording import read_recording, read_truth

DATA = Path(__file__).resolve().parents[1] / "data"


def test_info_on_shared_recording(shared_recordings):
    path = shared_recordings / "pairII_boundary_65.6_20pct_16Hz.h5"
    result = CliRunner().invoke(main, ["info", str(path), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.output)
    assert summary["gear_pair"]["teeth"] == [19, 41]
    assert summary["operating"]["lubrication"] == "boundary"
    assert summary["duration_s"] == pytest.approx(3.0)
    assert summary["notes"] == []
    # the paper's oil at 20 °C: the independent simulator's truth viscosity
    assert summary["operating"]["viscosity_Pa_s"] == pytest.approx(0.4942, abs=1e-4)


def test_info_text_names_igr_and_backlash():
    result = CliRunner().invoke(main, ["info", str(DATA / "pairII_boundary_65.6_20pct_16Hz.h5")])
    assert result.exit_code == 0, result.output
    assert "IGR" in result.output and "backlash" in result.output


def test_bad_file_gives_one_clean_message(tmp_path):
    bad = tmp_path / "notes.h5"
    bad.write_text("not an hdf5 file")
    proc = subprocess.run(
        [sys.executable, "-m", "rattlefit.cli", "info", str(bad)], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert str(bad) in proc.stderr and proc.stderr.count("\n") == 1


def test_missing_attribute_is_named(tmp_path, shared_recordings):
    path = tmp_path / "r.h5"
    shutil.copy(shared_recordings / "pairII_dry_65.6_20pct_16Hz.h5", path)
    with h5py.File(path, "r+") as f:
        del f["operating"].attrs["lubrication"]
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 2
    assert "/operating@lubrication" in result.output


def test_simulate_writes_valid_recording_with_truth(tmp_path):
    out = tmp_path / "syn.h5"
    args = [
        "simulate",
        "--pair",
        "II",
        "--center-distance-mm",
        "65.0",
        "--fluctuation-pct",
        "10",
        "--frequency",
        "8",
        "--film-half-length-mm",
        "0.085",
        "--drag-torque",
        "0.025",
        "--duration",
        "1.0",
        "--seed",
        "7",
        "-o",
        str(out),
    ]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    rec = read_recording(out)
    truth = read_truth(out)
    assert truth["film_half_length"] == pytest.approx(0.085e-3)
    assert truth["seed"] == 7
    assert rec.operating.drive_frequency_hz == 8.0
    # the relative motion stays inside the backlash written in the file (plus contact
    # deflection and quantisation), as on the rig
    assert np.ptp(rec.relative_motion) < 1.1 * rec.gear_pair.angular_backlash_rad
    # reproducible: same seed, same counts
    again = tmp_path / "again.h5"
    CliRunner().invoke(main, [*args[:-1], str(again)])
    assert np.array_equal(read_recording(again).secondary, rec.secondary)


def test_simulate_refuses_unphysical_and_keeps_old_output(tmp_path):
    out = tmp_path / "syn.h5"
    out.write_bytes(b"precious")
    result = CliRunner().invoke(
        main,
        [
            "simulate",
            "--pair",
            "II",
            "--film-half-length-mm",
            "0.1",
            "--drag-torque",
            "-1",
            "-o",
            str(out),
        ],
    )
    assert result.exit_code == 2
    assert "drag_torque" in result.output
    assert out.read_bytes() == b"precious"
    assert list(tmp_path.iterdir()) == [out]


def prior_factor(name: str, priors: dict) -> float:
    """The 95 % factor a parameter's prior alone gives (``priors``: the fit document's, by
    name; the default prior otherwise): ``inf`` for a parameter without one."""
    from rattlefit.inference.design import interval_factors
    from rattlefit.problem.parameters import prior_template

    log_sd = priors[name]["log_sd"] if name in priors else prior_template(name).log_sd
    return float("inf") if log_sd is None else interval_factors([name], [[log_sd**-2.0]])[name]


def check_suggestion(plan: dict, output: str, priors: dict) -> None:
    """``--suggest``: information from one more recording adds to the fit's, so no candidate
    may predict a wider interval than the fit alone for any parameter; the longer run of the
    same test narrows every parameter the data inform (whose factor now is narrower than its
    prior's, ``priors`` the fit's by name: a simulated estimate of the information can find
    none above its Monte Carlo noise); the seed and realisations used are reported."""
    assert "with one more recording" in output and "seed 0" in output
    assert plan["seed"] == 0 and plan["realisations"] >= 2
    now, *rest = plan["candidates"]
    assert now["recording"] == "now" and len(rest) >= 6
    inf = float("inf")
    for row in rest:
        for name, factor in now["factors"].items():
            before = inf if factor is None else factor
            after = inf if row["factors"][name] is None else row["factors"][name]
            assert after <= before * (1 + 1e-9), (row["recording"], name, before, after)
    longer = next(r for r in rest if "as long" in r["recording"])
    informed = [
        k
        for k, f in now["factors"].items()
        if f is not None and f < prior_factor(k, priors) * (1 - 1e-6)
    ]
    for k in informed:
        assert longer["factors"][k] < now["factors"][k] * (1 - 1e-6), (k, now, longer)
    assert any("oil-jet companion" in r["recording"] for r in rest)


def test_identify_writes_json_plots_and_a_suggestion(tmp_path):
    # one quick fit (four starts) serves the JSON, the figures and --suggest
    out = tmp_path / "result.json"
    plots = tmp_path / "plots"
    path = DATA / "pairII_boundary_65.6_20pct_16Hz.h5"
    result = CliRunner().invoke(
        main,
        [
            "identify",
            str(path),
            "--quick",
            "--starts",
            "4",
            "-q",
            "-o",
            str(out),
            "--plot",
            str(plots),
            "--prior",
            "min_film=3um:0.1",
            "--suggest",
        ],
    )
    assert result.exit_code == 0, result.output
    assert "drag_torque" in result.output and "95 % interval" in result.output
    doc = json.loads(out.read_text())
    # the prior given is the one fitted with, and recorded: h_min known to 10 % keeps the
    # interval within the prior's reach (the default prior's 95 % factor is 15.6)
    assert doc["fit"]["options"]["priors"]["min_film"]["log_sd"] == 0.1
    h = doc["parameters"]["min_film"]
    assert 3e-6 * np.exp(-0.45) < h["lower"] < h["upper"] < 3e-6 * np.exp(0.45), h
    for name, unit in (("film_half_length", "m"), ("drag_torque", "N m"), ("viscosity", "Pa s")):
        p = doc["parameters"][name]
        assert p["unit"] == unit
        assert p["lower"] <= p["upper"]
        assert p["lower"] <= p["estimate"] <= p["upper"]  # always a point estimate
    assert doc["fit"]["seed"] == 0
    # the fit says how far below the optimum's cost its profiles reach exactly when a profile
    # point lies more than 0.5 below it, and on that point's profile
    fit = doc["fit"]
    lowest = min((d, name) for name, pts in fit["profiles"].items() for _, d in pts)
    low = fit["below_optimum"]
    if lowest[0] < -0.5:
        assert low["depth"] == pytest.approx(-lowest[0]) and low["parameter"] == lowest[1], low
    else:
        assert low is None, (lowest, low)
    pngs = sorted(x.name for x in plots.iterdir())
    assert "correlation.png" in pngs and any(x.startswith("fit_0_") for x in pngs)
    assert {"profiles.png", "igr.png"} <= set(pngs)  # every figure the report has
    assert not list(tmp_path.glob("**/*.tmp"))
    check_suggestion(doc["suggest"], result.output, doc["fit"]["options"]["priors"])
    # this fit's profile figure: a cost axis from zero, the printed interval shaded
    from rattlefit.report.plots import profile_figure

    threshold = doc["fit"]["profile"]["threshold"]
    fig = profile_figure(doc["fit"]["profiles"], threshold, doc["parameters"])
    for ax, name in zip(fig.axes, doc["fit"]["profiles"], strict=True):
        p, scale = doc["parameters"][name], 1e3 if name == "film_half_length" else 1.0
        (line,) = [x for x in ax.get_lines() if x.get_label() == "profile"]
        assert min(line.get_ydata()) >= 0 and ax.get_ylim()[0] >= 0
        (span,) = ax.patches
        assert span.get_x() + span.get_width() == pytest.approx(p["upper"] * scale)
        assert span.get_x() == pytest.approx(max(p["lower"] * scale, ax.get_xlim()[0]))


def test_identify_bad_file_is_one_clean_error(tmp_path):
    bad = tmp_path / "x.h5"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 20)  # an HDF5 signature, then nothing
    result = CliRunner().invoke(main, ["identify", str(bad), "-o", str(tmp_path / "r.json")])
    assert result.exit_code == 2
    assert str(bad) in result.output
    assert not (tmp_path / "r.json").exists()


@pytest.mark.parametrize(
    ("prior", "problem"),
    [
        ("h_min=2e-6:0.1", "not a parameter that takes a prior"),
        ("min_film=2um", "expected NAME=CENTER:LOG_SD"),
        ("min_film=1000um:0.1", "outside the range"),
        ("min_film=2e-6:0.1", "must say so"),
        ("viscosity_scale=1:0", "log_sd must be a positive number"),
    ],
)
def test_identify_bad_prior_is_one_clean_error(tmp_path, prior, problem):
    out = tmp_path / "r.json"
    path = DATA / "pairII_boundary_65.6_20pct_16Hz.h5"
    result = CliRunner().invoke(main, ["identify", str(path), "--prior", prior, "-o", str(out)])
    assert result.exit_code == 2
    assert "--prior" in result.output and problem in result.output, result.output
    assert "Traceback" not in result.output
    assert not out.exists()


def test_sample_refuses_a_foreign_backend_and_keeps_it(tmp_path):
    backend = tmp_path / "notes.h5"
    with h5py.File(backend, "w") as f:
        f["x"] = np.arange(4)
    out = tmp_path / "post.json"
    result = CliRunner().invoke(
        main,
        [
            "sample",
            str(DATA / "pairII_boundary_65.6_20pct_16Hz.h5"),
            "--backend",
            str(backend),
            "-o",
            str(out),
        ],
    )
    assert result.exit_code == 2
    assert "notes.h5: /rattlefit: missing" in result.output
    assert "Traceback" not in result.output
    assert not out.exists()
    with h5py.File(backend, "r") as f:
        np.testing.assert_array_equal(f["x"][:], np.arange(4))


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (None, "no such file"),
        ('{"parameters": {', "not valid JSON (line 1"),
        ('{"chi2": 3}', "parameters: missing; not the output of rattlefit identify -o"),
    ],
)
def test_report_with_a_bad_fit_file_is_one_clean_error(tmp_path, content, problem):
    fit = tmp_path / "fit.json"
    if content is not None:
        fit.write_text(content)
    out = tmp_path / "report.html"
    proc = subprocess.run(
        [sys.executable, "-m", "rattlefit.cli", "report", "--fit", str(fit), "-o", str(out)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"rattlefit: error: {fit}: {problem}")
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == (["fit.json"] if content else [])


def test_report_finds_recordings_beside_the_fit_and_writes_html(tmp_path):
    # a fit naming its recording by a relative path, the JSON beside the recording
    shutil.copy(DATA / "pairII_boundary_65.6_20pct_16Hz.h5", tmp_path / "r.h5")
    f = np.geomspace(5.0, 4000.0, 30)
    measured = (-6.0 - 1.5 * np.log10(f / 5.0)).tolist()
    doc = {
        **FIT.header(),
        "parameters": {
            "film_half_length": {
                "unit": "m",
                "estimate": 8.5e-5,
                "lower": 7e-5,
                "upper": 1e-4,
                "identified": True,
                "bound": None,
            },
        },
        "fit": {"chi2": 30.0, "dof": 28, "p_value": 0.36, "recordings": ["r.h5"]},
        "spectra": {
            "band_centers_hz": f.tolist(),
            "measured": [measured],
            "fitted": [measured],
            "sigma": [[0.1] * 30],
        },
    }
    (tmp_path / "fit.json").write_text(json.dumps(doc))
    out = tmp_path / "out" / "report.html"
    result = CliRunner().invoke(
        main, ["report", "--fit", str(tmp_path / "fit.json"), "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    html = out.read_text(encoding="utf-8")
    assert html.startswith("<!DOCTYPE html>") and 'data-param="film_half_length"' in html
    assert "r.h5" in html
    # a recording named on the command line instead; a missing one is named
    result = CliRunner().invoke(
        main,
        [
            "report",
            "--fit",
            str(tmp_path / "fit.json"),
            "--recording",
            str(tmp_path / "gone.h5"),
            "-o",
            str(tmp_path / "x.html"),
        ],
    )
    assert result.exit_code == 2 and "gone.h5" in result.output
    assert not (tmp_path / "x.html").exists()


def test_help_and_version_start_without_jax_or_scipy():
    # the command line's start-up: --help and --version import neither JAX nor SciPy (what
    # makes them take seconds); a command still configures JAX before it runs
    probe = (
        "import sys; from click.testing import CliRunner; from rattlefit.cli import main; "
        "r = [CliRunner().invoke(main, a) for a in (['--help'], ['--version'], "
        "['identify', '--help'])]; "
        "print(all(x.exit_code == 0 for x in r), 'jax' in sys.modules, 'scipy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert out.stdout.split() == ["True", "False", "False"], out.stdout + out.stderr
    file = str(DATA / "pairII_boundary_65.6_20pct_16Hz.h5")
    probe = (
        "import sys; from click.testing import CliRunner; from rattlefit.cli import main; "
        f"r = CliRunner().invoke(main, ['info', {file!r}]); "
        "import jax; print(r.exit_code, jax.config.jax_enable_x64)"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert out.stdout.split() == ["0", "True"], out.stdout + out.stderr


def test_a_file_that_cannot_be_written_is_one_line_not_a_traceback(tmp_path):
    # an output folder under a file: the OS refuses it, and the command says so in one line
    (tmp_path / "taken").write_text("a file, not a folder")
    result = CliRunner().invoke(
        main,
        ["campaign", "simulate", "-o", str(tmp_path / "taken" / "camp"), "--pair", "II",
         "--fluctuations-pct", "20", "--frequencies", "16", "--center-distances-mm", "65.0"],
    )  # fmt: skip
    assert result.exit_code == 2, (result.output, result.exception)
    lines = [x for x in result.output.splitlines() if x.startswith("rattlefit: error")]
    assert len(lines) == 1 and "taken" in lines[0], result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["taken"]
