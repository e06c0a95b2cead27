"""The command line's start-up: ``rattlefit --help`` and ``--version`` against a bare Python
start in the same run, and the full import of the library for comparison.

    python benchmarks/startup.py [--repeats 10] [--json benchmarks/results/startup.json]

Each command runs in a fresh process, the commands alternated ``--repeats`` times; the median
wall time of each is reported, and its ratio to the bare start. Progress on stderr.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time
from pathlib import Path

import rattlefit.cli  # noqa: F401 - what --help and --version run (and this result measures)
from rattlefit.testing.results import provenance, write_result

RATTLEFIT = str(Path(sys.executable).with_name("rattlefit"))
COMMANDS = {
    "python (bare start)": [sys.executable, "-c", "pass"],
    "rattlefit --help": [RATTLEFIT, "--help"],
    "rattlefit --version": [RATTLEFIT, "--version"],
    "rattlefit identify --help": [RATTLEFIT, "identify", "--help"],
    "import the whole library": [sys.executable, "-c", "import rattlefit; rattlefit.identify"],
}
#: What the start-up of --help and --version should stay below (s).
AIM_S = 1.0


def timed(command: list[str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - t0


def measure(repeats: int) -> dict[str, float]:
    """The median wall time (s) of each of :data:`COMMANDS` over ``repeats`` alternated runs."""
    times: dict[str, list[float]] = {name: [] for name in COMMANDS}
    for k in range(repeats):
        for name, command in COMMANDS.items():
            times[name].append(timed(command))
        print(f"[{k + 1}/{repeats}]", file=sys.stderr, flush=True)
    return {name: statistics.median(t) for name, t in times.items()}


def document(medians: dict[str, float], repeats: int) -> dict:
    bare = medians["python (bare start)"]
    worst = max(medians["rattlefit --help"], medians["rattlefit --version"])
    return {
        "order": 9.5,
        "what": "the command line's start-up (`rattlefit --help`, `--version`)",
        "summary": f"--help {medians['rattlefit --help']:.2f} s, --version "
        f"{medians['rattlefit --version']:.2f} s ({worst / bare:.1f}× a bare Python start); "
        f"the whole library's import {medians['import the whole library']:.1f} s",
        "aim": f"< {AIM_S:g} s",
        "verdict": "met" if worst < AIM_S else "missed",
        "measured": f"median of {repeats} fresh processes per command, the commands alternated",
        "results": {"median_s": medians, "repeats": repeats},
        **provenance(),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--json", type=Path, help="write the result file here")
    args = ap.parse_args(argv)
    medians = measure(args.repeats)
    for name, t in medians.items():
        print(f"{name:28s} {t:7.3f} s")
    if args.json:
        write_result(args.json, document(medians, args.repeats))
    return 0


if __name__ == "__main__":
    sys.exit(main())
