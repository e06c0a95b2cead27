"""Rewrite the results tables of the README and docs/performance.md from the result files in
benchmarks/results/.

Each ``benchmarks/results/*.json`` holds one benchmark: ``what`` it measures, a one-line
``summary`` of the latest figures (the table shows its first clause), the ``aim`` and
``verdict``, ``order`` (its row's place) and, for the few rows the README shows,
``headline: true``. This script renders them as Markdown tables, every result in
docs/performance.md and the headline ones in the README, each between the page's markers

    <!-- results:begin -->
    <!-- results:end -->

replacing what was there. Each page is written through a temporary file in its directory that
is then renamed over it, so an interrupted run leaves the old page intact.

    python benchmarks/readme_table.py            # rewrite the tables
    python benchmarks/readme_table.py --check    # exit 1 if a table is stale

Standard library only.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
README = ROOT / "README.md"
PERFORMANCE = ROOT / "docs" / "performance.md"
BEGIN = "<!-- results:begin -->"
END = "<!-- results:end -->"
REQUIRED = ("what", "summary", "aim", "verdict", "commit", "platform")


def _cell(text: object) -> str:
    """One table cell: a single line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def load_results(directory: Path) -> list[tuple[str, dict]]:
    """The result files of ``directory`` as (file name, document), in table order."""
    docs = []
    for path in sorted(directory.glob("*.json")):
        doc = json.loads(path.read_text(encoding="utf-8"))
        missing = [k for k in REQUIRED if k not in doc]
        if missing:
            raise ValueError(f"{path}: missing field(s) {', '.join(missing)}")
        docs.append((path.name, doc))
    docs.sort(key=lambda item: (item[1].get("order", 1_000), item[0]))
    return docs


def headline(summary: str) -> str:
    """The summary's first clause (up to a "; " or a sentence's ". " outside parentheses),
    with "…" where more follows in the file."""
    depth = 0
    for i, c in enumerate(summary):
        depth += (c in "([") - (c in ")]")
        if depth == 0 and (
            summary.startswith("; ", i)
            or (summary.startswith(". ", i) and not summary[i - 1 : i].isdigit())
        ):
            return summary[:i] + " …"
    return summary


def render(docs: list[tuple[str, dict]], link_prefix: str = "benchmarks/results/") -> str:
    """The Markdown table of ``docs``, markers excluded."""
    lines = [
        "| what | latest result | aim | verdict | file |",
        "|---|---|---|---|---|",
    ]
    for name, doc in docs:
        row = (
            _cell(doc["what"]),
            _cell(headline(doc["summary"])),
            _cell(doc["aim"]),
            _cell(doc["verdict"]),
            f"[{name}]({link_prefix}{name})",
        )
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def replace_table(text: str, table: str) -> str:
    """``text`` with everything between the markers replaced by ``table``."""
    start = text.find(BEGIN)
    stop = text.find(END)
    if start < 0 or stop < 0 or stop < start:
        raise ValueError(f"the README needs the markers {BEGIN} and {END}, in that order")
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


def pages(readme: Path, performance: Path, docs) -> list[tuple[Path, str]]:
    """Each page and its table: the headline results in the README, every one in
    docs/performance.md."""
    top = [(n, d) for n, d in docs if d.get("headline")]
    return [(readme, render(top)), (performance, render(docs, "../benchmarks/results/"))]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a table is stale")
    parser.add_argument("--readme", type=Path, default=README)
    parser.add_argument("--performance", type=Path, default=PERFORMANCE)
    parser.add_argument("--results", type=Path, default=RESULTS)
    args = parser.parse_args(argv)

    stale = 0
    try:
        docs = load_results(args.results)
        for page, table in pages(args.readme, args.performance, docs):
            text = page.read_text(encoding="utf-8")
            updated = replace_table(text, table)
            if updated == text:
                print(f"{page}: the results table is up to date")
            elif args.check:
                print(f"{page}: the results table is stale; run benchmarks/readme_table.py")
                stale = 1
            else:
                atomic_write(page, updated)
                print(f"rewrote the results table of {page}")
    except (OSError, ValueError) as exc:
        print(f"readme_table: {exc}", file=sys.stderr)
        return 2
    return stale


if __name__ == "__main__":
    sys.exit(main())
