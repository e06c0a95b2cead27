"""Result files of benchmarks and studies: what was measured, at which commit, on what.

Every result file carries ``commit``, ``date``, ``platform`` and ``command``
(:func:`provenance`), so that a figure can be traced to the code that produced it and
re-measured, and what the tree was while it ran: ``commit_started`` (HEAD when this module was
first imported, the run's start) and ``uncommitted`` (the paths with uncommitted changes when
it was written). ``benchmarks/readme_table.py`` marks a result stale when a path its command
imports changed between the two commits or was among the uncommitted ones. Files are written
whole or not at all (:func:`write_result`).
"""

from __future__ import annotations

import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path


def head_commit() -> str:
    """The checkout's HEAD commit (short hash), or "" outside a git checkout."""
    out = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
    )
    return out.stdout.strip()


def uncommitted_paths() -> list[str]:
    """The repository's paths (relative to its root) with uncommitted changes, untracked files
    included, outside the folders results are written to; [] outside a git checkout."""
    out = subprocess.run(
        ["git", "status", "--porcelain", "--untracked-files=all"],
        capture_output=True,
        text=True,
        check=False,
    )
    paths = []
    for line in out.stdout.splitlines():
        path = line[3:].split(" -> ")[-1].strip('"')
        if not path.startswith(OUTPUT_DIRS):
            paths.append(path)
    return sorted(paths)


#: Folders that results and caches are written to: their changes are not the code's.
OUTPUT_DIRS = ("benchmarks/results/", "studies/results/", "studies/cache/", "benchmarks/cache/")
#: HEAD when this module was first imported: the commit a study or benchmark started at.
COMMIT_STARTED = head_commit()


def tree_state() -> dict:
    """``commit`` (HEAD now), ``commit_started`` (:data:`COMMIT_STARTED`) and ``uncommitted``
    (:func:`uncommitted_paths`): what a result file needs for its freshness to be judged."""
    return {
        "commit": head_commit(),
        "commit_started": COMMIT_STARTED,
        "uncommitted": uncommitted_paths(),
    }


def provenance(command: str | None = None) -> dict:
    """:func:`tree_state`, ``date`` (UTC, ISO), ``platform``
    (:func:`rattlefit.platform_info`) and ``command`` (default: this process's command
    line)."""
    from ..reproducibility import platform_info

    if command is None:
        command = "python " + shlex.join(sys.argv)
    return {
        **tree_state(),
        "date": time.strftime("%Y-%m-%d", time.gmtime()),
        "platform": platform_info(),
        "command": command,
    }


def write_result(path: str | os.PathLike, doc: dict, **dump_options) -> None:
    """``doc`` as JSON (indented by 2 unless ``dump_options`` say otherwise) at ``path``,
    through a temporary file renamed into place: never a half-written file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc, **{"indent": 2, **dump_options}))
    os.replace(tmp, path)
