"""The documentation as a user meets it: the README's size, its links, and the generated
results tables against the result files."""

from __future__ import annotations

import re
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def test_the_readme_is_a_manual_of_at_most_200_lines_and_14_kb():
    # a manual, not a report: its generated results table takes up to about 2 KB of it
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200 and len(text.encode()) <= 14 * 1024


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_relative_link_resolves(page):
    text = page.read_text(encoding="utf-8")
    missing = [
        target
        for target in LINK.findall(text)
        if "://" not in target and not (page.parent / target).exists()
    ]
    assert not missing, f"{page.name}: links to missing files {missing}"


def test_the_results_tables_match_the_result_files():
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "readme_table.py"), "--check"],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stdout + out.stderr


def _remeasure():
    import readme_table
    import remeasure

    return readme_table, remeasure


def test_every_tabled_result_can_be_measured_again():
    # each result file has a recipe (a script that writes it) or says how it is measured by
    # hand; every headline figure the README can show has a recipe; a recipe names a script
    # that exists and options that script parses
    readme_table, remeasure = _remeasure()
    docs = readme_table.load_results(readme_table.RESULT_DIRS)
    names = {Path(n).name for n, _ in docs}
    assert not set(remeasure.RECIPES) & set(remeasure.BY_HAND)
    assert names <= set(remeasure.RECIPES) | set(remeasure.BY_HAND), names
    assert not (set(remeasure.RECIPES) | set(remeasure.BY_HAND)) - names  # no dead entry
    headlines = {Path(n).name for n, d in docs if d.get("headline")}
    assert headlines <= set(remeasure.RECIPES), headlines - set(remeasure.RECIPES)
    for name, (command, minutes) in remeasure.RECIPES.items():
        words = command.split()
        assert words[0] == "python" and minutes > 0, name
        source = (ROOT / words[1]).read_text(encoding="utf-8")
        if "from common import" in source:  # the studies' shared options (--set)
            source += (ROOT / "studies" / "common.py").read_text(encoding="utf-8")
        unknown = [w for w in words if w.startswith("--") and f'"{w}"' not in source]
        assert not unknown, f"{name}: {words[1]} has no option {unknown}"


def test_remeasure_runs_the_stale_results_and_stops_at_a_failure(monkeypatch):
    import subprocess as sp

    _, remeasure = _remeasure()
    rows = [("a/forward.json", {}, "current"), ("b/coverage.json", {}, "stale: src changed")]
    rows.append(("b/ci_time.json", {}, "stale: src changed"))  # by hand: never run
    assert remeasure.chosen(rows, every=False, only=[]) == ["coverage.json"]
    assert remeasure.chosen(rows, every=True, only=[]) == ["forward.json", "coverage.json"]
    with pytest.raises(ValueError, match=r"ci_time\.json"):
        remeasure.chosen(rows, every=False, only=["ci_time.json"])
    ran = []

    def fake_run(command, **kwargs):  # records; "broken" fails, the rest succeed
        ran.append(command)
        status = 3 if command == "broken {commit}".format(commit="abc") else 0
        return sp.CompletedProcess(command, status, stdout="abc\n")

    monkeypatch.setattr(remeasure.subprocess, "run", fake_run)
    monkeypatch.setattr(remeasure, "git", lambda *a: fake_run(["git", *a]))
    monkeypatch.setattr(
        remeasure, "RECIPES", {"broken": ("broken {commit}", 1), "fine": ("fine", 1)}
    )
    assert remeasure.run(["broken", "fine"]) == 3
    assert ran[-1] == "broken abc"  # HEAD's hash in place of {commit}; stopped there
    ran.clear()
    assert remeasure.run(["fine"]) == 0
    assert ran[1] == "fine" and ran[-1][-1] == "benchmarks/readme_table.py"  # then the tables


#: What reads as a measured figure in prose: a count of cases (24/27, 6 of 22), a ratio
#: (2.8×, 3–6 times, a factor 20–26) or a change (from 5.4 to 3.1, 262 → 30). Settings and
#: closed forms are written otherwise (ten times as long, R^{3/2}).
MEASURED = re.compile(
    r"(?<![\w^{(/.])\d+/\d+(?![\w}/.])"
    r"|(?<![\d.])\d+ of (the )?\d+\b(?!\.\d)"
    r"|\d[\d.]*\s?×"
    r"|\d[\d.]*\s?[–-]\s?\d[\d.]*\s?times"
    r"|\bfrom (a factor )?\d[\d.]* to \d[\d.]*"
    r"|\d[\d.]*\s?→\s?\d[\d.]*"
    r"|factor (of )?\d[\d.]*\s?[–-]\s?\d"
)
RESULT_FILE = re.compile(r"(?:benchmarks|studies)/results/[\w./-]+\.json|\b[\w-]+\.json\b")
PROSE = [*PAGES, ROOT / "CHANGELOG.md"]


