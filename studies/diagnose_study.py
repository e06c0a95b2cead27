"""How often `diagnose` is right: false positives on clean recordings, and the confusion
matrix on recordings with an effect written in another form than the catalogue's.

The cases are the independent simulator's recordings in ``../shared/recordings/`` (with their
truth), the sets of ``validation.diagnose_sets`` (clean recordings whose model form
differs from rattlefit's fitted one; recordings with an injected effect of another form), and
a validation set of the second rig model (``validation/second_rig``, set ``validation``, read
from ``--validation-dir``; made once from a seed drawn after its method was committed, and
scored only by a checkout whose package and scoring equal that method commit, which its
``manifest.json`` names; ``--unfrozen`` scores it anyway and labels the result so; the
manifest's hash is kept in the result).
Each case lists the verdicts that count as right: ``none``, ``unexplained`` or
``model_form`` for a clean recording, the effect (or, for dissipation in contact, any of the
dissipative candidates) otherwise.

    python studies/diagnose_study.py [--sets shared,clean,injected,validation] [--full]
                                        [--validation-dir DIR]
                                        [--only NAME ...] [--cases-dir DIR [--rows-only]]
                                        [--sample N [--sample-seed S]]
                                        [--json out.json] [--quiet]
                                        [--result README_RESULT.json] [--unfrozen]

A full study takes hours: with ``--cases-dir`` each case's row is written there as it ends
(``<name>.json``) and a case whose row is there is not run again, so an interrupted study
resumes; the summary covers every row in the directory that the selection holds.
``--rows-only`` summarises those rows and runs nothing.

The standing study, re-measured at every method change within an hour on 2 cores, is a seeded
sample (``--sample N --sample-seed S``): ``N // 2`` clean cases and the rest effect cases,
drawn without replacement from the selected sets; its rates carry their Clopper–Pearson
intervals, which a sample that small leaves wide.

Without ``--full`` only the model-free tests run (seconds per recording): the verdict is what
they name, or ``none``, and a case counts as clean when its effect has no model-free test
(dissipation, drag); that measures the angle- and time-domain tests' false-positive rate and
their hits. With ``--full`` each case gets a whole diagnosis with every candidate
(minutes each). Seeds: the diagnosis' fit seed is 0 for every case; the sets are built from
their own fixed seeds.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import time
from collections import Counter
from pathlib import Path

import numpy as np
from common import provenance, write_result
from scipy import stats

import rattlefit as rf
from rattlefit.diagnosis.diagnose import DiagnoseOptions, diagnose
from rattlefit.diagnosis.evidence import findings
from rattlefit.diagnosis.policy import POINTS_TO
from rattlefit.diagnosis.verdict import NAMES_NOTHING as CLEAN
from rattlefit.report import verdict_sentence
from rattlefit.testing.shared import recordings_dir
from validation.diagnose_sets import DISSIPATION, clean_set, injected_set

REPO = Path(__file__).resolve().parents[1]
SHARED = recordings_dir(REPO)
#: The shared truth's effect names, as the verdicts that count as right.
SHARED_EXPECTED = {"runout": ("runout",), "sliding_friction": DISSIPATION}
FAMILY = 0.01  # the diagnosis' default family-wise level


def shared_cases() -> list[dict]:
    """The shared recordings (3 s and long) with their expected verdicts."""
    path = SHARED / "truth.json"
    if not path.is_file():
        return []
    out = []
    for name, truth in sorted(json.loads(path.read_text()).items()):
        file = next(SHARED.glob(f"**/{name}.h5"), None)
        if file is None:
            continue
        effects = truth["unmodelled_effects"]
        expected = CLEAN if not effects else SHARED_EXPECTED[effects[0]]
        out.append({"name": name, "path": str(file), "set": "shared", "expected": list(expected)})
    return out


def set_cases(which: str) -> list[dict]:
    """The cases of ``diagnose_sets``' set ``which`` (built first if missing)."""
    build = {"clean": clean_set, "injected": injected_set}[which]
    kwargs = {"include_shared": False} if which == "clean" else {}
    return [
        {
            "name": Path(path).stem,
            "path": str(path),
            "set": which,
            "expected": list(truth["expected"]),
        }
        for path, truth in build(**kwargs)
    ]


def validation_cases(directory: Path) -> list[dict]:
    """The cases of a second-rig validation set in ``directory`` (its ``truth.json``)."""
    truth = json.loads((directory / "truth.json").read_text())
    return [
        {
            "name": name,
            "path": str(directory / f"{name}.h5"),
            "set": "validation",
            "expected": list(entry["expected"]),
        }
        for name, entry in sorted(truth.items())
    ]


