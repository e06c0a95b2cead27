"""Does the learned likelihood hold rattlefit's own truth? Notebook 2's joint fits (the
bundled boundary file with its oil-jet companion, and a three-distance backlash sweep) at
several fit seeds, and any further files given.

    python studies/own_data.py [--seeds 0 1 2] [--fits companion sweep] [--keep]
                               [--json studies/results/own_data.json]

``--keep`` keeps the result file's rows of the fits and seeds this run does not redo (each
row records the commit it ran at).

For each fit and seed: the 95 % intervals of the drag torque, each film half-length and the
viscosity against the truth, χ² on its degrees of freedom and its p-value, the learned
likelihood's check, and the wall time. The aim: every interval holds its truth, p > 0.01.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from common import head_commit, held, tree_state, write_result

import rattlefit as rf
from rattlefit.io.recording import read_truth
from rattlefit.simulation.synthetic import backlash_sweep

ROOT = Path(__file__).resolve().parents[1]
BOUNDARY = ROOT / "data" / "pairII_boundary_65.6_20pct_16Hz.h5"
OIL_JET = ROOT / "data" / "pairII_oil_jet_65.6_20pct_16Hz.h5"
SWEEP_CENTRE_DISTANCES_MM = (65.0, 65.4, 66.0)
SWEEP_SEEDS = (21, 22, 23)


def companion():
    """The bundled boundary file and its oil-jet companion, with their truths by name."""
    tb, to = read_truth(BOUNDARY), read_truth(OIL_JET)
    truths = {
        "film_half_length[boundary]": tb["film_half_length"],
        "film_half_length[oil_jet]": to["film_half_length"],
        "drag_torque": tb["drag_torque"],
        "viscosity": tb["viscosity"],
    }
    return [rf.read_recording(BOUNDARY), rf.read_recording(OIL_JET)], truths


def sweep():
    """Notebook 2's backlash sweep, with its truths by name."""
    runs = backlash_sweep(SWEEP_CENTRE_DISTANCES_MM, SWEEP_SEEDS)
    p = runs[0][1]
    truths = {
        "film_half_length": float(p.film_half_length),
        "drag_torque": float(p.drag_torque),
        "viscosity": float(p.viscosity),
    }
    return [rec for rec, _ in runs], truths


def row(name: str, result, truths: dict, wall: float, seed: int) -> dict:
    """One fit's intervals against the truth."""
    params = {
        k: {
            "truth": v,
            "lower": result.estimates.parameters[k].lower,
            "upper": result.estimates.parameters[k].upper,
            "estimate": result.estimates.parameters[k].estimate,
            "holds": bool(
                result.estimates.parameters[k].lower <= v <= result.estimates.parameters[k].upper
            ),
        }
        for k, v in truths.items()
    }
    return {
        "fit": name,
        "seed": seed,
        "chi2": result.statistics.chi2,
        "dof": result.statistics.dof,
        "p_value": result.statistics.p_value,
        "check_passed": result.provenance.likelihood.get("check_passed"),
        "wall_s": wall,
        "parameters": params,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument(
        "--fits", nargs="+", choices=["companion", "sweep"], default=["companion", "sweep"]
    )
    ap.add_argument("--keep", action="store_true", help="keep the other rows of the result file")
    ap.add_argument("--json", default=str(ROOT / "studies" / "results" / "own_data.json"))
    args = ap.parse_args()
    devices = rf.configure().devices
    makers = {
        "companion": ("boundary + oil-jet companion", companion),
        "sweep": ("backlash sweep", sweep),
    }
    cases = {makers[f][0]: makers[f][1]() for f in args.fits}
    redo = {(name, seed) for name in cases for seed in args.seeds}
    rows = []
    if args.keep and Path(args.json).exists():
        old = json.loads(Path(args.json).read_text())["rows"]
        rows = [r for r in old if (r["fit"], r["seed"]) not in redo]
    for name, (recs, truths) in cases.items():
        for seed in args.seeds:
            t0 = time.perf_counter()
            res = rf.identify(recs, rf.FitOptions(seed=seed, likelihood="learned"))
            r = row(name, res, truths, time.perf_counter() - t0, seed)
            r["commit"] = head_commit()
            rows.append(r)
            marks = " ".join(
                f"{k}:{'IN' if v['holds'] else 'OUT'}" for k, v in r["parameters"].items()
            )
            print(
                f"{name}, seed {seed}: {marks}; χ² {r['chi2']:.1f}/{r['dof']} "
                f"(p {r['p_value']:.2g}); {r['wall_s']:.0f} s",
                flush=True,
            )
            write(args, rows, devices)


def write(args, rows: list, devices: int) -> None:
    """Write the result file (atomically) from the fits so far."""
    n_held, total = held(rows)
    n_fitting = sum(r["p_value"] > 0.01 for r in rows)
    doc = {
        "what": "the learned likelihood on rattlefit's own data: notebook 2's joint fits at "
        "several fit seeds",
        "command": "python studies/own_data.py --seeds "
        + " ".join(map(str, args.seeds))
        + " --fits "
        + " ".join(args.fits)
        + (" --keep" if args.keep else ""),
        **tree_state(),
        "date": time.strftime("%Y-%m-%d"),
        "platform": rf.platform_info(),
        "devices": devices,
        "summary": f"{n_held}/{total} intervals hold their truth; p > 0.01 in "
        f"{n_fitting}/{len(rows)} fits",
        "aim": "every interval holds its truth, χ² consistent with its dof (p > 0.01)",
        "verdict": "met" if n_held == total and n_fitting == len(rows) else "not met",
        "rows": rows,
    }
    write_result(args.json, doc)
    print(doc["summary"], flush=True)


if __name__ == "__main__":
    main()
