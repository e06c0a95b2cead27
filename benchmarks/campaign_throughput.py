"""A campaign's throughput against the number of dask workers, and what in it does not grow
with more workers (the client's single-process steps), extrapolated to the paper's
180-recording campaign on N machines.

    python benchmarks/campaign_throughput.py [--recordings 12] [--workers 1,2]
        [--result benchmarks/results/campaign.json]

A synthetic campaign (pair II, dry, boundary and oil jet, 20 % at 16 Hz, 1 s recordings) is
identified at the test suite's quick settings on a local cluster of 1, then 2 worker
processes of one core each, with the compilation cache warmed first by a run of one recording
per lubrication (a long campaign compiles once). Each run starts from an empty directory.
Measured: the wall time of each phase (starting the cluster, reading, identifying, the table
and report), the client's busy time, each task's time on its worker. Then the client's
single-process steps (the plan, resumption's checks, the table and the report: the client's
``finish``) are timed on the real results replicated to 12, 60 and 180 recordings, which
shows how they grow with the campaign. The extrapolation: T(N machines of C cores) =
start + read + ⌈180 / (N·C)⌉ × the task time with every core busy + the client's steps at
180 recordings.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import rattlefit
from rattlefit.campaign import (
    CampaignGrid,
    CampaignOptions,
    ClusterOptions,
    read_manifest,
    run_campaign,
    simulate_campaign,
)
from rattlefit.campaign.manifest import Manifest, Unit
from rattlefit.campaign.schedule import Store, finish, plan
from rattlefit.campaign.synthetic import PAPER_CENTER_DISTANCES
from rattlefit.problem.options import FitOptions
from rattlefit.testing.results import provenance, write_result

ROOT = Path(__file__).resolve().parents[1]
#: The fits: the test suite's quick settings (identify --quick, 8 starts, 8 iterations).
FIT = FitOptions.quick(seed=0, n_starts=8, max_iterations=8)
OPTIONS = CampaignOptions(fit=FIT, resimulations=2)
SIZES = (12, 60, 180)
PAPER_CAMPAIGN = 180
MACHINES = (1, 2, 5, 10, 20, 45, 90)


def run(manifest: Path, workers: int, cache: Path, out: Path) -> dict:
    """One campaign on a fresh local cluster of ``workers`` one-core workers."""
    t0 = time.perf_counter()
    cluster = ClusterOptions(
        workers=workers, cores_per_worker=1, compilation_cache=cache, dashboard=False
    )
    result = run_campaign(manifest, out, options=OPTIONS, cluster=cluster, progress=log)
    wall = time.perf_counter() - t0
    records = [json.loads(p.read_text()) for p in sorted((out / "tasks").glob("fit-*.json"))]
    tasks = [r["wall_s"] for r in records]
    return {
        "workers": workers,
        "recordings": len(records),
        "wall_s": wall,
        "phases_s": result.phases,
        "client_busy_s": result.client_s,
        "task_s": tasks,
        "task_mean_s": statistics.mean(tasks),
        "identify_mean_s": statistics.mean(r["timings"]["identify"] for r in records),
        "recordings_per_min": 60 * len(records) / result.phases["run"],
        "failures": len(result.failures),
        "records": records,
    }


def replicated(records: list[dict], docs: dict, n: int) -> list[tuple[Unit, dict, dict]]:
    """``n`` units made of the real ones cycled: each its own name and recording (moved along
    the paper's centre distances), with a real run's JSON and recording descriptions."""
    out = []
    for k in range(n):
        rec = records[k % len(records)]
        cd = PAPER_CENTER_DISTANCES[k % len(PAPER_CENTER_DISTANCES)]
        infos = [
            {**info, "recording": f"{info['recording']}_c{k}", "center_distance_mm": cd}
            for info in rec["recording_info"]
        ]
        unit = Unit(f"u{k}", tuple(i["recording"] for i in infos), None)
        out.append((unit, docs[rec["unit"]], infos))
    return out


def client_steps(records: list[dict], docs: dict, n: int, directory: Path) -> dict:
    """The client's single-process steps for a campaign of ``n`` recordings, timed on the
    real results replicated: the plan with no stage done, the plan with every stage done
    (resumption's checks of ``n`` records and their files), and the finish (the table and
    the report from the records, as ``run_campaign`` does)."""
    units = replicated(records, docs, n)
    inspections = {
        u.name: {"error": None, "test_point": None, "recordings": [{"sha256": f"{i:064x}"}]}
        for i, (u, _, _) in enumerate(units)
    }
    store = Store(directory)
    only = tuple(u for u, _, _ in units)
    t = time.perf_counter()
    plans = plan(only, inspections, OPTIONS, store.done)
    plan_s = time.perf_counter() - t
    for p, (_, doc, infos) in zip(plans, units, strict=True):
        found = {"doc": doc, "recordings": infos}
        store.write_stage(p, "fit", found, {"rattlefit": "bench"})
    t = time.perf_counter()
    plans = plan(only, inspections, OPTIONS, store.done)
    check_s = time.perf_counter() - t
    assert not any(p.pending for p in plans)
    t = time.perf_counter()
    manifest = Manifest(directory / "replicated.csv", ())
    finish(store, manifest, only, plans, OPTIONS, [], lambda msg: None)
    finish_s = time.perf_counter() - t
    return {
        "recordings": n,
        "plan_s": plan_s,
        "resume_check_s": check_s,
        "finish_s": finish_s,
        "total_s": plan_s + check_s + finish_s,
    }


def log(msg: str) -> None:
    print(f"  {msg}", file=sys.stderr, flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--recordings", type=int, default=12, help="multiple of 3")
    ap.add_argument("--workers", default="1,2")
    ap.add_argument("--result", type=Path, default=ROOT / "benchmarks/results/campaign.json")
    args = ap.parse_args()
    rattlefit.configure(cpu_cores=1)  # this process simulates the recordings; workers fit
    counts = [int(w) for w in args.workers.split(",")]
    per_lub = max(1, args.recordings // 3)
    cds = tuple(PAPER_CENTER_DISTANCES[i % 6] + 0.05 * (i // 6) for i in range(per_lub))
    grid = CampaignGrid(
        pairs=("II",), center_distances_mm=cds, fluctuations_pct=(20.0,), frequencies_hz=(16.0,)
    )
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        log(f"simulating {len(grid.points())} recordings …")
        manifest = simulate_campaign(tmp / "recordings", grid=grid, duration=1.0, seed=100)
        cache = tmp / "jax"
        warm_manifest = tmp / "warm.csv"
        entries = read_manifest(manifest).entries
        firsts = {}
        for e in entries:
            firsts.setdefault(e.path.name.split("_")[1], e)
        warm_manifest.write_text("recording\n" + "".join(f"{e.path}\n" for e in firsts.values()))
        log("warming the compilation cache (one recording per lubrication, one worker) …")
        t = time.perf_counter()
        run(warm_manifest, 1, cache, tmp / "warm")
        warm_s = time.perf_counter() - t
        runs = {}
        for n in counts:
            log(f"the campaign on {n} worker(s) …")
            runs[n] = run(manifest, n, cache, tmp / f"run{n}")
        records = runs[max(counts)]["records"]
        out = tmp / f"run{max(counts)}"
        docs = {r["unit"]: json.loads((out / next(iter(r["files"]))).read_text()) for r in records}
        steps = [client_steps(records, docs, n, tmp / f"client{n}") for n in SIZES]
    base, top = runs[min(counts)], runs[max(counts)]
    speedup = base["phases_s"]["run"] / top["phases_s"]["run"]
    ideal = max(counts) / min(counts)
    cores = os.cpu_count() or 1
    read_per_unit = top["phases_s"]["read"] / top["recordings"] * max(counts)
    client180 = steps[-1]["total_s"]
    start = top["phases_s"]["connected"]
    extrapolated = {
        str(m): start
        + read_per_unit * math.ceil(PAPER_CAMPAIGN / (m * cores))
        + math.ceil(PAPER_CAMPAIGN / (m * cores)) * top["task_mean_s"]
        + client180
        for m in MACHINES
    }
    serial_share = client180 / extrapolated[str(MACHINES[-1])]
    per_recording_client = [s["total_s"] / s["recordings"] for s in steps]
    verdict = (
        "met"
        if speedup >= 0.8 * ideal and top["client_busy_s"] < 0.05 * top["wall_s"]
        else "missed"
    )
    for r in runs.values():
        del r["records"]
    doc = {
        "order": 6,
        "headline": True,
        "what": "`rattlefit campaign` throughput against dask workers (one core each), and "
        "the client's single-process steps against the campaign's size",
        "summary": f"{speedup:.2f}× the identifications' throughput on {max(counts)} workers "
        f"as on {min(counts)} ({top['recordings_per_min']:.1f} against "
        f"{base['recordings_per_min']:.1f} recordings a minute at the quick settings, 1 s "
        f"recordings); the client busy {100 * top['client_busy_s'] / top['wall_s']:.1f} % of "
        f"the run; its single-process steps {client180:.1f} s at 180 recordings "
        f"({1e3 * per_recording_client[-1]:.0f} ms a recording, "
        f"{1e3 * per_recording_client[0]:.0f} at 12); 180 recordings extrapolated: "
        f"{extrapolated['1'] / 60:.0f} min on 1 machine of {cores} cores, "
        f"{extrapolated['10'] / 60:.1f} min on 10, {extrapolated['90']:.0f} s on 90",
        "aim": "throughput ≥ 80 % of linear in the workers; the client busy < 5 % of the run",
        "verdict": verdict,
        "measured": "benchmarks/campaign_throughput.py: a synthetic campaign of "
        f"{top['recordings']} recordings (pair II, dry, boundary, oil jet; 20 % at 16 Hz; 1 s) "
        "identified with identify --quick, 8 starts, 8 iterations, 2 re-simulations, on local "
        "clusters of one-core workers, the compilation cache warm; each run from an empty "
        "directory. Speed-up: the identification phase's wall time. The client's steps (the "
        "plan, resumption's checks, the table, the report) timed on the results replicated "
        "to 12, 60 and 180 recordings. Extrapolation: start + read + ⌈180/(N·C)⌉ × the mean "
        f"task time with every core busy + the client's steps at 180, C = {cores}.",
        "devices": 1,
        "results": {
            "runs": {str(k): v for k, v in runs.items()},
            "speedup": speedup,
            "ideal_speedup": ideal,
            "warm_up_s": warm_s,
            "client_steps": steps,
            "extrapolated_180_s": extrapolated,
            "serial_share_at_90_machines": serial_share,
            "cores_per_machine": cores,
            "load_average_before": load_before,
            "load_average_after": os.getloadavg(),
        },
        **provenance(),
    }
    write_result(args.result, doc)
    print(json.dumps({k: doc[k] for k in ("summary", "verdict")}, indent=1, ensure_ascii=False))
    print(f"wrote {args.result}")


if __name__ == "__main__":
    main()
