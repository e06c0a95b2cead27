"""The golden pin: outputs that a change of structure must not move, to the last bit.

``compute()`` runs three fixed pipelines on the bundled ``data/`` files and returns their JSON
documents with wall times removed:

- ``identify`` with ``FitOptions.quick(seed=0)`` on the bundled pair II boundary file;
- a diagnosis from a quick fit (``FitOptions.quick(seed=0)``) trying two effects;
- a 20-step emcee chain started from the first identification.

A seeded result depends on the platform (JAX version, backend, device count, CPU and its
instruction-set cap), so a pin is recorded per platform, in ``tests/pins/<key>.json``.
Record one on a new platform with ``python tests/golden_pin.py --record``.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import jax

import rattlefit  # noqa: F401  (caps the CPU instruction set before JAX starts)

DATA = Path(__file__).resolve().parents[1] / "data"
PINS = Path(__file__).resolve().parent / "pins"
#: one file keeps the pin within CI's time: the oil-jet and pair I files run through the same
#: code (their fits are checked in test_report and the notebooks)
FILES = ("pairII_boundary_65.6_20pct_16Hz.h5",)
DIAGNOSE_FILE = "pairII_boundary_65.6_20pct_16Hz.h5"
DIAGNOSE_EFFECTS = ("flank_friction", "runout")
CHAIN_STEPS = 20
CHAIN_WALKERS = 16
SEED = 0
#: keys whose values are wall-clock times or where the platform is recorded
UNPINNED = {"wall_time_s", "wall_time", "platform", "elapsed_s"}


def platform_key() -> tuple[str, dict]:
    """A short hash of what a seeded result depends on, and the facts it hashes."""
    from rattlefit.reproducibility import platform_info

    info = platform_info()
    text = json.dumps(info, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:12], info


def strip(doc):
    """``doc`` without wall times and platform records, with paths made relative to data/."""
    if isinstance(doc, dict):
        return {k: strip(v) for k, v in doc.items() if k not in UNPINNED}
    if isinstance(doc, list):
        return [strip(v) for v in doc]
    if isinstance(doc, str) and str(DATA) in doc:
        return doc.replace(str(DATA), "data")
    return doc


def compute() -> dict:
    """The pinned documents, keyed by pipeline, with numpy's BLAS on one thread (as in the
    test workers, tests/conftest.py): a matrix product's last bit depends on the thread
    count."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return compute_pipelines()


def compute_pipelines() -> dict:
    """The pinned documents, keyed by pipeline (:func:`compute`)."""
    from rattlefit import (
        DiagnoseOptions,
        FitOptions,
        SampleOptions,
        diagnose,
        identify,
        read_recording,
        sample,
    )

    out = {}
    first = None
    for name in FILES:
        rec = read_recording(DATA / name)
        result = identify([rec], FitOptions.quick(seed=SEED))
        out[f"identify/{name}"] = strip(result.to_json())
        if first is None:
            first = (rec, result)
    rec, result = first
    post = sample(
        [rec],
        result,
        SampleOptions(n_walkers=CHAIN_WALKERS, n_steps=CHAIN_STEPS, seed=SEED),
    )
    out["sample"] = strip(post.to_json())
    rec = read_recording(DATA / DIAGNOSE_FILE)
    options = DiagnoseOptions(effects=DIAGNOSE_EFFECTS, fit=FitOptions.quick(seed=SEED))
    out["diagnose"] = strip(diagnose([rec], options).to_json())
    return json.loads(json.dumps(out))  # what a JSON file holds: floats by their repr


def pin_path() -> Path:
    return PINS / f"{platform_key()[0]}.json"


def record() -> Path:
    key, info = platform_key()
    doc = {"platform": info, "outputs": compute()}
    path = PINS / f"{key}.json"
    PINS.mkdir(exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    tmp.replace(path)
    return path


if __name__ == "__main__":
    if sys.argv[1:] != ["--record"]:
        sys.exit("usage: python tests/golden_pin.py --record")
    jax.devices()  # one device, as under pytest-xdist
    print(record())
