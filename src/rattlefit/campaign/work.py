"""What a campaign's worker does: read and describe a unit's recordings, and identify,
sample and diagnose it. Each function runs in a worker process, configures JAX there (once
per process; the compilation cache shared), never raises for bad data (the error is returned,
so that the campaign reports it and goes on), and returns plain data: JSON documents, table
rows and the learned likelihood's file as bytes.
"""

from __future__ import annotations

import dataclasses
import hashlib
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

from ..config import quietly_configure
from ..errors import RattlefitError
from ..physics.geometry import TABLE2
from ..problem.options import FitOptions
from ..quantities import DRAG_TORQUE, FILM, MIN_FILM, STIFFNESS_SCALE, VISCOSITY
from ..version import __version__
from .manifest import Unit
from .options import CampaignOptions

#: The parameters whose truth a synthetic recording's ``/truth`` group holds, as the table
#: names them.
TRUTH_NAMES = (
    FILM,
    DRAG_TORQUE,
    VISCOSITY,
    MIN_FILM,
    STIFFNESS_SCALE,
    "backlash",
)


@dataclasses.dataclass(frozen=True)
class Environment:
    """How a worker sets JAX up: its CPU devices (None: one per core) and the compilation
    cache (``rattlefit.configure``'s ``compilation_cache``)."""

    cores: int | None = None
    cache: bool | str = True


@dataclasses.dataclass(frozen=True)
class UnitTask:
    """One unit's work: which ``stages`` to run (of "fit", "sample", "diagnose"), with which
    ``options``, whether this fit stores the learned likelihood for the others of its test
    point (``learn``), and the name of the stored likelihood it reuses (``reuses``)."""

    unit: Unit
    stages: tuple[str, ...]
    options: CampaignOptions
    learn: bool = False
    reuses: str | None = None


def configure(env: Environment) -> None:
    """Set JAX up in this worker process (64-bit, the CPU devices, the shared compilation
    cache); a no-op once JAX has started here."""
    quietly_configure(cpu_cores=env.cores, compilation_cache=env.cache)


def worker_address() -> str:
    """This worker's address, or "local" outside a dask worker."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


def error_text(exc: BaseException) -> str:
    """One line: a rattlefit error's own message, else the exception's type and message and
    where it was raised."""
    if isinstance(exc, RattlefitError):
        return str(exc)
    where = traceback.extract_tb(exc.__traceback__)[-1] if exc.__traceback__ else None
    at = f" (at {Path(where.filename).name}:{where.lineno})" if where else ""
    return f"{type(exc).__name__}: {exc}{at}"


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of the file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def pair_name(teeth: tuple[int, int]) -> str:
    """ "I" or "II" for a pair of the paper's Table 2, else ``z=a/b``."""
    for name, spec in TABLE2.items():
        if tuple(spec["teeth"]) == tuple(teeth):
            return name
    return f"z={teeth[0]}/{teeth[1]}"


def describe(rec, path: str, sha: str) -> dict:
    """What the table and the report show of a recording: its file and hash, gear pair,
    centre distance (mm), lubrication, oil temperature (°C), speed setting (mean speed
    rad/s, fluctuation % of it, frequency Hz), duration (s), measured IGR (rad·Hz) and, for a
    synthetic recording, its truth (SI)."""
    from ..io.recording import read_truth
    from ..rig import setup

    op, gp = rec.operating, rec.gear_pair
    truth = read_truth(path) or {}
    return {
        "recording": path,
        "name": Path(path).name,
        "sha256": sha,
        "pair": pair_name((gp.teeth_driving, gp.teeth_driven)),
        "center_distance_mm": float(gp.center_distance_mm),
        "lubrication": op.lubrication,
        "oil_temperature_c": float(op.oil_temperature_c),
        "mean_speed_rad_s": float(op.drive_mean_speed_rad_s),
        "fluctuation_pct": round(
            100.0 * op.drive_speed_amplitude_rad_s / op.drive_mean_speed_rad_s, 6
        ),
        "frequency_hz": float(op.drive_frequency_hz),
        "duration_s": float(rec.duration),
        "igr_measured": setup(rec).rattle_index(),
        "truth": {k: float(truth[k]) for k in TRUTH_NAMES if k in truth},
    }


def inspect_unit(unit: Unit, fit: FitOptions, learned: bool, env: Environment) -> dict:
    """Read ``unit``'s recordings: each one's :func:`describe`, and with ``learned`` the
    test-point key of the unit's problem (:func:`rattlefit.likelihood.store.test_point_key`).
    On failure ``error`` names the recording and the problem and ``recordings`` holds those
    read before it."""
    t0 = time.perf_counter()
    out: dict = {"unit": unit.name, "recordings": [], "error": None, "test_point": None}
    try:
        configure(env)
        from ..io.recording import read_recording

        recs = []
        for path in unit.paths:
            rec = read_recording(path)
            out["recordings"].append(describe(rec, path, file_sha256(path)))
            recs.append(rec)
        if learned:
            from ..likelihood.store import test_point_key
            from ..problem.problem import problem_from

            out["test_point"] = test_point_key(problem_from(recs, fit)[0])
    except Exception as exc:  # reported, and the campaign goes on
        out["error"] = error_text(exc)
    out["wall_s"] = time.perf_counter() - t0
    return out


