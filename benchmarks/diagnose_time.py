"""How long one diagnosis with every candidate takes, compile included, against the
identification it starts from in the same run.

It runs ``diagnose(--every-effect)`` of one 3 s recording (by default the shared pair II
run-out file) in a fresh process, as a user's ``rattlefit diagnose FILE --every-effect``
would, and reports its wall time, the identification's share of it (the same run's
baseline: the ratio diagnosis / identification does not depend on the CPU's speed the way
the seconds do), each candidate's time, the verdict and the process's peak memory. The aim is
under 15 minutes on 2 cores.

    python benchmarks/diagnose_time.py [--file FILE] [--json out.json]

Seed: the diagnosis' fit seed 0.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import resource
import sys
import time
from pathlib import Path

from rattlefit.reproducibility import platform_info
from rattlefit.testing.results import tree_state, write_result

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_FILE = ROOT.parent / "shared" / "recordings" / "pairII_boundary_65.4_20pct_16Hz_runout.h5"
AIM_S = 900.0


def timed_diagnosis(path: str) -> dict:
    """The diagnosis of ``path`` with every candidate, in this (fresh) process: its wall
    time, the identification's, each candidate's, the verdict and the peak RSS."""
    import rattlefit as rf
    from rattlefit.diagnosis.diagnose import DiagnoseOptions, diagnose

    devices = rf.configure().devices
    t0 = time.perf_counter()
    diag = diagnose(
        [rf.read_recording(path)],
        DiagnoseOptions(every_effect=True),
        progress=lambda msg: print(f"  {msg}", file=sys.stderr, flush=True),
    )
    wall = time.perf_counter() - t0
    return {
        "total_s": round(wall, 1),
        "identify_s": round(diag.baseline.provenance.wall_time, 1),
        "per_effect_s": {o.name: round(o.wall_time, 1) for o in diag.outcomes},
        "gap_chi2": round(diag.gap_chi2[0], 2),
        "dof": diag.gap_chi2[1],
        "verdict": diag.verdict.label,
        "devices": devices,
        "peak_memory_MiB": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
        "platform": platform_info(),  # the measuring process's (its device count)
    }


def result_document(path: Path, res: dict) -> dict:
    """The README result file of one run."""
    slowest = sorted(res["per_effect_s"].items(), key=lambda kv: -kv[1])[:2]
    ratio = res["total_s"] / res["identify_s"]
    met = res["total_s"] < AIM_S
    return {
        "order": 11,
        "what": "`diagnose` fitting every candidate (`--every-effect`), one 3 s recording, "
        "compile included",
        "summary": (
            f"{res['total_s']:.0f} s on {path.stem} ({ratio:.0f}× its identification, "
            f"{res['identify_s']:.0f} s, in the same run); the slowest candidates "
            + ", ".join(f"{n} {s:.0f} s" for n, s in slowest)
            + f"; verdict {res['verdict']}. By default only the candidates that could be "
            "named are fitted"
        ),
        "aim": "< 15 min",
        "verdict": ("met" if met else "missed")
        + f" ({res['total_s']:.0f} s, {100 * res['total_s'] / AIM_S:.0f} % of the aim)",
        "measured": "benchmarks/diagnose_time.py: one diagnosis in a fresh spawned process, "
        "compile included, fit seed 0",
        "command": f"python benchmarks/diagnose_time.py --file {path}",
        "results": {k: v for k, v in res.items() if k != "platform"},
        "platform": res["platform"],
        **tree_state(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--file", default=str(DEFAULT_FILE))
    ap.add_argument("--json", help="write the README result file here")
    args = ap.parse_args()
    path = Path(args.file)
    if not path.is_file():
        ap.error(f"--file {path}: no such recording")
    with mp.get_context("spawn").Pool(1) as pool:  # a fresh process: compile included
        res = pool.apply(timed_diagnosis, (str(path),))
    print(
        f"{path.name}: {res['total_s']:.0f} s (identify {res['identify_s']:.0f} s), "
        f"verdict {res['verdict']}, peak {res['peak_memory_MiB']} MiB"
    )
    for name, seconds in res["per_effect_s"].items():
        print(f"  {name:24s} {seconds:6.0f} s")
    if args.json:
        write_result(args.json, result_document(path, res))


if __name__ == "__main__":
    main()
