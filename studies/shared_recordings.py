"""The learned likelihood on someone else's simulator: every 3 s recording in
``../shared/recordings`` without an unmodelled effect, identified with
``FitOptions(likelihood="learned")``, its intervals against ``truth.json``.

    python studies/shared_recordings.py [--seed 0] [--json studies/results/shared_recordings.json]

Per recording: the 95 % intervals of ``a``, the drag torque and the viscosity against the
truth, whether each is two-sided, χ² and its p-value, the check against fresh simulations,
and the wall time.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import statistics
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

from common import held, tree_state, write_result

import rattlefit as rf
from rattlefit.testing.shared import recordings_dir

ROOT = Path(__file__).resolve().parents[1]
SHARED = recordings_dir(ROOT)


def entry(p, truth: float) -> dict:
    """One parameter's interval against its truth."""
    return {
        "truth": truth,
        "estimate": p.estimate,
        "lower": p.lower,
        "upper": p.upper,
        "bound": p.bound,
        "holds": bool(p.lower <= truth <= p.upper),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=str(ROOT / "studies" / "results" / "shared_recordings.json"))
    ap.add_argument("names", nargs="*", help="recordings (default: every one without effects)")
    args = ap.parse_args()
    devices = rf.configure().devices
    truth = json.loads((SHARED / "truth.json").read_text())
    names = args.names or sorted(
        n for n, t in truth.items() if not t["unmodelled_effects"] and not n.endswith("_30s")
    )
    rows = []
    # each recording in a fresh process: one process that compiled the learned fits of eight
    # recordings ran out of memory for its compiled code at the ninth
    fresh = multiprocessing.get_context("spawn")
    for name in names:
        path = next(SHARED.rglob(f"{name}.h5"))
        with ProcessPoolExecutor(1, mp_context=fresh) as pool:
            r = pool.submit(identify_row, str(path), args.seed, truth[name]).result()
        rows.append(r)
        params = r["parameters"]
        marks = " ".join(f"{k}:{'IN' if v['holds'] else 'OUT'}" for k, v in params.items())
        tb = params["drag_torque"]
        print(
            f"{name}: {marks}; T_b [{tb['lower']:.4g}, {tb['upper']:.4g}] (truth {tb['truth']}); "
            f"χ² {r['chi2']:.1f}/{r['dof']} (p {r['p_value']:.2g}); check "
            f"{'passed' if r['check_passed'] else 'FAILED'}; {r['wall_s']:.0f} s",
            flush=True,
        )
        write(args, rows, devices)


def identify_row(path: str, seed: int, t: dict) -> dict:
    """One recording identified on the learned likelihood, its intervals against its truth
    ``t`` (an entry of ``truth.json``)."""
    rf.configure()
    t0 = time.perf_counter()
    res = rf.identify([rf.read_recording(path)], rf.FitOptions(seed=seed, likelihood="learned"))
    params = {
        "film_half_length": entry(res.estimates.parameters["film_half_length"], t["a_mm"] * 1e-3),
        "drag_torque": entry(res.estimates.parameters["drag_torque"], t["drag_torque_Nm"]),
        "viscosity": entry(res.estimates.parameters["viscosity"], t["viscosity_Pa_s"]),
    }
    return {
        "recording": Path(path).stem,
        "chi2": res.statistics.chi2,
        "dof": res.statistics.dof,
        "p_value": res.statistics.p_value,
        "check_passed": res.provenance.likelihood["check_passed"],
        "wall_s": time.perf_counter() - t0,
        "parameters": params,
    }


def write(args, rows: list, devices: int) -> None:
    """Write the result file (atomically) from the recordings so far."""
    n_held, total = held(rows)
    drag = [r["parameters"]["drag_torque"] for r in rows]
    two_sided = [d["upper"] / d["lower"] for d in drag if d["lower"] > 0]
    widths = (
        f"; T_b two-sided in {len(two_sided)}, its median width ×{statistics.median(two_sided):.2f}"
        if two_sided
        else "; T_b one-sided in all"
    )
    doc = {
        "headline": True,
        "order": 7.5,
        "what": "`identify --likelihood learned` on the independent simulator's clean 3 s "
        "recordings: truth inside the 95 % intervals of `a`, `T_b` and μ",
        "command": "python studies/shared_recordings.py --seed "
        + str(args.seed)
        + (" " + " ".join(args.names) if args.names else ""),
        **tree_state(),
        "date": time.strftime("%Y-%m-%d"),
        "platform": rf.platform_info(),
        "devices": devices,
        "summary": f"{n_held}/{total} intervals hold their truth over {len(rows)} recordings"
        + widths,
        "aim": "95 % intervals hold the truth (about 95 % of them)",
        "verdict": "met" if n_held >= 0.9 * total else "not met",
        "rows": rows,
    }
    write_result(args.json, doc)
    print(doc["summary"], flush=True)


if __name__ == "__main__":
    main()
