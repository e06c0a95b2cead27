"""What a longer recording pins: `identify`'s 95 % intervals and run time on a 3 s and a 30 s
recording of the same operating point, per feature set.

Each pair is (3 s, 30 s) of pair II at 65.6 mm, boundary, 20 % at 16 Hz (the paper's headline
point): the independent simulator's shared recordings, and rattlefit's own (the bundled 3 s
file and a 30 s one simulated with seed 7). Every identification is a plain
``rattlefit identify FILE [--features F] -o OUT`` with the default options (seed 0); this script
runs them (or, with ``--from DIR``, reads the OUT files already in DIR, named
``<label>_<duration>_<features>.json``) and reports each parameter's log width (a one-sided
bound runs to the end of the range), the ratio of the 3 s width to the 30 s one (the width check
asks for ≥ 2), whether the truth is inside, and the wall times.

    python studies/long_recording.py [--from DIR] [--features bands,bands+folded]
                                        [--pairs shared,rattlefit] [--json out.json]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from common import identified, log_width, tree_state, write_result

from rattlefit.reproducibility import platform_info
from rattlefit.testing.shared import recordings_dir

ROOT = Path(__file__).resolve().parents[1]
SHARED = recordings_dir(ROOT)
#: label → (3 s file, 30 s file); the synthetic 30 s file is made by ``synthetic_long``.
PAIRS = {
    "shared": (
        SHARED / "pairII_boundary_65.6_20pct_16Hz.h5",
        SHARED / "long" / "pairII_boundary_65.6_20pct_16Hz_30s.h5",
    ),
    "rattlefit": (ROOT / "data" / "pairII_boundary_65.6_20pct_16Hz.h5", None),
}
SYNTHETIC_SEED = 7
#: The truth of every file here (the shared ones' from ``truth.json``, the same point).
TRUTH = {"film_half_length": 0.085e-3, "drag_torque": 0.025, "viscosity": 0.4942}
PARAMETERS = ("film_half_length", "drag_torque", "viscosity")


def synthetic_long(directory: Path) -> Path:
    """rattlefit's own 30 s recording of the headline point (seed :data:`SYNTHETIC_SEED`)."""
    path = directory / f"rattlefit_30s_seed{SYNTHETIC_SEED}.h5"
    if not path.exists():
        subprocess.run(
            [sys.executable, "-m", "rattlefit.cli", "simulate", "--pair", "II",
             "--center-distance", "65.6", "--lubrication", "boundary",
             "--film-half-length", "0.085e-3", "--drag-torque", "0.025",
             "--seed", str(SYNTHETIC_SEED), "--duration", "30", "-o", str(path)],
            check=True,
        )  # fmt: skip
    return path


def widths(doc: dict, truth: dict) -> dict:
    """Each parameter's interval, log width and whether the truth is inside."""
    out = {}
    for name in PARAMETERS:
        p = doc["parameters"][name]
        row = {"lower": p["lower"], "upper": p["upper"], "bound": p["bound"]}
        row["log_width"] = log_width(p, name)
        if name in truth:
            row["truth_inside"] = bool(p["lower"] <= truth[name] <= p["upper"])
        out[name] = row
    return out


