"""Benchmarks of rattlefit against the sharp scipy reference, at the shared recordings.

Run ``python benchmarks/run.py [--quick] [--identify] [--posterior [STEPS]] [--diagnose]
[--json out.json]``.

Every measured step runs in its own fresh ``multiprocessing`` "spawn" process, so that its peak
resident memory (``ru_maxrss``) is its own; a baseline process that only imports rattlefit gives
the reference level. Steps run one after another (never two at once), and speed is reported only
as ratios of wall times measured in the same run: nothing here asserts a time.

Rattle is chaotic: two solvers' trajectories part after ~20 ms, so accuracy is judged on the
ensemble-mean spectral features (log10 band PSDs) of ``M`` realisations released across the
gap, in units of their chaotic standard error (as ``tests/test_convergence.py`` does).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from rattlefit.testing.results import provenance, write_result
from rattlefit.testing.shared import recordings_dir
from suite_report import forward_result, match, report
from suite_steps import (
    DIAGNOSE_RECORDING,
    IDENTIFY_RECORDING,
    POSTERIOR_STEPS,
    QUICK_RECORDING,
    M,
    run_step,
)

#: The operating points of the forward comparison: the first seven shared recordings, one of
#: each regime the paper's figures show.
FORWARD_POINTS = (
    "pairII_boundary_65.0_10pct_8Hz",
    "pairII_boundary_65.4_20pct_16Hz_runout",
    "pairII_boundary_65.6_20pct_16Hz",
    "pairII_dry_65.6_20pct_16Hz",
    "pairII_oiljet_65.6_20pct_16Hz",
    "pairI_boundary_66.0_20pct_16Hz",
    "pairI_oiljet_65.4_20pct_8Hz",
)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one operating point, fewer repetitions")
    ap.add_argument("--identify", action="store_true", help="also time one identify() run")
    ap.add_argument(
        "--posterior",
        nargs="?",
        type=int,
        const=POSTERIOR_STEPS,
        default=None,
        metavar="STEPS",
        help=f"also time a posterior (identify + a chain of STEPS, default {POSTERIOR_STEPS})",
    )
    ap.add_argument(
        "--diagnose",
        action="store_true",
        help=f"also time one diagnose() of {DIAGNOSE_RECORDING} (identify + every effect)",
    )
    ap.add_argument("--json", type=Path, help="write all results to this JSON file")
    ap.add_argument(
        "--write-results",
        action="store_true",
        help="write benchmarks/results/forward.json from this run (with its provenance)",
    )
    ap.add_argument(
        "--names", nargs="+", default=list(FORWARD_POINTS), help="the shared recordings to run"
    )
    args = ap.parse_args(argv)

    if not recordings_dir().is_dir():
        print(f"the shared recordings are not at {recordings_dir()}", file=sys.stderr)
        return 2
    if args.quick:
        names = [QUICK_RECORDING]
    else:
        names = args.names
    reps = 1 if args.quick else 3

    t0 = time.perf_counter()
    res: dict = {"quick": args.quick, "names": names, "memory": {}}
    res["load_before"] = os.getloadavg()
    base = run_step("baseline", {})
    res["machine"] = base["machine"]
    res["devices"] = base["devices"]
    res["memory"]["baseline"] = base["peak_mib"]

    for step, step_args in (
        ("reference", {"names": names}),
        ("forward", {"names": names, "reps": reps}),
    ):
        res[step] = run_step(step, step_args)
        res["memory"][step] = res[step]["peak_mib"]
    res["match"] = {
        n: match(res["reference"]["points"][n], res["forward"]["points"][n]) for n in names
    }
    rtol = {n: res["match"][n]["rtol"] for n in names}
    res["paired"] = run_step(
        "paired", {"names": names, "rtol": rtol, "pairs": 2 if args.quick else M}
    )
    res["memory"]["paired"] = res["paired"]["peak_mib"]
    res["batch"] = run_step("batch", {"names": names, "rtol": rtol, "reps": 1})
    res["memory"]["batch"] = res["batch"]["peak_mib"]
    res["jacobian"] = run_step("jacobian", {"names": names, "reps": 2 if args.quick else 3})
    res["memory"]["jacobian"] = res["jacobian"]["peak_mib"]
    if args.identify:
        res["identify"] = run_step("identify", {"file": IDENTIFY_RECORDING})
        res["memory"]["identify"] = res["identify"]["peak_mib"]
    if args.posterior:
        res["posterior"] = run_step(
            "posterior", {"file": IDENTIFY_RECORDING, "steps": args.posterior}
        )
        res["memory"]["posterior"] = res["posterior"]["peak_mib"]
    if args.diagnose:
        res["diagnose"] = run_step("diagnose", {"file": DIAGNOSE_RECORDING})
        res["memory"]["diagnose"] = res["diagnose"]["peak_mib"]
    res["wall_s"] = time.perf_counter() - t0
    res["load_after"] = os.getloadavg()

    text = report(res)
    print(text)
    if args.write_results:
        import rattlefit

        rattlefit.configure()  # the platform as the steps had it (one device per core)
        doc = {**forward_result(res), **provenance()}
        write_result(Path(__file__).parent / "results" / "forward.json", doc)
        print("wrote benchmarks/results/forward.json")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=1, default=float))
        print(f"results written to {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
