"""What the studies in this directory share: `--set FIELD=JSON` overrides of `FitOptions`,
their JSON reports written whole, the checkout's commit, an interval's log width, and the
shared recordings with their truth."""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

from rattlefit.inference.options import FLAT_FIELDS
from rattlefit.inference.parameters import default_specs

#: The independent simulator's recordings and their truth (``truth.json``).
RECORDINGS = Path(__file__).resolve().parents[2] / "shared" / "recordings"

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
    :data:`~rattlefit.inference.options.FLAT_FIELDS`), their values read as JSON; a bad item
    ends the script through ``ap.error``."""
    fields = set(FLAT_FIELDS) - {"priors"}
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


def write_json(path: str, doc: dict, **dump_options) -> None:
    """``doc`` as JSON at ``path``, written to a temporary file and renamed: never a
    half-written report."""
    tmp = f"{path}.tmp"
    with open(tmp, "w") as fh:
        json.dump(doc, fh, indent=2, **dump_options)
    os.replace(tmp, path)


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


def head_commit() -> str:
    """The checkout's commit (short), or "" outside a git checkout."""
    out = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
    )
    return out.stdout.strip()


def log_width(p: dict, name: str) -> float:
    """The log width of interval ``p`` (``identify``'s JSON ``parameters[name]``); a lower end
    reported as 0 stands for the range's lower end (:data:`RANGE_LOW`)."""
    return math.log(p["upper"] / (p["lower"] if p["lower"] > 0 else RANGE_LOW[name]))


def operating_points(names):
    """(name, RigSetup, truth dict) of each recording, in the order given."""
    from rattlefit.inference import rig
    from rattlefit.io.recording import read_recording

    truth = json.loads((RECORDINGS / "truth.json").read_text())
    return [(n, rig.setup(read_recording(RECORDINGS / f"{n}.h5")), truth[n]) for n in names]


def truth_params(setup, truth):
    """The RattleParams of a recording's truth (``truth.json``) on its rig ``setup``."""
    from rattlefit.physics.model import RattleParams

    return RattleParams(
        truth["a_mm"] * 1e-3,
        truth["drag_torque_Nm"],
        truth["viscosity_Pa_s"],
        setup.geometry.backlash,
    )
