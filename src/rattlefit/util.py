"""Small helpers shared by the modules (not public API)."""

from __future__ import annotations

import json
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np


def concrete(x) -> np.ndarray | None:
    """``x`` as a numpy array if it is a concrete value, or None while it is being traced."""
    if isinstance(x, jax.core.Tracer):
        return None
    try:
        return np.asarray(x, dtype=float)
    except (TypeError, jax.errors.ConcretizationTypeError):
        return None


def array_namespace(*xs):
    """``jax.numpy`` while any of ``xs`` is being traced, else ``numpy``.

    The host side of a fit (its costs, band spreads, finite-difference points and interval
    bookkeeping) runs on concrete arrays of ever new shapes, and every new shape of an eager
    ``jax.numpy`` operation compiles a program of its own (hundreds of programs, many seconds,
    for one identification). Functions
    that serve both sides take their array module from this, so that the traced side (the
    Levenberg–Marquardt residual, the simulator's inputs) stays in JAX and the host side
    compiles nothing.
    """
    return jnp if any(isinstance(x, jax.core.Tracer) for x in xs) else np


def atomic_write(path: str | os.PathLike[str], write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it into place.

    The temporary file is flushed to disk and given the permissions the destination has (or
    the umask's default) before the rename. On any error it is removed and whatever was at
    ``path`` is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        write(tmp_path)
        with open(tmp_path, "rb+") as fh:
            os.fsync(fh.fileno())
        if path.exists():
            mode = path.stat().st_mode & 0o777
        else:
            umask = os.umask(0)
            os.umask(umask)
            mode = 0o666 & ~umask
        os.chmod(tmp_path, mode)
        os.replace(tmp_path, path)
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise
    return path


def write_json(path: str | os.PathLike[str], doc: dict) -> Path:
    """Write ``doc`` as indented JSON to ``path`` through :func:`atomic_write` (what every
    ``-o`` of the command line writes); returns ``path``. Raises TypeError for a value JSON
    cannot hold, before anything is written."""
    text = json.dumps(doc, indent=2)
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def stamped(progress: Callable[[str], None] | None, t_start: float) -> Callable[[str], None]:
    """A progress callback that prefixes each message with the seconds since ``t_start``
    (``time.perf_counter()``); a no-op when ``progress`` is None."""

    def say(msg: str) -> None:
        if progress is not None:
            progress(f"[{time.perf_counter() - t_start:5.0f} s] {msg}")

    return say