def study(directory: Path, feature_sets: list[str], pairs: list[str], say) -> list[dict]:
    rows = []
    for label in pairs:
        short, long = PAIRS[label]
        long = long or synthetic_long(directory)
        for features in feature_sets:
            row = {"recordings": label, "features": features}
            for duration, path in (("3s", short), ("30s", long)):
                tag = features.replace("+", "_")
                doc, wall = identified(path, features, directory / f"{label}_{duration}_{tag}.json")
                row[duration] = {
                    "file": str(path.relative_to(ROOT.parent)),
                    "identify_s": doc["fit"]["wall_time_s"],
                    "process_s": wall,
                    "chi2": doc["fit"]["chi2"],
                    "dof": doc["fit"]["dof"],
                    "parameters": widths(doc, TRUTH),
                }
            row["width_ratio"] = {
                k: row["3s"]["parameters"][k]["log_width"]
                / row["30s"]["parameters"][k]["log_width"]
                for k in PARAMETERS
            }
            say(
                f"{label:9s} {features:13s} 3 s → 30 s log widths: "
                + ", ".join(
                    f"{k} {row['3s']['parameters'][k]['log_width']:.2f} → "
                    f"{row['30s']['parameters'][k]['log_width']:.2f}"
                    for k in PARAMETERS
                )
                + f"; identify {row['3s']['identify_s']:.0f} s → {row['30s']['identify_s']:.0f} s"
            )
            rows.append(row)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--from", dest="directory", default="studies/results/raw/long")
    ap.add_argument("--features", default="bands,bands+folded")
    ap.add_argument("--pairs", default=",".join(PAIRS), help="of: " + ", ".join(PAIRS))
    ap.add_argument("--json")
    args = ap.parse_args()
    directory = Path(args.directory).resolve()
    directory.mkdir(parents=True, exist_ok=True)
    pairs = args.pairs.split(",")
    unknown = sorted(set(pairs) - set(PAIRS))
    if unknown:
        ap.error(f"--pairs: unknown {', '.join(unknown)} (of {', '.join(PAIRS)})")
    rows = study(directory, args.features.split(","), pairs, print)
    if args.json:
        write_result(args.json, result_document(rows))


def row_phrase(row: dict) -> str:
    """One pair and feature set in words: each parameter's interval at 3 s → at 30 s."""

    def interval(p: dict, unit_scale: float, unit: str) -> str:
        if p["bound"] == "upper" or p["lower"] <= 0:
            return f"≤ {p['upper'] * unit_scale:.3g}"
        return f"[{p['lower'] * unit_scale:.3g}, {p['upper'] * unit_scale:.3g}]"

    parts = []
    for name, scale, unit in (("drag_torque", 1.0, "N m"), ("film_half_length", 1e3, "mm")):
        short, long = row["3s"]["parameters"][name], row["30s"]["parameters"][name]
        parts.append(
            f"{'T_b' if name == 'drag_torque' else 'a'} {interval(short, scale, unit)} → "
            f"{interval(long, scale, unit)} {unit} (log width ÷{row['width_ratio'][name]:.1f})"
        )
    return (
        f"{row['recordings']} files, {row['features']}: "
        + "; ".join(parts)
        + f"; identify {row['3s']['identify_s']:.0f} s → {row['30s']['identify_s']:.0f} s"
    )


def result_document(rows: list[dict]) -> dict:
    """The result file (``studies/results/``) of ``rows``."""
    held = all(
        p.get("truth_inside", True)
        for r in rows
        for d in ("3s", "30s")
        for p in r[d]["parameters"].values()
    )
    t_b = sum(r["width_ratio"]["drag_torque"] >= 2 for r in rows)
    a = sum(r["width_ratio"]["film_half_length"] >= 2 for r in rows)
    return {
        "order": 12.6,
        "what": "what a 30 s recording pins against a 3 s one of the same point (pair II, "
        "65.6 mm, boundary, 20 % at 16 Hz): identify's 95 % intervals and run time",
        "summary": "; ".join(row_phrase(r) for r in rows)
        + ("; every truth inside" if held else "; a truth outside"),
        "aim": "intervals ≥ 2× narrower (log width) at 30 s; run time no faster-growing than "
        "the simulated time",
        "verdict": "met"
        if t_b == a == len(rows)
        else f"T_b ≥ 2× narrower in {t_b} of {len(rows)}, a in {a} (a is held by h_min's prior)",
        "measured": "rattlefit identify FILE [--features F] with the default options, seed 0; "
        "a one-sided interval's log width runs to the end of the range; pairs measured: "
        + ", ".join(dict.fromkeys(r["recordings"] for r in rows))
        + f" (of {', '.join(PAIRS)})",
        "command": "python studies/long_recording.py --json OUT",
        "results": rows,
        "platform": platform_info(),
        **tree_state(),
    }


if __name__ == "__main__":
    main()
