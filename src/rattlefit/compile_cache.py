"""A persistent cache of compiled programs: the second run of a command skips compilation.

Every identification compiles the simulator, its batched evaluation and the
Levenberg–Marquardt loop before it simulates anything; in a fresh process that is a fixed cost
of each ``rattlefit identify``, several seconds, that a cached program skips. (The fit's
host-side arithmetic runs in numpy, :func:`rattlefit.util.array_namespace`, so it compiles
nothing.)

JAX can keep compiled programs on disk and reuse them in a later process whose code, JAX
version, device count and XLA flags (the instruction-set cap of
:mod:`rattlefit.reproducibility` included) are the same. A reused program is the program
compiled before, so results do not change (the same features to the last bit).

The command line turns the cache on (:func:`use_compilation_cache`); in Python call it before
the first fit. ``RATTLEFIT_CACHE_DIR`` chooses the directory, ``off`` (or empty) disables it;
the default is ``$XDG_CACHE_HOME/rattlefit/jax`` (``~/.cache/rattlefit/jax``). The directory
may be deleted at any time.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import jax

#: The environment variable naming the cache directory ("off" or empty: no cache).
CACHE_ENV = "RATTLEFIT_CACHE_DIR"
#: Programs that took less than this to compile (s) are not kept. Zero: many small programs
#: (about 0.05 s each) add up to more than the few large ones, and keeping them all costs
#: only a few megabytes of disk.
MIN_COMPILE_TIME = 0.0


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/rattlefit/jax``, or ``~/.cache/rattlefit/jax``."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "rattlefit" / "jax"


def use_compilation_cache(path: str | os.PathLike | None = None) -> Path | None:
    """Keep JAX's compiled programs in ``path`` (default: ``$RATTLEFIT_CACHE_DIR``, else
    :func:`default_cache_dir`) and reuse them in later processes. Returns the directory, or
    None when the cache is off (``RATTLEFIT_CACHE_DIR=off``) or the directory cannot be
    created (a warning says why: the run goes on, only without the cache).
    """
    if path is None:
        env = os.environ.get(CACHE_ENV)
        if env is not None and env.strip().lower() in ("", "off", "0", "none"):
            return None
        path = env or default_cache_dir()
    path = Path(path).expanduser()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        warnings.warn(
            f"rattlefit: cannot use {path} for the compilation cache ({exc}); every run "
            f"compiles afresh. Set {CACHE_ENV} to a writable directory, or to 'off'.",
            RuntimeWarning,
            stacklevel=2,
        )
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_TIME)
    return path
