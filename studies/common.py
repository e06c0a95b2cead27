"""What the studies share: the commit they ran at, and writing a result file atomically."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path


def head_commit() -> str:
    """The short hash of the checkout's HEAD."""
    out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return out.stdout.strip()


def write_result(path: str | os.PathLike, doc: dict) -> None:
    """Write ``doc`` as JSON to ``path`` through a temporary file renamed into place."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(doc, indent=1))
    os.replace(tmp, path)


def held(rows: list[dict]) -> tuple[int, int]:
    """How many of the rows' parameters hold their truth, and how many there are."""
    flags = [v["holds"] for r in rows for v in r["parameters"].values()]
    return sum(flags), len(flags)