def manifest_hash(directory: Path) -> str:
    """The sha256 of a validation set's ``manifest.json``: which frozen set was scored."""
    import hashlib

    return hashlib.sha256((directory / "manifest.json").read_bytes()).hexdigest()


#: What a frozen set's score depends on besides the data: the package and the scoring itself.
METHOD_PATHS = ("src", "studies/diagnose_study.py", "studies/common.py")


def frozen_method_problem(directory: Path) -> str:
    """Why this checkout may not score the validation set in ``directory`` as frozen, or "":
    its manifest must name the method commit fixed when its seed was drawn, and this checkout's
    package and scoring must equal that commit's, uncommitted changes included."""
    manifest = json.loads((directory / "manifest.json").read_text())
    method = manifest.get("method_commit", "")
    if not method:
        return (f"{directory}: its manifest names no method commit (drawn before sets recorded "
                "one): it is no frozen set; score it with --unfrozen")  # fmt: skip
    diff = subprocess.run(
        ["git", "diff", "--name-only", method, "--", *METHOD_PATHS],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=False,
    )
    if diff.returncode != 0:
        return f"{directory}: its method commit {method[:12]} is not in this history"
    if diff.stdout.strip():
        changed = diff.stdout.split()
        where = ", ".join(changed[:3]) + (" …" if len(changed) > 3 else "")
        return (f"{directory}: drawn for the method of {method[:12]}, but this checkout differs "
                f"from it in {where}: score it in a worktree of that commit "
                f"(git worktree add /tmp/method {method[:12]})")  # fmt: skip
    return ""


def model_free_verdict(recording) -> tuple[str, list[dict]]:
    """The verdict of the model-free tests alone: what they name, or ``none``."""
    found = findings([recording], FAMILY)
    named = []
    for f in sorted(found, key=lambda f: f.test.p_value):
        if f.significant and f.effect not in named:
            named.append(f.effect)
    return "+".join(named) or "none", [f.as_dict() for f in found if f.significant]


def model_free_expected(expected: list[str]) -> list[str]:
    """What the model-free tests alone should name: each expected combination less the effects
    they have no test for (dissipation, drag), ``none`` when nothing is left."""
    testable = set(POINTS_TO.values())
    return sorted(
        {"+".join(n for n in combo.split("+") if n in testable) or "none" for combo in expected}
    )


def right(verdict: str, expected: list[str]) -> bool:
    """The verdict is one of the expected ones (a combination in any order)."""
    have = set(verdict.split("+"))
    return any(set(e.split("+")) == have for e in expected)


def run_case(case: dict, full: bool, say) -> dict:
    rec = rf.read_recording(case["path"])
    t0 = time.perf_counter()
    if full:
        diag = diagnose([rec], DiagnoseOptions(), progress=None)
        verdict, detail = diag.verdict.label, full_detail(diag)
    else:
        verdict, detail = model_free_verdict(rec)
        case = case | {"expected": model_free_expected(case["expected"])}
    wall = time.perf_counter() - t0
    ok = right(verdict, case["expected"])
    mark = "right" if ok else "WRONG"
    say(f"{case['set']:8s} {case['name']:45s} {verdict:28s} {mark} ({wall:.0f} s)")
    where = os.path.relpath(case["path"], REPO)  # a row reads the same on every checkout
    row = {"verdict": verdict, "right": ok, "wall_s": round(wall, 1), "detail": detail}
    return case | {"path": where} | row


def full_detail(diag) -> dict:
    """What a full diagnosis of a case leaves for the study: the sentence, the band gap and
    each candidate's χ² with it, support and time."""
    chi2, dof, p = diag.gap_chi2
    return {
        "sentence": verdict_sentence(diag),
        "gap_chi2": round(chi2, 2),
        "dof": dof,
        "gap_p": p,
        "effects": [
            {
                "name": o.name,
                "chi2_with": None if o.failure else round(o.chi2_with, 2),
                "supported": o.supported,
                "p_after": None if o.failure else o.p_after,
                "wall_s": round(o.wall_time, 1),
            }
            for o in diag.outcomes
        ],
    }


def run_cases(cases: list[dict], full: bool, cases_dir: Path | None, say) -> list[dict]:
    """Each case's row (:func:`run_case`); with ``cases_dir``, rows already there are read
    back instead of run, and each new one is written there as it ends."""
    rows = []
    for case in cases:
        path = None if cases_dir is None else cases_dir / f"{case['name']}.json"
        if path is not None and path.is_file():
            rows.append(json.loads(path.read_text()))
            continue
        try:
            row = run_case(case, full, say)
        except Exception as exc:  # a crash is a result too: recorded, and the study goes on
            say(f"{case['set']:8s} {case['name']:45s} ERROR {type(exc).__name__}: {exc}")
            where = os.path.relpath(case["path"], REPO)
            row = case | {"path": where, "verdict": "error", "right": False, "wall_s": None}
            row["detail"] = {"error": f"{type(exc).__name__}: {exc}"}
        if path is not None:
            write_result(path, row)
        rows.append(row)
    return rows


