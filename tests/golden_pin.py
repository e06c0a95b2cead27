"""The golden pin: outputs that a change of structure must not move.

Two parts:

- **Within rounding, everywhere** (``compute_stable()``, pinned in ``tests/pins/stable.json``
  and checked by ``tests/test_golden.py`` on every platform): the stages that are not chaotic —
  each bundled recording's feature vector, 30 ms of simulated motion (one solve and a lockstep
  batch) and the squeeze momentum's closed form — compared with tolerances that float64
  rounding on another CPU or JAX version stays within (:data:`TOLERANCES`).
- **To the last bit, on one machine** (``compute()``): three fixed seeded pipelines on the
  bundled ``data/`` files, their JSON documents with wall times removed:

  - ``identify`` with ``FitOptions.quick(seed=0)`` on the bundled pair II boundary file;
  - a diagnosis from a quick fit (``FitOptions.quick(seed=0)``) trying two effects;
  - a 20-step emcee chain started from the first identification.

  A seeded result depends on the platform (JAX version, backend, device count, CPU model and
  its instruction-set cap): rattle is chaotic, so a last-bit difference grows into another
  realisation. So this part is no test and no file in the repository: a developer who
  restructures code records it before the change and compares after it, on the same machine::

      git stash; python tests/golden_pin.py --record /tmp/before.json; git stash pop
      python tests/golden_pin.py --compare /tmp/before.json     # exit 1 and a diff if moved

Re-record the pin within rounding with ``python tests/golden_pin.py --record-stable``.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import sys
from pathlib import Path

import jax
import numpy as np

import rattlefit

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
#: The within-rounding pin's file.
STABLE = PINS / "stable.json"
#: Simulated time of the pinned motion (s): short enough that the chaos has not grown a
#: rounding difference into another trajectory.
MOTION_S = 0.03
#: Each stable output's (rtol, atol), in its unit. Features: logs of Welch PSDs of 30,000
#: samples, whose float64 rounding error is ~1e-13 relative; a change of the feature code moves
#: them by 1e-6 or more. Motion (m): a rounding difference (another CPU's code generation)
#: can flip one of the adaptive solver's accept/reject decisions, which moves the state by at
#: most its local tolerance (rtol·|q| + atol ≈ 1.4e-9 m), and the impacts amplify it: between
#: two x86-64 CPUs the motion differs by up to 3e-9 m over the first 30 ms (5e-7 m at 50 ms).
#: Over 30 ms a 1 % change of the drag torque moves q by 1.1e-6 m and a 0.1 % change by
#: 1.1e-7 m, so 3e-8 m, against a backlash of 4e-4 m, holds rounding with a margin of ten and
#: sees a change of the model. Squeeze momentum: a closed form, rounding only.
TOLERANCES = {"features": (1e-9, 1e-12), "motion": (0.0, 3e-8), "momentum": (1e-12, 0.0)}
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
    from rattlefit.report import diagnosis_document

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
    out["diagnose"] = strip(diagnosis_document(diagnose([rec], options)))
    return json.loads(json.dumps(out))  # what a JSON file holds: floats by their repr


def compute_stable() -> dict:
    """The outputs pinned within rounding, keyed ``<kind>/<name>`` (kinds: the keys of
    :data:`TOLERANCES`), each a list of floats."""
    from rattlefit import FitOptions, RattleParams, read_recording, rig, simulate, simulate_batch
    from rattlefit.problem.problem import problem_from
    from rattlefit.simulation.solve import broadcast_params

    out = {}
    for path in sorted(DATA.glob("*.h5")):
        problem, _, _ = problem_from([read_recording(path)], FitOptions.quick(seed=SEED))
        out[f"features/{path.name}"] = np.asarray(problem.data).ravel().tolist()
    s = rig.setup(read_recording(DATA / FILES[0]))
    truth = RattleParams(0.085e-3, 0.025, 0.4942, s.geometry.backlash)
    one = simulate(s.model, truth, s.drive, duration=MOTION_S, burn_in=0.0)
    out["motion/simulate"] = np.asarray(one.q).tolist()
    films = RattleParams([0.02e-3, 0.085e-3, 0.3e-3, 1e-3], 0.025, 0.4942, s.geometry.backlash)
    batch = simulate_batch(
        s.model, broadcast_params(films, 4), s.drive, batch="lockstep", duration=MOTION_S,
        burn_in=0.0,
    )  # fmt: skip
    out["motion/lockstep"] = np.asarray(batch.q).ravel().tolist()
    a, mu, h = np.meshgrid([1e-5, 1e-4, 1e-3], [0.05, 0.5], [1e-6, 5e-6], indexing="ij")
    m = rattlefit.squeeze_momentum(a.ravel(), mu.ravel(), h.ravel(), 0.01, 0.012)
    out["momentum/grid"] = np.asarray(m).tolist()
    return out


def record_stable() -> Path:
    PINS.mkdir(exist_ok=True)
    doc = {"tolerances": TOLERANCES, "outputs": compute_stable()}
    tmp = STABLE.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    tmp.replace(STABLE)
    return STABLE


def record(path: Path) -> Path:
    """Write this platform's exact outputs (:func:`compute`) and the platform to ``path``."""
    key, info = platform_key()
    doc = {"platform": info, "platform_key": key, "outputs": compute()}
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    tmp.replace(path)
    return path


def differences(pinned: dict, now: dict) -> list[str]:
    """One unified diff per pipeline whose JSON text differs (floats by their repr, so to the
    last bit, NaN equal to NaN), or a line naming pipelines present on one side only."""
    moved = []
    if sorted(now) != sorted(pinned):
        moved.append(f"pipelines differ: pinned {sorted(pinned)}, now {sorted(now)}")
    for name in sorted(set(pinned) & set(now)):
        want = json.dumps(pinned[name], indent=1, sort_keys=True).splitlines()
        got = json.dumps(now[name], indent=1, sort_keys=True).splitlines()
        diff = list(difflib.unified_diff(want, got, "pinned", "now", n=2, lineterm=""))
        if diff:
            moved.append(f"{name} moved:\n" + "\n".join(diff[:60]))
    return moved


def compare(path: Path) -> int:
    """0 when this platform's outputs equal those recorded at ``path`` to the last bit, 1 with
    the differences on stderr otherwise, 2 when ``path`` was recorded on another platform."""
    pinned = json.loads(path.read_text())
    key, info = platform_key()
    if pinned.get("platform_key") != key:
        recorded = pinned.get("platform")
        print(f"{path}: recorded on another platform ({recorded}); this one is {info}: a "
              "seeded result is comparable only on the same one", file=sys.stderr)  # fmt: skip
        return 2
    moved = differences(pinned["outputs"], compute())
    for text in moved:
        print(text, file=sys.stderr)
    print(f"{'moved' if moved else 'unchanged to the last bit'} against {path}")
    return 1 if moved else 0


def main(argv: list[str]) -> int:
    usage = "usage: python tests/golden_pin.py --record FILE | --compare FILE | --record-stable"
    if argv[:1] not in (["--record"], ["--compare"], ["--record-stable"]):
        print(usage, file=sys.stderr)
        return 2
    if (argv[0] == "--record-stable") != (len(argv) == 1) or len(argv) > 2:
        print(usage, file=sys.stderr)
        return 2
    rattlefit.configure(cpu_cores=1)  # one device, as under pytest-xdist
    jax.devices()
    if argv[0] == "--record-stable":
        print(record_stable())
        return 0
    if argv[0] == "--record":
        print(record(Path(argv[1])))
        return 0
    return compare(Path(argv[1]))


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
