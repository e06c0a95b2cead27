"""Rewrite the results tables of the README and docs/performance.md from the result files, and
check that every figure the README shows is true of the code.

Each ``benchmarks/results/*.json`` and ``studies/results/*.json`` with a one-line string
``summary`` is one row: ``what`` it measures, the ``summary`` of its figures (the table shows
its first clause), the ``aim`` and ``verdict``, ``order`` (its row's place) and, for the rows
the README shows, ``headline: true``. Files whose ``summary`` is not a string (raw study
output) are not tabled.

**Freshness.** What a result measures is derived from its ``command`` (``measured.py``: the
scripts it runs and every repository module they import, the repository files it names,
``constraints.txt``), never declared. A result is *current* when its ``commit`` descends from
the last change to those paths, none of them has uncommitted changes now, none changed between
the commit its run started at (``commit_started``) and ``commit``, and none was among the
``uncommitted`` paths when it was written; otherwise it is *stale* (a file that does not record
``uncommitted`` is stale too). docs/performance.md lists every result with its state; the
README shows only the current headline results, so a figure it shows was measured on the code
it describes. A stale result is fixed by re-running its command, never by editing it.

Each table sits between the page's markers

    <!-- results:begin -->
    <!-- results:end -->

and is written through a temporary file renamed over the page.

    python benchmarks/readme_table.py            # rewrite the tables
    python benchmarks/readme_table.py --check    # exit 1 if a table is not what the files and
                                                 # the history give (run in the tests)

Needs git and the repository's history. Standard library only.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from measured import ENVIRONMENT, measured_paths

ROOT = Path(__file__).resolve().parents[1]
RESULT_DIRS = (ROOT / "benchmarks" / "results", ROOT / "studies" / "results")
README = ROOT / "README.md"
PERFORMANCE = ROOT / "docs" / "performance.md"
BEGIN = "<!-- results:begin -->"
END = "<!-- results:end -->"
REQUIRED = ("what", "summary", "aim", "verdict", "commit", "platform", "command")


def _cell(text: object) -> str:
    """One table cell: a single line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def load_results(directories, root: Path = ROOT) -> list[tuple[str, dict]]:
    """The tabled result files of ``directories`` as (path relative to ``root``, document), in
    table order. Raises ValueError naming the file and the missing fields."""
    docs = []
    for directory in directories:
        for path in sorted(Path(directory).glob("*.json")):
            doc = json.loads(path.read_text(encoding="utf-8"))
            if not isinstance(doc.get("summary"), str):
                continue
            missing = [k for k in REQUIRED if k not in doc]
            if missing:
                raise ValueError(f"{path}: missing field(s) {', '.join(missing)}")
            docs.append((path.relative_to(root).as_posix(), doc))
    docs.sort(key=lambda item: (item[1].get("order", 1_000), item[0]))
    return docs


def git(*args: str, root: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, check=False)


def uncommitted(paths, root: Path = ROOT) -> bool:
    """Whether any of ``paths`` has uncommitted changes (untracked files included)."""
    return bool(git("status", "--porcelain", "--", *paths, root=root).stdout.strip())


def state(doc: dict, name: str, root: Path = ROOT) -> str:
    """ "current", or "stale: ..." saying why (:func:`staleness`; which paths or commits is
    left out, so that the state changes only when a result goes stale or is re-measured)."""
    return staleness(doc, name, root)[0]


def staleness(doc: dict, name: str, root: Path = ROOT) -> tuple[str, list[str]]:
    """The state of result ``doc`` (file ``name``) and the paths behind a stale one. Raises
    ValueError when its commit is not in the history."""
    commit = str(doc["commit"])
    for c in {commit, str(doc.get("commit_started") or commit)}:
        if git("cat-file", "-e", f"{c}^{{commit}}", root=root).returncode != 0:
            raise ValueError(f"{name}: its commit {c} is not in this repository's history")
    derived = measured_paths(str(doc["command"]), root)
    if derived.missing:
        return "stale: its command runs a script this tree does not have", list(derived.missing)
    paths = [p for p in derived.paths if p not in ENVIRONMENT]
    if not paths:
        return "stale: its command runs nothing in this repository", []
    if not isinstance(doc.get("uncommitted"), list):
        return "stale: its file does not record whether the tree was clean", []
    dirty = [u for u in doc["uncommitted"] if any(u == p or u.startswith(p.rstrip("/") + "/")
                                                  for p in derived.paths)]  # fmt: skip
    if dirty:
        return "stale: written with uncommitted changes to what it runs", dirty
    started = str(doc.get("commit_started") or commit)
    moved = changed_between(started, commit, derived.paths, root)
    if moved:
        return "stale: what it runs changed while it ran", moved
    if uncommitted(derived.paths, root):
        return "stale: what it runs has uncommitted changes", []
    later = changed_between(commit, "HEAD", derived.paths, root)
    if later:
        return f"stale: what it runs changed after {commit}", later
    return "current", []


