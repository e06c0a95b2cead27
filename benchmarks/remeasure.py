"""Re-measure the tabled results at HEAD: one command for every figure the tables show.

Each tabled result file (``benchmarks/results/*.json``, ``studies/results/*.json``; see
``readme_table.py``) has a recipe here (:data:`RECIPES`): the command that writes it, with its
provenance, and a typical time on 2 cores. The command a result file records is how that file
was made; the recipe is how to make it again from today's tree.

    python benchmarks/remeasure.py                  # every result: state, recipe, typical time
    python benchmarks/remeasure.py --run            # re-run every stale result with a recipe,
                                                    # one after another, then the tables
    python benchmarks/remeasure.py --run --all      # every result with a recipe
    python benchmarks/remeasure.py --run --only forward.json coverage.json

Results without a recipe (:data:`BY_HAND`) are measured by hand, as their entry says; the
listing shows them. A recipe that fails stops the run with its exit status; what it had not
yet written is left as it was (result files are written whole, through a rename). Run it from
the repository's root with the README's environment; nothing else should run beside it.
Standard library only.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from readme_table import RESULT_DIRS, ROOT, git, load_results, staleness, state

#: Result file (its name) → (the command that writes it, typical minutes on 2 cores).
#: ``{commit}`` stands for HEAD's short hash: a study that resumes from rows or learned
#: likelihoods kept on disk resumes only from those of the code it measures.
RECIPES: dict[str, tuple[str, float]] = {
    "forward.json": (
        "python benchmarks/run.py --write-results --json benchmarks/results/raw/full.json",
        10,
    ),
    "campaign.json": ("python benchmarks/campaign_throughput.py", 6),
    "startup.json": ("python benchmarks/startup.py --json benchmarks/results/startup.json", 1),
    "step_regimes.json": (
        "python benchmarks/step_regimes.py --json benchmarks/results/step_regimes.json",
        3,
    ),
    "identify_time.json": (
        "python benchmarks/identify_time.py --json benchmarks/results/identify_time.json "
        "--cache-json benchmarks/results/compile_cache.json",
        4,
    ),
    "diagnose_time.json": (
        "python benchmarks/diagnose_time.py --json benchmarks/results/diagnose_time.json",
        8,
    ),
    "learned_time.json": (
        "python benchmarks/learned_time.py data/pairII_boundary_65.6_20pct_16Hz.h5 "
        "--json benchmarks/results/learned_time.json",
        6,
    ),
    "coverage.json": (
        "python studies/coverage.py --seed 0 --quiet --result studies/results/coverage.json",
        60,
    ),
    "coverage_learned.json": (
        "python studies/coverage.py --seed 1 --quiet --set 'likelihood=\"learned\"' "
        "--result studies/results/coverage_learned.json",
        40,
    ),
    "companion.json": (
        "python studies/coverage.py --seed 0 --companion oil_jet --quiet "
        "--result studies/results/companion.json",
        90,
    ),
    "feature_sets.json": (
        "python studies/feature_sets.py --seed 0 --json studies/results/feature_sets.json",
        120,
    ),
    "feature_information.json": (
        "python studies/feature_information.py --json studies/results/feature_information.json",
        30,
    ),
    "headline_point.json": (
        "python studies/headline_point.py --json studies/results/headline_point.json",
        30,
    ),
    "long_recording.json": (
        "python studies/long_recording.py --json studies/results/long_recording.json",
        60,
    ),
    "diagnose_study.json": (
        "python studies/diagnose_study.py --sets shared,clean,injected "
        "--json studies/results/diagnose_study.json",
        10,
    ),
    "diagnose_full_study.json": (
        "python studies/diagnose_study.py --full --sets shared,clean,injected --sample 20 "
        "--sample-seed 0 --quiet --cases-dir studies/cache/diagnose_cases/{commit} "
        "--result studies/results/diagnose_full_study.json",
        60,
    ),
    "fixed_step.json": (
        "python benchmarks/fixed_step.py --steps-per-sample 1 2 3 5 10 "
        "--json benchmarks/results/fixed_step.json",
        6,
    ),
    "step_anatomy.json": (
        "python benchmarks/step_anatomy.py --json benchmarks/results/step_anatomy.json",
        2,
    ),
    "density_error.json": ("python studies/density_error.py --cases 20", 90),
    "own_data.json": ("python studies/own_data.py --seeds 0 1 2", 60),
    "shared_recordings.json": ("python studies/shared_recordings.py --seed 0", 60),
    "sbc.json": (
        "python studies/sbc.py --cases 70 --points boundary,oil_jet,dry --initial 8192 "
        "--steps 1200 --seed 0 --cache studies/cache/sbc/{commit}",
        46,
    ),
}
#: Result files that no script writes whole, and how each is measured.
BY_HAND: dict[str, str] = {
    "batch.json": "python benchmarks/run.py --quick --identify (its batch and per-member lines)",
    "jacobian.json": "python benchmarks/run.py (its Jacobian lines)",
    "memory.json": "python benchmarks/run.py --identify --posterior; --quick --diagnose",
    "posterior.json": "python benchmarks/run.py --identify --posterior",
    "compile_cache.json": "written with identify_time.json (its recipe)",
    "ci_time.json": ".ci/run on a fresh clone, timed",
    "isa_cost.json": "python benchmarks/isa_cost.py",
    "slow_tests.json": "RATTLEFIT_SLOW=1 python -m pytest -n 2 tests/test_fit.py",
    "joint_sweep.json": "python studies/sweep_study.py --center-distances 65.0 65.4 66.0 "
    "--refits 3",
    "diagnose_withheld_friction.json": "RATTLEFIT_NOTEBOOK_QUICK=0 jupyter execute "
    "notebooks/04_diagnose_the_gap.ipynb (its outputs)",
}


def listing(rows) -> list[str]:
    """One line per result: its state with the paths behind it, and its recipe and typical
    time (or how it is measured by hand)."""
    out = []
    for name, doc, st in rows:
        base = Path(name).name
        if base in RECIPES:
            command, minutes = RECIPES[base]
            how = f"~{minutes:g} min: {command}"
        else:
            how = f"by hand: {BY_HAND.get(base, '(no recipe)')}"
        paths = staleness(doc, name)[1] if st != "current" else []
        more = f" (+{len(paths) - 4} more)" if len(paths) > 4 else ""
        why = f" [{', '.join(paths[:4])}{more}]" if paths else ""
        out.append(f"{name}: {st}{why}\n    {how}")
    return out


def chosen(rows, *, every: bool, only: list[str]) -> list[str]:
    """The result names to re-run: ``only`` when given, else every stale one with a recipe
    (every one with ``every``). Raises ValueError for a name without a recipe."""
    if only:
        missing = [n for n in only if n not in RECIPES]
        if missing:
            raise ValueError(f"no recipe for {', '.join(missing)}; known: {', '.join(RECIPES)}")
        return list(only)
    return [
        Path(name).name
        for name, _, st in rows
        if Path(name).name in RECIPES and (every or st != "current")
    ]


def run(names: list[str]) -> int:
    """Run each recipe of ``names`` in turn from the repository's root, then the tables; the
    first failure's exit status, else 0."""
    total = sum(RECIPES[n][1] for n in names)
    commit = git("rev-parse", "--short", "HEAD").stdout.strip()
    print(f"re-measuring {len(names)} result(s), typically {total:g} min", file=sys.stderr)
    for k, name in enumerate(names):
        command, minutes = RECIPES[name]
        command = command.format(commit=commit)
        print(f"[{k + 1}/{len(names)}] {name} (~{minutes:g} min): {command}", file=sys.stderr)
        t0 = time.perf_counter()
        status = subprocess.run(command, shell=True, cwd=ROOT, check=False).returncode
        took = (time.perf_counter() - t0) / 60
        if status != 0:
            print(
                f"{name}: its recipe failed (exit {status}) after {took:.1f} min", file=sys.stderr
            )
            return status
        print(f"{name}: done in {took:.1f} min", file=sys.stderr)
    return subprocess.run(
        [sys.executable, "benchmarks/readme_table.py"], cwd=ROOT, check=False
    ).returncode


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", action="store_true", help="re-run the recipes (default: list)")
    ap.add_argument("--all", action="store_true", help="with --run: current results too")
    ap.add_argument("--only", nargs="+", default=[], metavar="FILE", help="these results")
    args = ap.parse_args(argv)
    try:
        rows = [(n, d, state(d, n)) for n, d in load_results(RESULT_DIRS)]
        if not args.run:
            print("\n".join(listing(rows)))
            return 0
        names = chosen(rows, every=args.all, only=args.only)
    except (OSError, ValueError) as exc:
        print(f"remeasure: {exc}", file=sys.stderr)
        return 2
    return run(names)


if __name__ == "__main__":
    sys.exit(main())
