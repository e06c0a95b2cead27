"""How long ``rattlefit identify`` takes on one 3 s recording, and what the compilation cache
saves: each run a fresh process, wall time of the whole command and identify's own.

    python benchmarks/identify_time.py [--file F] [--json benchmarks/results/identify_time.json]
                                       [--cache-json benchmarks/results/compile_cache.json]

Runs, one after another: the defaults with the compilation cache off (cold); the defaults
twice with a new cache directory (the first fills it, the second is warm); ``--quick`` with
the cache off. The warm and the cold fit must agree to the last bit (a cached program is the
program a fresh compilation gives). Progress on stderr; ``--json`` and ``--cache-json`` write
the two result files.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rattlefit.cli  # noqa: F401 - what the timed command runs (and these results measure)
from rattlefit.compile_cache import CACHE_ENV
from rattlefit.testing.results import provenance, write_result
from rattlefit.testing.shared import recordings_dir

ROOT = Path(__file__).resolve().parents[1]
RATTLEFIT = str(Path(sys.executable).with_name("rattlefit"))
#: The mild shared recording (pair II, boundary, 65.0 mm, 10 % at 8 Hz, 3 s).
FILE = "pairII_boundary_65.0_10pct_8Hz.h5"
#: What a cold identify of one 3 s recording should stay below (s).
AIM_S = 60.0


def run(path: Path, out: Path, cache: str, *extra: str) -> dict:
    """One ``rattlefit identify`` in a fresh process: its wall time (s), identify's own and
    the JSON it wrote."""
    env = {**os.environ, CACHE_ENV: cache}
    t0 = time.perf_counter()
    subprocess.run([RATTLEFIT, "identify", str(path), "-q", "-o", str(out), *extra], env=env,
                   check=True, capture_output=True)  # fmt: skip
    wall = time.perf_counter() - t0
    doc = json.loads(out.read_text())
    return {"wall_s": wall, "identify_s": doc["fit"]["wall_time_s"], "doc": doc}


def measure(path: Path) -> dict:
    """The four runs (module notes), each reported as it ends."""
    with tempfile.TemporaryDirectory(prefix="rattlefit-bench-") as tmp:
        tmp = Path(tmp)
        runs = {}
        for name, cache, extra in (
            ("cold", "off", ()),
            ("filling", str(tmp / "cache"), ()),
            ("warm", str(tmp / "cache"), ()),
            ("quick_cold", "off", ("--quick",)),
        ):
            runs[name] = run(path, tmp / f"{name}.json", cache, *extra)
            print(f"{name}: {runs[name]['wall_s']:.1f} s", file=sys.stderr, flush=True)
        size = sum(p.stat().st_size for p in (tmp / "cache").rglob("*") if p.is_file())
    runs["cache_bytes"] = size
    return runs


def same_fit(a: dict, b: dict) -> bool:
    """Whether two fit JSONs give the same parameters and χ² to the last bit."""
    return a["parameters"] == b["parameters"] and a["fit"]["chi2"] == b["fit"]["chi2"]


def identify_document(runs: dict, path: Path, command: str) -> dict:
    cold, quick = runs["cold"], runs["quick_cold"]
    return {
        "order": 4,
        "headline": True,
        "what": "`rattlefit identify` of one 3 s recording, compile included",
        "summary": f"cold {cold['wall_s']:.0f} s wall (identify itself {cold['identify_s']:.0f} "
        f"s), the compilation cache warm {runs['warm']['wall_s']:.0f} s, --quick cold "
        f"{quick['wall_s']:.0f} s",
        "aim": f"cold < {AIM_S:g} s",
        "verdict": "met" if cold["wall_s"] < AIM_S else "missed",
        "measured": f"`rattlefit identify {path.name}` (the mild shared file), the defaults and "
        "--quick, each in a fresh process one after another; wall time of the process and "
        "identify's own (fit.wall_time_s)",
        "results": {
            name: {"wall_s": r["wall_s"], "identify_s": r["identify_s"]}
            for name, r in runs.items()
            if isinstance(r, dict)
        },
        **provenance(command),
    }


def cache_document(runs: dict, command: str) -> dict:
    warm, cold = runs["warm"], runs["cold"]
    same = same_fit(warm["doc"], cold["doc"])
    return {
        "order": 5,
        "what": "compilation cache: a warm `rattlefit identify` against a cold one",
        "summary": f"warm {warm['wall_s']:.0f} s against {cold['wall_s']:.0f} s cold (×"
        f"{cold['wall_s'] / warm['wall_s']:.2f}); "
        + ("the same fit to the last bit" if same else "the fits differ"),
        "aim": "the same fit to the last bit",
        "verdict": "met" if same else "missed",
        "measured": "the defaults cold (cache off) and warm (a new cache filled by one run), "
        "each in a fresh process",
        "results": {
            "warm_wall_s": warm["wall_s"],
            "cold_wall_s": cold["wall_s"],
            "same_to_the_last_bit": same,
            "cache_MB": runs["cache_bytes"] / 1e6,
        },
        **provenance(command),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--file", type=Path, default=recordings_dir(ROOT) / FILE)
    ap.add_argument("--json", type=Path, help="write the identify-time result file here")
    ap.add_argument("--cache-json", type=Path, help="write the compilation-cache result here")
    args = ap.parse_args(argv)
    if not args.file.is_file():
        print(f"identify_time: {args.file}: no such recording", file=sys.stderr)
        return 2
    runs = measure(args.file)
    command = "python " + " ".join([Path(__file__).relative_to(ROOT).as_posix(), *sys.argv[1:]])
    if args.json:
        write_result(args.json, identify_document(runs, args.file, command))
    if args.cache_json:
        write_result(args.cache_json, cache_document(runs, command))
    return 0


if __name__ == "__main__":
    sys.exit(main())