def changed_between(old: str, new: str, paths, root: Path = ROOT) -> list[str]:
    """The ``paths`` (files, or files under folders) that differ between commits ``old`` and
    ``new``."""
    if old == new:
        return []
    out = git("diff", "--name-only", old, new, "--", *paths, root=root)
    if out.returncode != 0:
        raise ValueError(f"git cannot compare {old} with {new}: {out.stderr.strip()}")
    return out.stdout.split()


def headline(summary: str, stops: tuple[str, ...] = ("; ", ". ")) -> str:
    """The summary's first clause (up to a "; " or a sentence's ". " outside parentheses, or
    another of ``stops``), with "…" where more follows in the file."""
    depth = 0
    for i, c in enumerate(summary):
        depth += (c in "([") - (c in ")]")
        if depth == 0 and any(
            summary.startswith(stop, i) and not (stop == ". " and summary[i - 1 : i].isdigit())
            for stop in stops
        ):
            return summary[:i] + " …"
    return summary


def render(rows, link_prefix: str = "", with_state: bool = False) -> str:
    """The Markdown table of ``rows`` ((path, document, state)), markers excluded."""
    head = ["what", "latest result", "aim", "verdict"] + (["state"] if with_state else [])
    lines = ["| " + " | ".join([*head, "file"]) + " |", "|" + "---|" * (len(head) + 1)]
    for name, doc, st in rows:
        # the README names what was measured up to its ": " (the full text in the file)
        what = doc["what"] if with_state else headline(doc["what"], (": ",))
        row = [_cell(what), _cell(headline(doc["summary"])), _cell(doc["aim"])]
        row.append(_cell(doc["verdict"]))
        if with_state:
            row.append(_cell(st))
        row.append(f"[{Path(name).name}]({link_prefix}{name})")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def replace_table(text: str, table: str) -> str:
    """``text`` with everything between the markers replaced by ``table``."""
    start = text.find(BEGIN)
    stop = text.find(END)
    if start < 0 or stop < 0 or stop < start:
        raise ValueError(f"the page needs the markers {BEGIN} and {END}, in that order")
    head = text[: start + len(BEGIN)]
    return f"{head}\n{table}\n{text[stop:]}"


def atomic_write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file renamed into place."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as f:
            f.write(text)
        if path.exists():
            os.chmod(tmp, path.stat().st_mode & 0o777)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def pages(readme: Path, performance: Path, rows) -> list[tuple[Path, str]]:
    """Each page and its table: the current headline results in the README, every result
    with its state in docs/performance.md."""
    top = [r for r in rows if r[1].get("headline") and r[2] == "current"]
    return [(readme, render(top)), (performance, render(rows, "../", with_state=True))]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a table is stale")
    parser.add_argument("--readme", type=Path, default=README)
    parser.add_argument("--performance", type=Path, default=PERFORMANCE)
    args = parser.parse_args(argv)

    outdated = 0
    try:
        rows = [(n, d, state(d, n)) for n, d in load_results(RESULT_DIRS)]
        for page, table in pages(args.readme, args.performance, rows):
            text = page.read_text(encoding="utf-8")
            updated = replace_table(text, table)
            if updated == text:
                print(f"{page}: the results table is up to date")
            elif args.check:
                print(f"{page}: the results table is not what the result files and the git "
                      "history give; run benchmarks/readme_table.py")  # fmt: skip
                outdated = 1
            else:
                atomic_write(page, updated)
                print(f"rewrote the results table of {page}")
        for name, _, st in rows:
            if st != "current":
                print(f"{name}: {st}")
    except (OSError, ValueError) as exc:
        print(f"readme_table: {exc}", file=sys.stderr)
        return 2
    return outdated


if __name__ == "__main__":
    sys.exit(main())