def is_clean(case: dict) -> bool:
    """The case holds no effect: its acceptable verdicts are ``none``, ``unexplained`` or
    ``model_form``."""
    return set(case["expected"]) <= set(CLEAN)


def rate_interval(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Clopper–Pearson interval of a rate from ``k`` of ``n`` cases: what the study's size
    allows one to say of the rate on more recordings like these."""
    if n == 0:
        return 0.0, 1.0
    tail = (1.0 - level) / 2.0
    lower = stats.beta.ppf(tail, k, n - k + 1) if k > 0 else 0.0
    upper = stats.beta.ppf(1.0 - tail, k + 1, n - k) if k < n else 1.0
    return round(float(lower), 4), round(float(upper), 4)


def summary(rows: list[dict]) -> dict:
    """False-positive rate on the clean cases, right rate on the effect cases (each with its
    95 % Clopper–Pearson interval), right verdicts per set, confusion."""
    clean = [r for r in rows if is_clean(r)]
    effect = [r for r in rows if not is_clean(r)]
    confusion = Counter((("clean" if r in clean else r["expected"][0]), r["verdict"]) for r in rows)
    false_positives = sum(not r["right"] for r in clean)
    effect_right = sum(r["right"] for r in effect)
    return {
        "clean_cases": len(clean),
        "false_positives": false_positives,
        "false_positive_rate": false_positives / max(len(clean), 1),
        "false_positive_rate_95": rate_interval(false_positives, len(clean)),
        "effect_cases": len(effect),
        "effect_right": effect_right,
        "effect_right_rate": effect_right / max(len(effect), 1),
        "effect_right_rate_95": rate_interval(effect_right, len(effect)),
        "per_set": {
            name: {"cases": len(rs), "right": sum(r["right"] for r in rs)}
            for name in dict.fromkeys(r["set"] for r in rows)
            for rs in [[r for r in rows if r["set"] == name]]
        },
        "confusion": [
            {"truth": t, "verdict": v, "count": n} for (t, v), n in sorted(confusion.items())
        ],
    }


def study_verdict(result: dict, n_clean: int, n_effect: int) -> str:
    """Each aim judged once all its cases are in (of ``n_clean`` clean and ``n_effect`` effect
    cases selected): ``met`` when both are, else a clause each."""
    clean, effect = result["clean_cases"], result["effect_cases"]
    fp_ok = result["false_positive_rate"] <= 0.05 and clean >= 20
    right_ok = result["effect_right_rate"] >= 0.8
    if clean == n_clean and effect == n_effect and fp_ok and right_ok:
        return "met"
    lo, hi = result["false_positive_rate_95"]
    fp = (
        f"false positives {'met' if fp_ok else 'missed'} ({result['false_positives']} of "
        f"{clean} clean, {100 * result['false_positive_rate']:.1f} %; 95 % interval "
        f"{100 * lo:.1f}–{100 * hi:.1f} %)"
        if clean == n_clean
        else f"false positives not yet measured ({clean} of {n_clean} clean cases run)"
    )
    right = (
        f"effect cases {'met' if right_ok else 'missed'} ({result['effect_right']} of {effect} "
        "right)"
        if effect == n_effect
        else f"effect cases not yet measured ({effect} of {n_effect} run)"
    )
    return f"{fp}; {right}"


def sample_cases(cases: list[dict], n: int, seed: int) -> list[dict]:
    """A seeded sample of ``n`` of ``cases``: ``n // 2`` clean ones and the rest with an
    effect (as many as there are of each), in the order of ``cases``."""
    rng = np.random.default_rng(seed)
    clean = [i for i, c in enumerate(cases) if is_clean(c)]
    effect = [i for i, c in enumerate(cases) if not is_clean(c)]
    n_clean = min(n // 2, len(clean))
    n_effect = min(n - n_clean, len(effect))
    keep = set(rng.choice(clean, n_clean, replace=False).tolist()) if n_clean else set()
    if n_effect:
        keep |= set(rng.choice(effect, n_effect, replace=False).tolist())
    return [c for i, c in enumerate(cases) if i in keep]


def result_document(rows: list[dict], cases: list[dict], *, population: int | None = None) -> dict:
    """The README result file (``studies/results/diagnose_full_study.json``) of a full
    study's ``rows`` out of the ``cases`` selected (a sample of ``population`` cases, when
    given), run by this process's command on the checkout's code (its commit is the method's:
    to score an older method, run the study in a worktree of its commit)."""
    result = summary(rows)
    made = provenance()
    n_cases = len(cases)
    n_clean = sum(is_clean(c) for c in cases)
    sampled = "" if population is None else f" (a seeded sample of the {population})"
    return {
        "headline": True,
        "order": 11.6,
        "what": "full `diagnose` (default options) on recordings rattlefit's fitted model did "
        "not make: the shared independent recordings, the clean calibration set and the "
        "injected set of validation.diagnose_sets",
        "summary": (
            f"all {n_cases} cases{sampled}"
            if len(rows) == n_cases
            else f"{len(rows)} of the {n_cases} cases so far (the study resumes from its "
            "committed rows)"
        )
        + f": {result['false_positives']} of {result['clean_cases']} clean recordings got an "
        f"effect verdict; {result['effect_right']} of {result['effect_cases']} effect cases right; "
        + ", ".join(f"{k} {v['right']}/{v['cases']} right" for k, v in result["per_set"].items()),
        "aim": "≤ 5 % false positives on ≥ 20 clean recordings; ≥ 80 % of effect cases right",
        "verdict": study_verdict(result, n_clean, n_cases - n_clean),
        "measured": f"{made['command']} (one row a case, fit seed 0, family-wise level 0.01), "
        f"on the diagnosis code of commit {made['commit']}; a row's wall_s includes any time "
        "the study was paused or ran at low priority",
        "results": {**result, "cases": [{k: r[k] for k in ROW_KEYS if k in r} for r in rows]},
        **made,
    }


#: What the result file keeps of each row.
ROW_KEYS = ("name", "set", "expected", "verdict", "right", "wall_s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", default="shared,clean,injected")
    ap.add_argument(
        "--validation-dir",
        type=Path,
        default=REPO / "studies/cache/validation_v2",
        help="the second rig's validation set (validation.second_rig.validation_set --out)",
    )
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--cases-dir", type=Path)
    ap.add_argument("--json")
    ap.add_argument("--quiet", action="store_true")
    ap.add_argument("--result", help="also write the README result file (with --full)")
    ap.add_argument(
        "--unfrozen",
        action="store_true",
        help="score a validation set at a method other than the one its manifest fixes (the "
        "result is labelled not frozen)",
    )
    ap.add_argument(
        "--sample",
        type=int,
        help="diagnose a seeded sample of this many of the selected cases (half clean)",
    )
    ap.add_argument("--sample-seed", type=int, default=0)
    ap.add_argument(
        "--rows-only",
        action="store_true",
        help="summarise the rows already in --cases-dir; run no case",
    )
    args = ap.parse_args()
    say = (lambda s: None) if args.quiet else (lambda s: print(s, flush=True))
    cases = []
    for which in args.sets.split(","):
        if which == "shared":
            cases += shared_cases()
        elif which == "validation":
            problem = "" if args.unfrozen else frozen_method_problem(args.validation_dir)
            if problem:
                ap.error(problem)
            cases += validation_cases(args.validation_dir)
        else:
            cases += set_cases(which)
    if args.only:
        cases = [c for c in cases if c["name"] in args.only]
    population = None
    if args.sample is not None:
        population = len(cases)
        cases = sample_cases(cases, args.sample, args.sample_seed)
        say(f"a sample of {len(cases)} of {population} cases (seed {args.sample_seed})")
    if args.cases_dir is not None:
        args.cases_dir.mkdir(parents=True, exist_ok=True)
    selected = list(cases)
    if args.rows_only:
        if args.cases_dir is None:
            ap.error("--rows-only needs --cases-dir")
        cases = [c for c in cases if (args.cases_dir / f"{c['name']}.json").is_file()]
    rows = run_cases(cases, args.full, args.cases_dir, say)
    result = summary(rows)
    say(json.dumps({k: v for k, v in result.items() if k != "confusion"}, indent=1))
    for c in result["confusion"]:
        say(f"  {c['truth']:28s} → {c['verdict']:28s} {c['count']}")
    if args.json:
        frozen = {}
        if "validation" in args.sets.split(","):
            frozen = {
                "validation_set": os.path.relpath(args.validation_dir, REPO),
                "validation_manifest_sha256": manifest_hash(args.validation_dir),
                "frozen": not args.unfrozen,
            }
        mode = "full" if args.full else "model-free"
        doc = {**provenance(), "mode": mode, **frozen, **result, "cases": rows}
        write_result(args.json, doc)
    if args.result:
        if not args.full:
            ap.error("--result describes a full study: add --full")
        write_result(args.result, result_document(rows, selected, population=population))


if __name__ == "__main__":
    rf.configure()
    main()
