"""What the studies share: ``--set FIELD=JSON`` overrides of ``FitOptions``, identify runs
kept on disk, an interval's log width, how many truths a table holds, and result files with
their provenance (:mod:`rattlefit.testing.results`)."""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

#: The repository's root, put on ``sys.path`` so that the studies import the validation data
#: generators (``validation/``), which are not part of the installed package.
REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(1, str(REPO))

from rattlefit.problem.options import OPTION_NAMES  # noqa: E402
from rattlefit.problem.parameters import default_specs  # noqa: E402
from rattlefit.testing.results import (  # noqa: E402
    head_commit,
    provenance,
    tree_state,
    write_result,
)

__all__ = [
    "add_set_argument",
    "head_commit",
    "held",
    "identified",
    "log_width",
    "provenance",
    "set_overrides",
    "tree_state",
    "write_result",
]

#: Where a lower end reported as 0 (a one-sided interval) stands: the range's lower end.
RANGE_LOW = {s.name: s.lower for s in default_specs([], {})}


def add_set_argument(ap: argparse.ArgumentParser) -> None:
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=JSON",
        help="replace a FitOptions field, e.g. profile_roughness=true (repeatable)",
    )


def set_overrides(ap: argparse.ArgumentParser, items: list[str]) -> dict:
    """The ``FitOptions`` options named by ``--set`` items (flat names,
    :data:`~rattlefit.problem.options.OPTION_NAMES`), their values read as JSON; a bad item
    ends the script through ``ap.error``."""
    fields = set(OPTION_NAMES) - {"priors"}
    overrides = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or name not in fields or name == "seed":
            ap.error(
                f"--set {item!r}: expected FIELD=JSON with FIELD a FitOptions option other "
                "than seed"
            )
        try:
            overrides[name] = json.loads(value)
        except json.JSONDecodeError as exc:
            ap.error(f"--set {item!r}: the value is not JSON ({exc})")
    return overrides


def identified(path: Path, features: str, out: Path, extra=()) -> tuple[dict, float | None]:
    """The JSON of ``rattlefit identify PATH --features FEATURES [EXTRA…] -o OUT`` with the
    default options otherwise (run when ``out`` is absent), and the process's wall time
    (None when it was read)."""
    if out.exists():
        return json.loads(out.read_text()), None
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "rattlefit.cli", "identify", str(path), "--features", features,
         *extra, "-q", "-o", str(out)],
        check=True, stdout=subprocess.DEVNULL,
    )  # fmt: skip
    return json.loads(out.read_text()), time.perf_counter() - t0


def log_width(p: dict, name: str) -> float:
    """The log width of interval ``p`` (``identify``'s JSON ``parameters[name]``); a lower end
    reported as 0 stands for the range's lower end (:data:`RANGE_LOW`)."""
    return math.log(p["upper"] / (p["lower"] if p["lower"] > 0 else RANGE_LOW[name]))


def held(rows: list[dict]) -> tuple[int, int]:
    """How many of the rows' parameters hold their truth, and how many there are."""
    flags = [v["holds"] for r in rows for v in r["parameters"].values()]
    return sum(flags), len(flags)
