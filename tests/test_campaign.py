"""rattlefit campaign on a real dask cluster: a scheduler and two worker processes on loopback.

One synthetic campaign (six recordings with known truth at quick settings, and a truncated
file) is run once for the module, with one worker killed by its PID while it fits; the tests
read what it wrote, re-run it, and check the manifest, the plan and the report on their own.
"""

from __future__ import annotations

import json
import math
import os
import signal
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from rattlefit.campaign import (
    CampaignGrid,
    CampaignOptions,
    ClusterOptions,
    Unit,
    read_manifest,
    read_table,
    run_campaign,
    schedule,
    simulate_campaign,
)
from rattlefit.campaign.manifest import write_manifest
from rattlefit.campaign.report import write_campaign_report
from rattlefit.campaign.schedule import plan, stage_keys
from rattlefit.cli import main
from rattlefit.errors import RattlefitError
from rattlefit.problem.options import FitOptions

#: The campaign: gear pair II, dry, boundary and oil jet, at two centre distances, at the
#: paper's strongest setting (20 % at 16 Hz), 1 s each; recording i seeded by the i-th child
#: spawned from SEED.
GRID = CampaignGrid(
    pairs=("II",),
    center_distances_mm=(65.6, 66.0),
    fluctuations_pct=(20.0,),
    frequencies_hz=(16.0,),
)
DURATION = 1.0
SEED = 40
#: Every fit: identify --quick with 8 starts instead of 16 and up to 8 Levenberg–Marquardt
#: iterations instead of 3 (cheaper and more reliable on 1 s recordings than more starts).
FIT = FitOptions.quick(seed=0, n_starts=8, max_iterations=8)
OPTIONS = CampaignOptions(fit=FIT, resimulations=2)
#: Workers of one core each, on the default compilation cache: the test run's
#: ($RATTLEFIT_CACHE_DIR, tests/conftest.py), which they inherit and share with each other and
#: with the rest of the run, as a campaign's workers share the user's.
CLUSTER = ClusterOptions(cores_per_worker=1)

# Margins of the truth's checks, as tests/test_fit.py's.
MARGIN = 1.1  # an interval end may miss the truth by this factor (its Monte Carlo roughness)
ESTIMATE_TOLERANCE = 0.25  # an identified estimate within 25 % of the truth (test_fit: 20 %)
DRY_FILM = 10e-6  # m: as good as dry
OIL_JET_FILM = 1e-3  # m: the paper's oil-jet film

#: How long a fit runs on a worker before that worker's process is killed, s.
KILL_AFTER = 1.0


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """A scheduler (in this process, on loopback TCP) and two worker processes of one thread
    each, whose JAX has one thread in XLA's pool as every test process (tests/xla_threads.py);
    closed, workers killed, at the end of the module."""
    from distributed import Client, LocalCluster

    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
            preload=[str(Path(__file__).with_name("xla_threads.py"))],
        ) as cluster,
        Client(cluster) as c,
    ):
        yield c


