"""Running a campaign on dask.distributed: the task graph, where work is skipped, and what is
written.

**The graph.** First every unit's recordings are read on the workers
(:func:`~rattlefit.campaign.work.inspect_unit`: their content hashes, what the report shows
and, for the learned likelihood, the test-point key). Then each unit with work left is one
task (:func:`~rattlefit.campaign.work.run_unit`: identify, then sample and diagnose from that
identification when asked). On the learned likelihood the units of one test point share one
learning: the first of them in the manifest learns and stores it, and the others' tasks take
that task's result as an input, so that they start after it and reuse what it learned.

**Resumption.** Each stage of a unit (fit, sample, diagnose) has a key: a hash of its
recordings' contents and of the options that define its result (for a reusing fit also the
key of the fit it reuses). When a stage finishes, the client writes its files and then
``tasks/<stage>-<key>.json``, which names those files with their hashes; a stage whose record
exists and whose files are unchanged is skipped. Failures are reported, not recorded, so a
re-run tries them again.

**Failures.** A recording that cannot be read, or a stage that raises, is reported (the
unit, its recordings, the stage and the error) and the rest go on. A worker process that
dies loses only the task it ran, which the scheduler gives to another worker (up to
``distributed.scheduler.allowed-failures`` times, 3 by default).

Only the client writes into the campaign's directory; the workers read the recordings at the
paths the manifest gives, so on a cluster of several machines those must be on a file system
every worker sees.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import itertools
import json
import logging
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

from ..errors import RattlefitError
from ..physics.effects import DEFAULT_EFFECTS
from ..util import atomic_write, write_json
from ..version import __version__
from .manifest import Manifest, Unit, read_manifest
from .options import CampaignOptions, ClusterOptions
from .report import write_campaign_report
from .table import unit_rows, with_diagnosis, with_posterior, write_table
from .work import Environment, UnitTask, inspect_unit, run_unit

#: A unit's stages, in the order they run.
STAGES = ("fit", "sample", "diagnose")
#: The campaign directory's subdirectories: every run's documents, the stages' records, and
#: the report's figures as PNG.
RUNS, TASKS, FIGURES = "runs", "tasks", "figures"
#: The campaign's summary, its failures and its report.
SUMMARY, FAILURES, REPORT = "campaign.json", "failures.csv", "report.html"
#: The files a stage writes into RUNS, after the unit's name.
SUFFIXES = {"fit": ".json", "sample": ".posterior.json", "diagnose": ".diagnosis.json"}
LIKELIHOOD_SUFFIX = ".likelihood.h5"
#: How long joining a running scheduler may take, s.
CONNECT_TIMEOUT = 30


@dataclasses.dataclass(frozen=True)
class Planned:
    """One unit's plan: its stages' ``keys``, the stages left to run (``pending``), whether
    it stores the learned likelihood of its test point (``learn``), the unit whose likelihood
    it reuses (``reuses``) and its ``test_point`` key (learned likelihood only)."""

    unit: Unit
    keys: dict
    pending: tuple[str, ...]
    learn: bool = False
    reuses: str | None = None
    test_point: str | None = None


@dataclasses.dataclass(frozen=True)
class CampaignResult:
    """What a campaign did: its ``directory``, the table (Parquet and CSV), the report
    (None when nothing was identified), its counts of ``units``, of those that ran work
    (``ran``) and of those entirely skipped as done before (``skipped``), the ``failures``
    (dicts of ``unit``, ``recordings``, ``stage``, ``error``), the wall time (s), the
    time the client process was busy rather than waiting for workers (s), and the wall time
    of each phase (s): ``connected`` (starting or joining the cluster), ``read``, ``run``
    (the identifications) and ``finish`` (the table and the report)."""

    directory: Path
    table: Path | None
    csv: Path | None
    report: Path | None
    units: int
    ran: int
    skipped: int
    failures: tuple[dict, ...]
    wall_s: float
    client_s: float
    phases: dict


def content_key(kind: str, payload: dict) -> str:
    """A 24-hex-digit hash of ``kind`` and ``payload`` (canonical JSON)."""
    text = json.dumps({"kind": kind, **payload}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def stage_keys(hashes: list[str], options: CampaignOptions, learned_from: str | None) -> dict:
    """Each stage's key for recordings of content ``hashes`` (in the fit's order) under
    ``options``; ``learned_from`` is the key of the fit whose learned likelihood this one
    reuses."""
    fit_options = options.fit.to_dict()
    fit_options["reuse_likelihood"] = None
    fit = content_key(
        "fit",
        {
            "recordings": hashes,
            "options": fit_options,
            "resimulations": options.resimulations,
            "learned_from": learned_from,
        },
    )
    sample = {"fit": fit, "steps": options.sample_steps, "walkers": options.sample_walkers}
    effects = options.effects or DEFAULT_EFFECTS
    return {
        "fit": fit,
        "sample": content_key("sample", sample),
        "diagnose": content_key("diagnose", {"fit": fit, "effects": list(effects)}),
    }


def wanted(options: CampaignOptions) -> tuple[str, ...]:
    """The stages ``options`` ask for."""
    return tuple(
        s
        for s in STAGES
        if s == "fit"
        or (s == "sample" and options.sample_steps)
        or (s == "diagnose" and options.diagnose)
    )


def plan(
    units: tuple[Unit, ...],
    inspections: dict[str, dict],
    options: CampaignOptions,
    done: Callable[[str, str], bool],
) -> list[Planned]:
    """The plan of every unit whose recordings were read (``inspections[unit.name]``
    without an error), in manifest order. On the learned likelihood the first unit of each
    test point learns (``learn``) and the others reuse its likelihood (``reuses``, and their
    keys depend on its fit's key). ``done(stage, key)`` says whether a stage is done."""
    out = []
    learners: dict[str, Planned] = {}
    for unit in units:
        found = inspections.get(unit.name)
        if found is None or found["error"] is not None:
            continue
        hashes = [r["sha256"] for r in found["recordings"]]
        point = found["test_point"] if options.learned else None
        learner = learners.get(point) if point is not None else None
        keys = stage_keys(hashes, options, learner.keys["fit"] if learner else None)
        pending = tuple(s for s in wanted(options) if not done(s, keys[s]))
        planned = Planned(
            unit,
            keys,
            pending,
            learn=point is not None and learner is None,
            reuses=learner.unit.name if learner else None,
            test_point=point,
        )
        if point is not None and learner is None:
            learners[point] = planned
        out.append(planned)
    return out


class Store:
    """The campaign's directory: every run's documents in ``runs/``, each finished stage's
    record in ``tasks/``. Every file is written atomically."""

    def __init__(self, directory: Path):
        self.directory = directory
        self.runs = directory / RUNS
        self.tasks = directory / TASKS
        for d in (self.runs, self.tasks):
            d.mkdir(parents=True, exist_ok=True)

    def record_path(self, stage: str, key: str) -> Path:
        return self.tasks / f"{stage}-{key}.json"

    def run_file(self, unit: Unit, stage: str) -> Path:
        return self.runs / f"{unit.name}{SUFFIXES[stage]}"

    def likelihood_file(self, name: str) -> Path:
        return self.runs / f"{name}{LIKELIHOOD_SUFFIX}"

    def record(self, stage: str, key: str) -> dict | None:
        """The stage's record when it exists and every file it names is unchanged."""
        path = self.record_path(stage, key)
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None
        for name, digest in record.get("files", {}).items():
            file = self.directory / name
            if not file.is_file() or hashlib.sha256(file.read_bytes()).hexdigest() != digest:
                return None
        return record

    def done(self, stage: str, key: str) -> bool:
        """Whether the stage of this key is done (:meth:`record`)."""
        return self.record(stage, key) is not None

    def write_stage(self, planned: Planned, stage: str, found: dict, extra: dict) -> None:
        """Write a finished stage's files, then its record (which names them by hash)."""
        files = {}
        path = write_json(self.run_file(planned.unit, stage), found["doc"])
        files[path.relative_to(self.directory).as_posix()] = sha256_of(path)
        if found.get("likelihood") is not None:
            data = found["likelihood"]
            path = atomic_write(
                self.likelihood_file(planned.unit.name), lambda tmp: tmp.write_bytes(data)
            )
            files[path.relative_to(self.directory).as_posix()] = sha256_of(path)
        record = {
            "stage": stage,
            "key": planned.keys[stage],
            "unit": planned.unit.name,
            "recordings": list(planned.unit.paths),
            "files": files,
            **extra,
        }
        if stage == "fit":
            record["recording_info"] = found["recordings"]
        write_json(self.record_path(stage, planned.keys[stage]), record)


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@contextlib.contextmanager
def connected(cluster: ClusterOptions, client=None) -> Iterator:
    """A dask client: ``client`` itself when given (left open), else one of the scheduler at
    ``cluster.scheduler``, else of a new local cluster of worker processes (one thread each:
    one fit at a time a process), closed on exit."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if cluster.scheduler is not None:
        try:
            joined = Client(cluster.scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as exc:
            raise RattlefitError(
                f"{cluster.scheduler}: scheduler: no dask scheduler answers there ({exc})"
            ) from exc
        with joined as c:
            yield c
        return
    with (
        LocalCluster(
            n_workers=cluster.local_workers(),
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0" if cluster.dashboard else None,
            silence_logs=logging.ERROR,
        ) as local,
        Client(local) as c,
    ):
        yield c


class Clock:
    """The client's busy time: what runs inside ``with clock:`` blocks."""

    def __init__(self):
        self.busy = 0.0

    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.busy += time.perf_counter() - self.t0


def run_campaign(
    manifest: str | Path | Manifest,
    output: str | Path,
    *,
    options: CampaignOptions | None = None,
    cluster: ClusterOptions | None = None,
    client=None,
    progress: Callable[[str], None] | None = None,
) -> CampaignResult:
    """Identify every unit of ``manifest`` (a :class:`Manifest` or its path, see
    :func:`~rattlefit.campaign.read_manifest`) on a dask cluster and write the results into
    the directory ``output``.

    options : what is computed (:class:`CampaignOptions`; default: identify only, with
        ``FitOptions()``).
    cluster : where (:class:`ClusterOptions`; default: a local cluster of one worker process
        per core); with ``client`` (an open ``distributed.Client`` to use instead) only its
        ``cores_per_worker`` and ``compilation_cache`` apply.
    progress : receives one-line messages (the dashboard's address, each finished task).

    Writes ``results.parquet`` and ``results.csv`` (:mod:`rattlefit.campaign.table`),
    ``runs/<unit>.json`` (identify's JSON; ``.posterior.json``, ``.diagnosis.json`` and the
    learned ``.likelihood.h5`` beside it when asked), ``report.html`` with ``figures/``,
    ``failures.csv`` and ``campaign.json``. Work done by an earlier run with the same
    recordings and options is skipped. Raises :class:`~rattlefit.errors.RattlefitError` for
    a bad manifest; a bad recording or a failed fit is reported in the result, not raised.
    """
    t_start = time.perf_counter()
    clock = Clock()
    say = progress or (lambda msg: None)
    with clock:
        options = options or CampaignOptions()
        cluster = cluster or ClusterOptions()
        if not isinstance(manifest, Manifest):
            manifest = read_manifest(manifest)
        directory = Path(output)
        if directory.exists() and not directory.is_dir():
            raise RattlefitError(f"{directory}: output: exists and is not a directory")
        store = Store(directory)
        units = manifest.units()
        env = Environment(cores=cluster.worker_cores(), cache=cluster.cache())
    marks = {"start": t_start}
    with connected(cluster, client) as c:
        marks["connected"] = time.perf_counter()
        with clock:
            info = c.scheduler_info()
            served = "dashboard" in info.get("services", {})
            link = getattr(c, "dashboard_link", None) if served else None
            n_workers = len(info.get("workers", {}))
            say(
                f"{len(units)} identifications on {n_workers} workers"
                + (f"; dashboard {link}" if link else "")
            )
        inspections, failures = inspect_all(c, units, options, env, clock, say)
        marks["read"] = time.perf_counter()
        with clock:
            plans = plan(units, inspections, options, store.done)
        ran = run_all(c, plans, options, env, store, failures, clock, say)
        marks["run"] = time.perf_counter()
    with clock:
        result = finish(store, manifest, units, plans, options, failures, say)
    marks["finish"] = time.perf_counter()
    wall = marks["finish"] - t_start
    names = list(marks)
    phases = {b: marks[b] - marks[a] for a, b in itertools.pairwise(names)}
    skipped = sum(1 for p in plans if not p.pending)
    summary = {
        "manifest": str(manifest.source),
        "units": len(units),
        "ran": ran,
        "skipped": skipped,
        "failures": failures,
        "seed": options.fit.seed,
        "options": campaign_options_doc(options),
        "rattlefit": __version__,
        "wall_time_s": wall,
        "client_busy_s": clock.busy,
        "phases_s": phases,
    }
    write_json(directory / SUMMARY, summary)
    return CampaignResult(
        directory=directory,
        table=result[0],
        csv=result[1],
        report=result[2],
        units=len(units),
        ran=ran,
        skipped=skipped,
        failures=tuple(failures),
        wall_s=wall,
        client_s=clock.busy,
        phases=phases,
    )


def campaign_options_doc(options: CampaignOptions) -> dict:
    """The campaign's options as JSON (the fit's flat, as identify's JSON has them)."""
    return {
        "fit": options.fit.to_dict(),
        "diagnose": options.diagnose,
        "effects": list(options.effects) if options.effects else None,
        "sample_steps": options.sample_steps,
        "sample_walkers": options.sample_walkers,
        "resimulations": options.resimulations,
    }


def inspect_all(client, units, options: CampaignOptions, env, clock: Clock, say):
    """Read every unit's recordings on the workers; the inspections by unit name, and the
    failures (stage "read")."""
    from distributed import as_completed

    with clock:
        token = uuid.uuid4().hex[:6]
        futures = {
            client.submit(
                inspect_unit,
                unit,
                options.fit,
                options.learned,
                env,
                key=f"inspect-{unit.name}-{token}",
                pure=False,
            ): unit
            for unit in units
        }
    found, failures = {}, []
    for future in as_completed(futures):
        with clock:
            unit = futures[future]
            try:
                result = future.result()
            except Exception as exc:  # the worker died too often, or the task was lost
                result = {"unit": unit.name, "recordings": [], "error": repr(exc)}
            found[unit.name] = result
            if result["error"] is not None:
                failures.append(failure(unit, "read", result["error"]))
                say(f"failed: {unit.name}: {result['error']}")
    return found, failures


def failure(unit: Unit, stage: str, error: str) -> dict:
    return {"unit": unit.name, "recordings": list(unit.paths), "stage": stage, "error": error}


def run_all(client, plans, options, env, store: Store, failures, clock: Clock, say) -> int:
    """Submit every plan with stages pending, learners first, and write each result as it
    arrives; returns how many units ran."""
    from distributed import as_completed

    with clock:
        todo = [p for p in plans if p.pending]
        done_before = len(plans) - len(todo)
        if done_before:
            say(f"{done_before} of {len(plans)} identifications already done: skipped")
        by_name = {p.unit.name: p for p in plans}
        token = uuid.uuid4().hex[:6]
        futures, submitted, scattered = {}, {}, {}
        for p in sorted(todo, key=lambda p: not p.learn):  # learners first
            likelihood = likelihood_input(p, by_name, submitted, store, client, scattered)
            task = UnitTask(
                p.unit,
                p.pending,
                options,
                learn=p.learn and "fit" in p.pending,
                reuses=f"{RUNS}/{p.reuses}{LIKELIHOOD_SUFFIX}" if p.reuses else None,
            )
            future = client.submit(
                run_unit,
                task,
                likelihood,
                env,
                key=f"{'learn' if p.learn else 'fit'}-{p.unit.name}-{token}",
                priority=1 if p.learn else 0,
                pure=False,
            )
            futures[future] = p
            submitted[p.unit.name] = future
    finished = 0
    for future in as_completed(futures):
        with clock:
            p = futures[future]
            finished += 1
            try:
                result = future.result()
            except Exception as exc:
                result = {"error": f"{type(exc).__name__}: {exc}", "stages": {}}
            bar = progress_bar(finished, len(futures))
            if result.get("error"):
                failures.append(failure(p.unit, "fit", result["error"]))
                say(f"{bar} {p.unit.name}: failed: {result['error']}")
                continue
            extra = {k: result.get(k) for k in ("worker", "rattlefit", "wall_s", "timings")}
            for stage in STAGES:
                found = result["stages"].get(stage)
                if found is None:
                    continue
                if "error" in found:
                    failures.append(failure(p.unit, stage, found["error"]))
                    say(f"{bar} {p.unit.name}: {stage} failed: {found['error']}")
                    continue
                store.write_stage(p, stage, found, extra)
            stages = ", ".join(p.pending)
            took = f"{result.get('wall_s', 0):.0f} s on {result.get('worker')}"
            say(f"{bar} {p.unit.name} ({stages}; {took})")
    return len(futures)


def likelihood_input(p: Planned, by_name, submitted, store: Store, client, scattered):
    """The learned likelihood ``p``'s task starts from: None (synthetic, or it learns
    now), the stored file of its test point's learner when that fit is done (scattered to
    the workers once), else the learner's task, which it then waits for."""
    source = p.unit.name if p.learn else p.reuses
    if source is None:
        return None
    owner = by_name[source]
    if "fit" not in owner.pending:
        path = store.likelihood_file(source)
        if not path.is_file():
            return None
        if source not in scattered:
            scattered[source] = client.scatter(path.read_bytes())
        return scattered[source]
    return None if owner is p else submitted[source]


def progress_bar(done: int, total: int, width: int = 20) -> str:
    """``[#####.....] 5/10``."""
    filled = round(width * done / max(total, 1))
    return f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total}"