def learned_bytes(result) -> bytes | None:
    """The learned likelihood ``result`` fitted on, as the bytes of its stored file
    (:func:`rattlefit.likelihood.store.write_learned`); None for the synthetic likelihood."""
    from ..likelihood.store import Learned, write_learned

    if not isinstance(result.state.likelihood, Learned):
        return None
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "learned.likelihood.h5"
        write_learned(path, result.state.likelihood)
        return path.read_bytes()


def run_unit(task: UnitTask, likelihood: bytes | dict | None, env: Environment) -> dict:
    """Run ``task``'s stages on its unit and return their documents.

    ``likelihood`` is the learned likelihood to reuse: its stored file's bytes, or the
    result of the unit that learned it (its ``likelihood``; when that unit failed, this one
    learns its own). The result holds, for each stage run, ``{"doc": …}`` or ``{"error":
    …}`` (the fit's also its table ``rows``, the re-simulated IGR and, when ``task.learn``,
    the learned likelihood's bytes), and the worker, rattlefit version and wall time.
    """
    t0 = time.perf_counter()
    out: dict = {"unit": task.unit.name, "stages": {}, "timings": {}}
    out["worker"] = worker_address()
    if isinstance(likelihood, dict):  # the learning unit's result
        likelihood = likelihood.get("stages", {}).get("fit", {}).get("likelihood")
    options = task.options
    with tempfile.TemporaryDirectory() as tmp:
        fit_options = options.fit
        if likelihood is not None:
            stored = Path(tmp) / "reused.likelihood.h5"
            stored.write_bytes(likelihood)
            fit_options = fit_options.replace(reuse_likelihood=str(stored))
        try:
            configure(env)
            from ..inference.identify import identify
            from ..io.recording import read_recording

            recordings = [read_recording(p) for p in task.unit.paths]
            result = None
            if "fit" in task.stages or "sample" in task.stages:
                t = time.perf_counter()
                result = identify(recordings, fit_options)
                out["timings"]["identify"] = time.perf_counter() - t
        except Exception as exc:
            out["error"] = error_text(exc)
            out["wall_s"] = time.perf_counter() - t0
            return out
        runs = {
            "fit": lambda: fit_stage(task, result, recordings, likelihood),
            "sample": lambda: sample_stage(options, result, recordings),
            "diagnose": lambda: diagnose_stage(options, result, recordings),
        }
        for name, run in runs.items():
            if name in task.stages:
                t = time.perf_counter()
                out["stages"][name] = stage(run)
                out["timings"][name] = time.perf_counter() - t
    out["rattlefit"] = __version__
    out["wall_s"] = time.perf_counter() - t0
    return out


def stage(run) -> dict:
    """``run()``'s dict, or ``{"error": …}`` when it raises."""
    try:
        return run()
    except Exception as exc:
        return {"error": error_text(exc)}


def fit_stage(task: UnitTask, result, recordings, likelihood: bytes | None) -> dict:
    """The identification's JSON (as ``identify -o`` writes it; a reused likelihood named by
    its campaign file), and its recordings' descriptions (:func:`describe`) with each one's
    re-simulated IGR (``igr_model``) and its oil's viscosity over the first recording's
    (``viscosity_factor``)."""
    from ..inference.realisation import fitted_igr

    doc = result.to_json()
    if likelihood is not None and task.reuses is not None:
        doc["fit"]["options"]["reuse_likelihood"] = task.reuses
        if "reused" in doc["fit"].get("likelihood", {}):
            doc["fit"]["likelihood"]["reused"] = task.reuses
    infos = [
        describe(rec, path, file_sha256(path))
        for rec, path in zip(recordings, task.unit.paths, strict=True)
    ]
    n, seed = task.options.resimulations, task.options.fit.seed
    igr = fitted_igr(result, recordings, n, seed=seed)
    oils = np.asarray(result.state.problem.viscosities, dtype=float)
    for k, (info, model) in enumerate(zip(infos, igr, strict=True)):
        info["igr_model"] = model
        info["viscosity_factor"] = float(oils[k] / oils[0])
    return {
        "doc": doc,
        "recordings": infos,
        "likelihood": learned_bytes(result) if task.learn else None,
    }


def sample_stage(options: CampaignOptions, result, recordings) -> dict:
    """The posterior's JSON (``sample -o``), its chain started from the identification."""
    from ..inference.posterior import SampleOptions, sample

    sample_options = SampleOptions(
        n_walkers=options.sample_walkers,
        n_steps=options.sample_steps,
        seed=options.fit.seed,
        fit=result.state.options,
    )
    return {"doc": sample(recordings, result, sample_options).to_json()}


def diagnose_stage(options: CampaignOptions, result, recordings) -> dict:
    """The diagnosis' JSON (``diagnose -o``), judged on the identification's likelihood
    (synthetic or learned), from the identification when it ran, else from one of its own
    with the same options."""
    from ..diagnosis.diagnose import DiagnoseOptions, diagnose
    from ..physics.effects import DEFAULT_EFFECTS
    from ..report.wording import diagnosis_document

    diag_options = DiagnoseOptions(effects=options.effects or DEFAULT_EFFECTS, fit=options.fit)
    return {"doc": diagnosis_document(diagnose(recordings, diag_options, baseline=result))}
