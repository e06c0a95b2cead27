"""The staleness check of result files (benchmarks/readme_table.py, benchmarks/measured.py):
what a result measures is derived from its command, and no edit, dirty tree or commit landing
mid-run leaves a stale figure looking current. Each case runs in a temporary clone."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
FORWARD = "python benchmarks/run.py --write-results --json benchmarks/results/raw/full.json"


def _modules():
    import measured
    import readme_table

    return measured, readme_table


def _git(root: Path, *args: str) -> str:
    out = subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, check=True)
    return out.stdout.strip()


@pytest.fixture
def clone(tmp_path) -> Path:
    """A clone of the repository at HEAD (uncommitted work left out), with an identity."""
    subprocess.run(["git", "clone", "--quiet", str(ROOT), str(tmp_path / "r")], check=True)
    root = tmp_path / "r"
    _git(root, "config", "user.email", "test@example.invalid")
    _git(root, "config", "user.name", "test")
    return root


def _result(root: Path, **changes) -> dict:
    head = _git(root, "rev-parse", "--short", "HEAD")
    doc = {"command": FORWARD, "commit": head, "commit_started": head, "uncommitted": []}
    return {**doc, **changes}


def _commit(root: Path, path: str, line: str) -> str:
    with open(root / path, "a", encoding="utf-8") as f:
        f.write(line)
    _git(root, "commit", "--quiet", "-am", f"touch {path}")
    return _git(root, "rev-parse", "--short", "HEAD")


def test_what_forward_measures_is_derived_from_its_imports():
    # the modules a hand-written list forgot: the configuration, the recording's reader and the
    # suite's own step module; and a script that is gone is named as missing
    measured, _ = _modules()
    paths = set(measured.measured_paths(FORWARD).paths)
    wanted = {
        "benchmarks/run.py",
        "benchmarks/suite_steps.py",
        "src/rattlefit/config.py",
        "src/rattlefit/io/recording.py",
        "src/rattlefit/simulation/reference.py",
        "constraints.txt",
    }
    assert wanted <= paths, wanted - paths
    # what the package's lazy names reach counts too: a script using rattlefit.identify
    assert (
        "src/rattlefit/inference/identify.py"
        in measured.measured_paths("python benchmarks/startup.py").paths
    )
    assert not {p for p in paths if p.startswith(("tests/", "studies/", "notebooks/"))}
    gone = measured.measured_paths("python benchmarks/coverage.py --seed 0")
    assert gone.missing == ("benchmarks/coverage.py",)


def test_an_import_inside_a_function_and_a_lazy_name_used_are_followed(tmp_path):
    measured, _ = _modules()
    (tmp_path / "src" / "pkg").mkdir(parents=True)
    lazy = '_LAZY = {"Y": ".lazy", "Z": ".other", "W": ".unused"}\n'
    (tmp_path / "src" / "pkg" / "__init__.py").write_text(lazy)
    for name in ("late", "lazy", "other", "unused", "never"):
        (tmp_path / "src" / "pkg" / f"{name}.py").write_text("X = 1\n")
    (tmp_path / "helper.py").write_text(
        "def f():\n    from pkg import late, Y\n    import pkg as p\n    return p.Z, late, Y\n"
    )
    (tmp_path / "run.py").write_text("import helper\n")
    found = measured.closure([tmp_path / "run.py"], tmp_path)
    want = ["helper.py", "run.py", "src/pkg/__init__.py", "src/pkg/late.py", "src/pkg/lazy.py"]
    assert found == [*want, "src/pkg/other.py"]  # W's module is never imported
    # the package handed on, or read by a computed name, reaches every lazy module
    (tmp_path / "helper.py").write_text("import pkg\n\ndef f(n):\n    return getattr(pkg, n)\n")
    measured.imported_names.cache_clear()
    found = measured.closure([tmp_path / "run.py"], tmp_path)
    assert "src/pkg/unused.py" in found and "src/pkg/late.py" not in found


def test_a_script_that_starts_the_command_line_depends_on_it(tmp_path):
    measured, _ = _modules()
    (tmp_path / "run.py").write_text(
        'import sys\nfrom pathlib import Path\nexe = Path(sys.executable).with_name("rattlefit")\n'
    )
    (tmp_path / "other.py").write_text('meta = {"rattlefit": "1.0"}\n')
    (tmp_path / "module.py").write_text('args = [sys.executable, "-m", "rattlefit", "identify"]\n')
    for script, starts in (("run.py", True), ("other.py", False), ("module.py", True)):
        assert measured.runs_the_command_line(tmp_path / script) == starts, script


def test_a_result_goes_stale_when_what_it_imports_changes(clone):
    _, rt = _modules()
    assert rt.state(_result(clone), "forward.json", clone) == "current"
    # a change to what no hand-written list named, uncommitted, then committed
    (clone / "src/rattlefit/config.py").write_text(
        (clone / "src/rattlefit/config.py").read_text() + "\n# changed\n"
    )
    assert rt.state(_result(clone), "f", clone) == "stale: what it runs has uncommitted changes"
    doc = _result(clone)
    _git(clone, "commit", "--quiet", "-am", "config")
    assert rt.state(doc, "f", clone).startswith("stale: what it runs changed after")
    # a change elsewhere leaves it current
    doc = _result(clone)
    _commit(clone, "notebooks/README.md", "\nmore words\n")
    assert rt.state(doc, "f", clone) == "current"


def test_a_result_written_from_a_dirty_tree_or_across_a_commit_is_stale(clone):
    _, rt = _modules()
    dirty = _result(clone, uncommitted=["src/rattlefit/io/recording.py"])
    assert rt.state(dirty, "f", clone) == "stale: written with uncommitted changes to what it runs"
    unrelated = _result(clone, uncommitted=["docs/model.md"])
    assert rt.state(unrelated, "f", clone) == "current"
    legacy = {k: v for k, v in _result(clone).items() if k != "uncommitted"}
    assert rt.state(legacy, "f", clone).startswith("stale: its file does not record")
    assert rt.state(_result(clone, uncommitted=None), "f", clone) == rt.state(legacy, "f", clone)
    started = _git(clone, "rev-parse", "--short", "HEAD")
    ended = _commit(clone, "benchmarks/suite_steps.py", "\n# landed mid-run\n")
    across = _result(clone, commit=ended, commit_started=started)
    assert rt.state(across, "f", clone) == "stale: what it runs changed while it ran"
    docs_only = _commit(clone, "docs/model.md", "\nmore words\n")
    assert rt.state(_result(clone, commit_started=ended), "f", clone) == "current"
    assert docs_only != ended


def _diagnose_study():
    # studies/ names its modules plainly (common, coverage): on sys.path only for this import
    sys.path.insert(0, str(ROOT / "studies"))
    try:
        import diagnose_study
    finally:
        sys.path.remove(str(ROOT / "studies"))
    return diagnose_study


def test_a_validation_set_is_scored_only_at_the_method_it_was_drawn_for(tmp_path):
    study = _diagnose_study()
    manifest = tmp_path / "manifest.json"
    manifest.write_text('{"seed": 1}')
    assert "no method commit" in study.frozen_method_problem(tmp_path)
    # a method commit whose package differs from this checkout's: refused, naming a path
    first = _git(ROOT, "rev-list", "--max-parents=0", "HEAD").split()[0]
    manifest.write_text(f'{{"seed": 1, "method_commit": "{first}"}}')
    problem = study.frozen_method_problem(tmp_path)
    assert f"drawn for the method of {first[:12]}" in problem and "src/" in problem
    manifest.write_text('{"seed": 1, "method_commit": "0123456789abcdef"}')
    assert "not in this history" in study.frozen_method_problem(tmp_path)


def test_the_standing_diagnose_sample_is_half_clean_seeded_and_scored_with_exact_intervals():
    study = _diagnose_study()
    clean = [{"name": f"c{i}", "expected": ["none", "unexplained"]} for i in range(28)]
    effect = [{"name": f"e{i}", "expected": ["runout"]} for i in range(23)]
    cases = [c for pair in zip(clean, effect, strict=False) for c in pair] + clean[23:]
    sample = study.sample_cases(cases, 10, 0)
    names = [c["name"] for c in sample]
    assert sum(map(study.is_clean, sample)) == 5 and len(set(names)) == 10
    assert names == [c["name"] for c in cases if c["name"] in names]  # in the cases' order
    assert sample == study.sample_cases(cases, 10, 0)
    assert sample != study.sample_cases(cases, 10, 1)
    # fewer clean cases than half the sample: all of them, the rest effect cases
    few = study.sample_cases(clean[:2] + effect, 10, 0)
    assert sum(map(study.is_clean, few)) == 2 and len(few) == 10
    # Clopper–Pearson: closed forms at the ends, binomial tails of 2.5 % inside
    assert study.rate_interval(0, 5)[1] == pytest.approx(1 - 0.025 ** (1 / 5), abs=1e-4)
    assert study.rate_interval(5, 5)[0] == pytest.approx(0.025 ** (1 / 5), abs=1e-4)
    lo, hi = study.rate_interval(2, 10)
    assert stats.binom.cdf(2, 10, hi) == pytest.approx(0.025, abs=1e-3)
    assert stats.binom.sf(1, 10, lo) == pytest.approx(0.025, abs=1e-3)
    # every verdict right on five clean cases: the false-positive aim needs twenty
    rows = [c | {"set": "s", "verdict": c["expected"][0], "right": True} for c in sample]
    result = study.summary(rows)
    assert (result["false_positives"], result["effect_right"]) == (0, 5)
    verdict = study.study_verdict(result, 5, 5)
    assert verdict.startswith("false positives missed (0 of 5 clean")
    assert "effect cases met" in verdict
