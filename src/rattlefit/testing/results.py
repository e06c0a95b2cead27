"""Result files of benchmarks and studies: what was measured, at which commit, on what.

Every result file carries ``commit``, ``date``, ``platform`` and ``command``
(:func:`provenance`), so that a figure can be traced to the code that produced it and
re-measured; files are written whole or not at all (:func:`write_result`).
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


def provenance(command: str | None = None) -> dict:
    """``commit``, ``date`` (UTC, ISO), ``platform`` (:func:`rattlefit.platform_info`) and
    ``command`` (default: this process's command line)."""
    from ..reproducibility import platform_info

    if command is None:
        command = "python " + shlex.join(sys.argv)
    return {
        "commit": head_commit(),
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