@pytest.fixture(scope="module")
def manifest(tmp_path_factory):
    """The six recordings' manifest, and a truncated copy of one listed after them."""
    directory = tmp_path_factory.mktemp("recordings")
    path = simulate_campaign(directory, grid=GRID, duration=DURATION, seed=SEED)
    rows = [(str(e.path), e.group) for e in read_manifest(path).entries]
    broken = directory / "truncated.h5"
    data = Path(rows[0][0]).read_bytes()
    broken.write_bytes(data[: len(data) // 2])
    return write_manifest(directory / "with_truncated.csv", [*rows, (str(broken), None)])


def kill_a_busy_worker(client, killed: dict, stop: threading.Event) -> None:
    """Once a worker has run a fit for KILL_AFTER seconds, kill its process (SIGKILL, by
    PID) and note which."""
    pids = client.run(os.getpid)
    while not stop.is_set():
        for address, keys in client.processing().items():
            fits = [str(k) for k in keys if str(k).startswith("fit-")]
            if fits and address in pids:
                time.sleep(KILL_AFTER)
                os.kill(pids[address], signal.SIGKILL)
                killed.update(worker=address, pid=pids[address], keys=fits)
                return
        time.sleep(0.1)


@pytest.fixture(scope="module")
def campaign(client, manifest, tmp_path_factory):
    """The campaign, run once with a worker killed mid-run: (result, output, killed)."""
    out = tmp_path_factory.mktemp("campaign")
    killed, stop = {}, threading.Event()
    killer = threading.Thread(target=kill_a_busy_worker, args=(client, killed, stop))
    killer.start()
    try:
        result = run_campaign(
            manifest,
            out,
            options=OPTIONS,
            cluster=CLUSTER,
            client=client,
        )
    finally:
        stop.set()
        killer.join()
    return result, out, killed


def test_a_killed_worker_loses_only_its_task_and_a_truncated_file_is_reported(campaign):
    result, out, killed = campaign
    assert killed, "no worker was killed: no fit ran long enough"
    assert result.units == 7 and result.ran == 6 and result.skipped == 0
    # the truncated file is the one failure, named, at reading; the other six are identified
    (failure,) = result.failures
    assert failure["stage"] == "read" and "truncated.h5" in failure["error"], failure
    table = read_table(out)
    assert table["recording_name"].nunique() == 6
    assert "truncated.h5" not in set(table["recording_name"])
    # the killed worker's fit was run again elsewhere and is in the table
    killed_units = {u for u in set(table["fit"]) if any(f"-{u}-" in k for k in killed["keys"])}
    assert killed_units, (killed, sorted(set(table["fit"])))
    # every run's JSON beside the table, as identify -o writes it, and the report
    for unit in set(table["fit"]):
        doc = json.loads((out / "runs" / f"{unit}.json").read_text())
        assert {"parameters", "fit", "spectra"} <= set(doc) and doc["fit"]["seed"] == FIT.seed
    html = (out / "report.html").read_text(encoding="utf-8")
    assert html.count("<img ") == 4  # IGR of pair II, and a, T_b and μ against distance
    assert "truncated.h5" in html and "Failures" in html
    assert (out / "figures" / "igr_pairII.png").is_file()
    assert "truncated.h5" in (out / "failures.csv").read_text()
    assert not list(out.rglob("*.tmp"))


def test_the_table_holds_the_truth_where_identify_would(campaign):
    # tests/test_fit.py's properties, with margins: every estimate inside its interval; an
    # identified estimate near the truth; the drag torque and the viscosity inside their
    # intervals, and under oil jet the film too; dry flanks not given a film (the interval
    # reaches films too short to matter and, unless the fit is flagged poor and its intervals
    # widened by √(χ²/dof), excludes oil-jet films). A boundary film's interval holds its
    # truth only where the profiles follow the film's valley (the full settings, asserted
    # there): at quick settings a boundary recording is asked only for T_b and μ
    _, out, _ = campaign
    table = read_table(out)
    misses = []
    for _, row in table.iterrows():
        assert row["lower"] <= row["estimate"] <= row["upper"], row.to_dict()
        name, lub, truth = row["parameter"], row["lubrication"], row["truth"]
        where = (row["recording_name"], name, row["lower"], truth, row["upper"])
        if row["identified"] and truth and math.isfinite(truth):
            if abs(row["estimate"] / truth - 1) > ESTIMATE_TOLERANCE:
                misses.append(("identified far from the truth", *where, row["estimate"]))
        checked = name in ("drag_torque", "viscosity") or (
            name == "film_half_length" and lub == "oil_jet"
        )
        if checked and not row["lower"] / MARGIN <= truth <= row["upper"] * MARGIN:
            misses.append(("outside", *where))
        if name == "film_half_length" and lub == "dry":
            reach = row["upper"] < OIL_JET_FILM or row["poor_fit"]
            if not (row["lower"] < DRY_FILM and reach and not row["identified"]):
                misses.append(("a film on dry flanks", *where))
    assert not misses, misses
    columns = {"estimate", "lower", "upper", "identified", "chi2", "seed", "rattlefit_version"}
    assert columns <= set(table.columns)
    assert set(table["seed"]) == {FIT.seed} and table["rattlefit_version"].nunique() == 1
    assert set(table["lubrication"]) == {"dry", "boundary", "oil_jet"}
    assert (table["pair"] == "II").all()


def test_a_rerun_resumes_what_is_missing_and_then_skips_everything(campaign, client, manifest):
    _, out, _ = campaign
    before = read_table(out)
    # a client killed before it wrote one fit's record: that fit alone runs again, and gives
    # the same rows to the last bit (seeded)
    records = sorted((out / "tasks").glob("fit-*.json"))
    lost = json.loads(records[0].read_text())["unit"]
    records[0].unlink()
    again = run_campaign(
        manifest,
        out,
        options=OPTIONS,
        cluster=CLUSTER,
        client=client,
    )
    assert again.ran == 1 and again.skipped == 5, (again.ran, again.skipped, lost)
    after = read_table(out)
    columns = ["fit", "recording", "fit_parameter", "estimate", "lower", "upper", "chi2"]
    assert after[columns].equals(before[columns])
    # the command line, on the same scheduler: nothing left to do; the truncated file is
    # reported again (exit status 1), the rest is done
    args = ["campaign", str(manifest), "-o", str(out), "--quick", "--starts", "8"]
    args += ["--iterations", "8", "--seed", "0"]
    args += ["--scheduler", client.scheduler.address, "--resimulations", "2"]
    run = CliRunner().invoke(main, args)
    assert run.exit_code == 1, run.output
    assert "0 run, 6 already done, 1 failure(s)" in run.output
    assert "truncated.h5" in run.output


def test_one_learning_per_test_point():
    # on the learned likelihood, the first unit of each test point learns; the others wait
    # for it and reuse what it learned (their keys follow its fit's key)
    units = tuple(Unit(n, (f"/r/{n}.h5",), None) for n in ("a", "b", "c", "d"))
    points = {"a": "P", "b": "Q", "c": "P", "d": "P"}
    inspections = {
        n: {"error": None, "test_point": p, "recordings": [{"sha256": n * 8}]}
        for n, p in points.items()
    }
    options = CampaignOptions(fit=FitOptions.quick(likelihood="learned", drive="commanded"))
    plans = {p.unit.name: p for p in plan(units, inspections, options, lambda s, k: False)}
    assert [n for n, p in plans.items() if p.learn] == ["a", "b"]
    assert plans["c"].reuses == "a" and plans["d"].reuses == "a" and plans["b"].reuses is None
    assert plans["c"].keys["fit"] == stage_keys(["c" * 8], options, plans["a"].keys["fit"])["fit"]
    # a done learner is not learned again: its stored likelihood is what the others reuse
    done = {plans["a"].keys["fit"]}
    again = plan(units, inspections, options, lambda s, k: k in done)
    assert again[0].pending == () and again[0].learn and again[2].reuses == "a"
    # on the synthetic likelihood nothing is learned
    synthetic = plan(units, inspections, CampaignOptions(fit=FitOptions.quick()), lambda s, k: 0)
    assert not any(p.learn or p.reuses for p in synthetic)
    # a failed read leaves the unit out
    inspections["a"]["error"] = "bad"
    assert [p.unit.name for p in plan(units, inspections, options, lambda s, k: False)] == [
        "b",
        "c",
        "d",
    ]


def test_manifests_group_recordings_and_bad_ones_are_one_clear_error(tmp_path, monkeypatch):
    for name in ("a.h5", "b.h5", "c.h5"):
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "sweep.csv").write_text("recording,group\na.h5,sweep\nb.h5,\nc.h5,sweep\n")
    units = read_manifest(tmp_path / "sweep.csv").units()
    assert [(u.name, len(u.paths), u.joint) for u in units] == [("sweep", 2, True), ("b", 1, False)]
    (tmp_path / "m.toml").write_text(
        '[[recording]]\npath = "a.h5"\ngroup = "g"\n[[recording]]\npath = "c.h5"\ngroup = "g"\n'
    )
    assert [u.paths for u in read_manifest(tmp_path / "m.toml").units()] == [
        (str(tmp_path / "a.h5"), str(tmp_path / "c.h5"))
    ]
    assert len(read_manifest(tmp_path).units()) == 3  # a directory: each alone
    bad = {
        "recording,grup\na.h5,x\n": "line 1, grup: unknown column",
        "recording\na.h5\nmissing.h5\n": "line 3, recording: 'missing.h5': no such file",
        "recording\na.h5\na.h5\n": "line 3: a.h5 is listed twice (also at line 2)",
        "group\nx\n": "line 1: no column 'recording'",
        "recording,group\n,x\n": "line 2, recording: empty",
    }
    for text, problem in bad.items():
        path = tmp_path / "bad.csv"
        path.write_text(text)
        with pytest.raises(RattlefitError) as error:
            read_manifest(path)
        assert f"bad.csv: {problem}" in str(error.value)
    (tmp_path / "bad.toml").write_text('[[recording]]\npath = "a.h5"\nfile = "b.h5"\n')
    with pytest.raises(RattlefitError, match=r"bad.toml: recording\[0\].file: unknown key"):
        read_manifest(tmp_path / "bad.toml")
    # the command line: one line naming the file, the field and the problem; exit status 2
    result = CliRunner().invoke(main, ["campaign", str(path), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2
    assert result.output.startswith(f"rattlefit: error: {path}: line 2, recording: empty")
    assert result.output.count("\n") == 1
    assert not (tmp_path / "out").exists()
    # a scheduler that does not answer: one line naming it (after a second here)
    monkeypatch.setattr(schedule, "CONNECT_TIMEOUT", 1)
    args = ["campaign", str(tmp_path), "-o", str(tmp_path / "out"), "--scheduler"]
    result = CliRunner().invoke(main, [*args, "tcp://127.0.0.1:1"])
    assert result.exit_code == 2, result.output
    assert result.output.startswith("rattlefit: error: tcp://127.0.0.1:1: scheduler: ")


def test_the_report_shows_the_diagnoses_and_failures(campaign, tmp_path):
    _, out, _ = campaign
    records = [json.loads(p.read_text()) for p in sorted((out / "tasks").glob("fit-*.json"))]
    rows = read_table(out).to_dict("records")
    recordings = [r for rec in records for r in rec["recording_info"]]
    diagnosis = {
        "unit": records[0]["unit"],
        "recordings": records[0]["recordings"],
        "verdict": "runout",
        "sentence": "run-out of the driven wheel explains the misfit",
    }
    failure = {"unit": "x", "recordings": ["/r/x.h5"], "stage": "fit", "error": "SolverError: …"}
    path = write_campaign_report(
        tmp_path / "r.html",
        recordings=recordings,
        rows=rows,
        diagnoses=[diagnosis],
        failures=[failure],
        meta={"manifest": "/r/m.csv", "units": 7, "seed": 0},
    )
    html = path.read_text(encoding="utf-8")
    assert "Diagnoses" in html and "run-out of the driven wheel" in html
    assert "x.h5" in html and "SolverError" in html
    assert html.count("<img ") == 4 and "<script" not in html


def test_nothing_below_the_campaign_imports_it_and_it_imports_dask_only_when_run():
    import ast

    from test_architecture import imports_of, module_names

    modules = module_names()
    above = ("rattlefit.campaign", "rattlefit.cli")
    wrong = [
        f"{name} imports {m}"
        for name, path in modules.items()
        if not name.startswith(above)
        for m in imports_of(name, path, modules)
        if m.startswith("rattlefit.campaign")
    ]
    assert not wrong, wrong
    for name, path in modules.items():
        if name.startswith("rattlefit.campaign"):
            top = ast.parse(path.read_text(encoding="utf-8")).body
            names = [a.name for n in top if isinstance(n, ast.Import) for a in n.names]
            names += [n.module or "" for n in top if isinstance(n, ast.ImportFrom)]
            assert not [n for n in names if n.split(".")[0] in ("dask", "distributed")], name


def test_the_report_table_marks_a_poor_or_unfinished_fit_and_the_csv_prints_no_float_noise(
    tmp_path,
):
    from rattlefit.campaign.report import estimates_table
    from rattlefit.campaign.table import COLUMNS, write_table

    def row(parameter, estimate, lower, upper, bound, **fit):
        return {
            "fit": "u1", "joint": False, "key": "k", "recording": "r.h5",
            "recording_name": "r", "recording_sha256": "0", "pair": "II",
            "center_distance_mm": 65.0 + 0.4000000000000002, "lubrication": "boundary",
            "oil_temperature_c": 20.0, "mean_speed_rad_s": 52.36, "fluctuation_pct": 20.0,
            "frequency_hz": 16.0, "duration_s": 3.0, "parameter": parameter,
            "fit_parameter": parameter, "unit": "N m" if parameter == "drag_torque" else "m",
            "estimate": estimate, "lower": lower, "upper": upper, "bound": bound,
            "identified": False, "truth": None, "chi2": 71.0, "dof": 28, "p_value": 1e-5,
            "seed": 0, "rattlefit_version": "0", **fit,
        }  # fmt: skip

    rows = [
        row("drag_torque", 0.07616, 0.0, 0.2325, "upper", poor_fit=True, converged=False,
            below_optimum=17.6),
        row("film_half_length", 8e-5, 5e-5, 1.1e-4, "interval", poor_fit=True, converged=False,
            below_optimum=17.6),
    ]  # fmt: skip
    html = estimates_table(rows)
    assert "0.07616 (≤ 0.2325)" in html  # not "0.07616 ≤ 0.2325", a comparison
    assert "71.0/28 (poor fit, not converged, profiles 17.6 below the optimum)" in html
    good = [dict(r, poor_fit=False, converged=True, below_optimum=0.0) for r in rows]
    assert "71.0/28</td>" in estimates_table(good)
    _, csv = write_table(tmp_path, rows)
    text = csv.read_text()
    assert "65.4," in text and "65.40000000000002" not in text
    assert text.splitlines()[0].split(",") == list(COLUMNS)