def finish(store: Store, manifest, units, plans, options, failures, say):
    """The table, the report and the failures' list of every stage done; returns the
    table's two paths and the report's (None each when nothing was identified)."""
    rows, infos, diagnoses = [], [], []
    for p in plans:
        fit = store.record("fit", p.keys["fit"])
        if fit is None:
            continue
        doc = json.loads(store.run_file(p.unit, "fit").read_text(encoding="utf-8"))
        version = fit.get("rattlefit") or __version__
        found = unit_rows(p.unit, doc, fit["recording_info"], version=version)
        found = [{**r, "key": p.keys["fit"]} for r in found]
        if "sample" in wanted(options) and store.record("sample", p.keys["sample"]):
            posterior = json.loads(store.run_file(p.unit, "sample").read_text(encoding="utf-8"))
            found = with_posterior(found, posterior)
        if "diagnose" in wanted(options) and store.record("diagnose", p.keys["diagnose"]):
            diagnosis = json.loads(store.run_file(p.unit, "diagnose").read_text(encoding="utf-8"))
            found = with_diagnosis(found, diagnosis)
            diagnoses.append({"unit": p.unit.name, "recordings": list(p.unit.paths), **diagnosis})
        rows += found
        infos += [{**r, "unit": p.unit.name} for r in fit["recording_info"]]
    write_failures(store.directory / FAILURES, failures)
    if not rows:
        say("nothing identified: no table or report")
        return None, None, None
    parquet, csv = write_table(store.directory, rows)
    report = write_campaign_report(
        store.directory / REPORT,
        recordings=infos,
        rows=rows,
        diagnoses=diagnoses,
        failures=failures,
        meta={
            "manifest": str(manifest.source),
            "units": len(units),
            "seed": options.fit.seed,
            "options": campaign_options_doc(options),
        },
        figures=store.directory / FIGURES,
    )
    say(f"wrote {parquet}, {csv.name} and {report.name} ({len(rows)} rows)")
    return parquet, csv, report


def write_failures(path: Path, failures: list[dict]) -> Path:
    """The failures as CSV (unit, stage, recordings separated by ";", error), atomically."""
    import csv

    def write(tmp: Path) -> None:
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            out = csv.writer(fh)
            out.writerow(["unit", "stage", "recordings", "error"])
            for f in failures:
                out.writerow([f["unit"], f["stage"], ";".join(f["recordings"]), f["error"]])

    return atomic_write(path, write)
