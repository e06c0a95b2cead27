"""Coverage and interval widths over the coverage grid, per feature set (the width
study): `studies/coverage.py` run once with each `FitOptions.features`, on the same seeded
cases, and each parameter's median log width per lubrication compared.

    python studies/feature_sets.py [--seed 0] [--cases 10] [--from DIR] [--json OUT]

Each coverage run writes ``DIR/coverage_seed<seed>_<features>.json`` and is reused when that
file exists. A one-sided interval's log width runs to the end of the parameter's range (a
lower end reported as 0 stands for the range's lower end).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

from common import log_width, tree_state, write_result

from rattlefit.reproducibility import platform_info

FEATURE_SETS = ("bands", "bands+folded")
PARAMETERS = ("film_half_length", "drag_torque", "viscosity")
HERE = Path(__file__).resolve().parent


def coverage_run(directory: Path, seed: int, cases: int, features: str) -> dict:
    """The coverage study's JSON for ``features`` (run when absent)."""
    out = directory / f"coverage_seed{seed}_{features.replace('+', '_')}.json"
    if not out.exists():
        subprocess.run(
            [sys.executable, str(HERE / "coverage.py"), "--seed", str(seed), "--cases",
             str(cases), "--quiet", "--set", f"features={json.dumps(features)}",
             "--json", str(out)],
            check=True,
        )  # fmt: skip
    return json.loads(out.read_text())


def summary(run: dict) -> dict:
    """Coverage and each parameter's median log width, over all cases and per lubrication."""
    cases = run["cases"]
    out = {
        "covered": sum(c[k]["covered"] for c in cases for k in PARAMETERS),
        "intervals": len(PARAMETERS) * len(cases),
        "median_log_width": {},
    }
    groups = {"all": cases}
    for c in cases:
        groups.setdefault(c["case"].split(", ")[1], []).append(c)
    for group, members in groups.items():
        out["median_log_width"][group] = {
            k: round(statistics.median(log_width(c[k], k) for c in members), 3) for k in PARAMETERS
        }
    return out


def result_document(seed: int, summaries: dict) -> dict:
    base, rich = (summaries[f] for f in FEATURE_SETS)
    ratio = {
        k: base["median_log_width"]["all"][k] / rich["median_log_width"]["all"][k]
        for k in PARAMETERS
    }

    def phrase(f: str) -> str:
        s = summaries[f]
        w = s["median_log_width"]["all"]
        return (
            f"{f}: coverage {s['covered']}/{s['intervals']}, median log width a "
            f"{w['film_half_length']:.2f}, "
            f"T_b {w['drag_torque']:.2f}, μ {w['viscosity']:.2f}"
        )

    return {
        "order": 7.5,
        "what": "coverage and interval widths over the coverage grid per feature set "
        "(--features bands against bands+folded, the same seeded cases)",
        "summary": "; ".join(phrase(f) for f in FEATURE_SETS)
        + "; the folded statistics divide the median log width by "
        + f"{ratio['film_half_length']:.2f} (a) and "
        f"{ratio['drag_torque']:.2f} (T_b)",
        "aim": "median log width of a and T_b halved, coverage ≥ 90 %",
        "verdict": "met"
        if min(ratio["film_half_length"], ratio["drag_torque"]) >= 2
        and rich["covered"] >= 0.9 * rich["intervals"]
        else "missed",
        "measured": f"studies/coverage.py --seed {seed} with each feature set",
        "command": f"python studies/feature_sets.py --seed {seed} --json OUT",
        "results": {"seed": seed, **summaries},
        "platform": platform_info(),
        **tree_state(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases", type=int, default=10)
    ap.add_argument("--from", dest="directory", default="studies/results/raw/feature_sets")
    ap.add_argument("--json")
    args = ap.parse_args()
    directory = Path(args.directory)
    directory.mkdir(parents=True, exist_ok=True)
    summaries = {}
    for features in FEATURE_SETS:
        summaries[features] = summary(coverage_run(directory, args.seed, args.cases, features))
        s = summaries[features]
        print(f"{features:13s} coverage {s['covered']}/{s['intervals']}; median log widths:")
        for group, w in s["median_log_width"].items():
            print(f"  {group:9s} " + ", ".join(f"{k} {v:.2f}" for k, v in w.items()))
    if args.json:
        write_result(args.json, result_document(args.seed, summaries))


if __name__ == "__main__":
    main()