def uncited_figures(text: str) -> list[str]:
    """The paragraphs (and list items) of Markdown ``text`` that hold a measured figure
    (:data:`MEASURED`, outside code) but name no result file."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    bad = []
    for block in re.split(r"\n\s*\n|\n(?=\s*(?:[*-]|\d+\.) )", text):
        if block.lstrip().startswith(("|", "<!--")):
            continue  # the generated results tables
        if MEASURED.search(re.sub(r"`[^`]*`", "", block)) and not RESULT_FILE.search(block):
            bad.append(" ".join(block.split())[:160])
    return bad


def test_the_figure_detector_needs_a_result_file_beside_a_figure():
    assert uncited_figures("Coverage is 24/27 on the grid.")
    assert uncited_figures("It narrows `a` from a factor 5.4 to 3.1.")
    assert uncited_figures("- about 2.8× the samples\n- and more")
    assert not uncited_figures("Coverage is 24/27 (`studies/results/companion.json`).")
    assert not uncited_figures("The film's momentum ∝ R^{3/2}; the same test ten times as long.")


@pytest.mark.parametrize("page", PROSE, ids=lambda p: p.name)
def test_every_measured_figure_in_the_prose_names_its_result_file(page):
    # a figure in docs/, the README or the changelog comes from a committed result file, and
    # says which, or it goes
    text = page.read_text(encoding="utf-8")
    assert not uncited_figures(text), "\n".join(uncited_figures(text))
    named = re.findall(r"(?:benchmarks|studies)/results/[\w./-]+\.json", text)
    missing = sorted({n for n in named if not (ROOT / n).is_file()})
    assert not missing, f"{page.name} names result files that do not exist: {missing}"


#: The pages whose commands a user copies: every ``rattlefit …`` line in their code.
COMMAND_PAGES = [*PAGES, ROOT / "data" / "README.md", ROOT / "notebooks" / "README.md"]


def documented_commands(text: str) -> list[str]:
    """Every ``rattlefit …`` command in Markdown ``text``'s code (fenced or indented), with
    its continuation lines joined and any trailing comment dropped."""
    commands, current, fenced = [], None, False
    for line in text.splitlines():
        body = line.strip()
        if body.startswith("```"):
            fenced = not fenced
            continue
        if current is not None:
            current += " " + body.rstrip("\\").strip()
        elif body.startswith("rattlefit ") and (fenced or line.startswith("    ")):
            current = body.rstrip("\\").strip()
        if current is not None and not body.endswith("\\"):
            commands.append(re.sub(r"\s+#.*$", "", current))
            current = None
    return commands


def parse_command(words: list[str]) -> None:
    """Parse ``rattlefit`` arguments ``words`` as the CLI would, running nothing. Raises
    click's UsageError for an unknown option or command, a bad choice or a missing value; a
    path that does not exist here (a placeholder such as FILE.h5) is not an error."""
    import click

    from rattlefit.cli import main

    ctx = main.make_context("rattlefit", list(words))
    command, group = main, ctx
    while isinstance(command, click.Group):
        with warnings.catch_warnings():  # click 8.2 deprecates protected_args, 9 drops it
            warnings.simplefilter("ignore", DeprecationWarning)
            args = [*group.protected_args, *group.args]
        name, sub, rest = command.resolve_command(group, args)
        try:
            group = sub.make_context(name, rest, parent=group)
        except click.BadParameter as exc:
            if "does not exist" not in str(exc):
                raise
            return
        command = sub


def test_the_command_parser_catches_a_removed_option():
    import click

    with pytest.raises(click.UsageError):
        parse_command(["simulate", "--pair", "II", "--center-distance", "65.6"])
    with pytest.raises(click.UsageError):
        parse_command(["identify", "FILE.h5", "--likelihood", "magic"])
    parse_command(["campaign", "camp/manifest.csv", "-o", "results/", "--quick"])


@pytest.mark.parametrize("page", COMMAND_PAGES, ids=lambda p: p.parent.name + "/" + p.name)
def test_every_documented_command_parses(page):
    import shlex

    commands = documented_commands(page.read_text(encoding="utf-8"))
    failed = []
    for command in commands:
        try:
            parse_command(shlex.split(command)[1:])
        except Exception as exc:  # every failure is reported with its command
            failed.append(f"{command}\n    {type(exc).__name__}: {exc}")
    assert not failed, "\n".join(failed)
