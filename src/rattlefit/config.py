"""Set JAX up for rattlefit: one explicit call, before anything computes.

Importing rattlefit changes nothing in JAX or the environment. :func:`configure` does what
rattlefit's numbers need, and must run before the first JAX computation of the process:

- **64-bit mode.** The contact law spans displacements from nanometres (the static deflection)
  to millimetres (the backlash), which single precision cannot hold. Every simulation refuses
  to run without it (:func:`require_x64`).
- **The instruction-set cap** of :mod:`rattlefit.reproducibility`, so that a seeded result does
  not depend on which vector extensions the CPU has.
- **One JAX device per CPU core** (:func:`rattlefit.use_cpu_cores`), so that batches of
  simulations use every core.
- optionally, **the compilation cache** on disk (:func:`rattlefit.use_compilation_cache`).

The command line calls it first thing. In Python::

    import rattlefit as rf
    rf.configure()
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path

import jax

from .compile_cache import use_compilation_cache
from .errors import RattlefitError
from .reproducibility import backend_started, cap_numpy_simd, cpu_isa, pin_cpu_isa


@dataclasses.dataclass(frozen=True)
class Configuration:
    """What :func:`configure` set: the JAX device count, the CPU instruction-set cap in effect
    ("native" for none) and the compilation cache's directory (None: no cache)."""

    devices: int
    cpu_isa: str
    compilation_cache: Path | None


def use_cpu_cores(n: int | None = None) -> int:
    """Expose ``n`` CPU devices to JAX (default: one per available core).

    Call before any JAX computation (JAX fixes its devices when it first runs something);
    this call itself does not start JAX. Returns ``n``, or, if JAX had already started (a
    warning says so), the CPU device count it has. Has no effect on the accelerators JAX uses
    when it finds a GPU.
    """
    if n is None:
        try:
            n = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not on Linux
            n = os.cpu_count() or 1
    n = max(int(n), 1)
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except RuntimeError:
        warnings.warn(
            "rattlefit.use_cpu_cores: JAX has already started, so its CPU device count is "
            "fixed; call use_cpu_cores() before any JAX computation to use every core",
            RuntimeWarning,
            stacklevel=2,
        )
        return len(jax.devices("cpu"))
    return n


def configure(
    *,
    cpu_cores: int | None = None,
    cpu_isa_cap: str | None = None,
    compilation_cache: bool | str | os.PathLike = False,
) -> Configuration:
    """Enable JAX's 64-bit mode, cap XLA's CPU instruction set (and numpy's, in the processes
    started after the call: :func:`~rattlefit.reproducibility.cap_numpy_simd`) and give JAX one
    CPU device per core (``cpu_cores`` of them if given).

    ``cpu_isa_cap`` overrides ``$RATTLEFIT_CPU_ISA`` and the default cap (AVX2; "native": no
    cap). ``compilation_cache`` True keeps compiled programs in the default directory
    (:func:`rattlefit.use_compilation_cache`), a path keeps them there. Call it before any JAX
    computation; when JAX has already started, the device count and the cap cannot change
    any more, and calling again with the settings already in effect changes nothing and warns
    of nothing. Returns the :class:`Configuration` in effect.
    """
    jax.config.update("jax_enable_x64", True)
    cap_numpy_simd(cpu_isa_cap)  # for the processes started from here on (numpy is loaded)
    if backend_started():
        devices = len(jax.devices("cpu"))
        if cpu_cores is not None and int(cpu_cores) != devices:
            use_cpu_cores(cpu_cores)  # warns that the count is fixed
        isa = cpu_isa() if cpu_isa_cap is None else pin_cpu_isa(cpu_isa_cap)
    else:
        isa = pin_cpu_isa(cpu_isa_cap)
        devices = use_cpu_cores(cpu_cores)
    cache = None
    if compilation_cache is True:
        cache = use_compilation_cache()
    elif compilation_cache:
        cache = use_compilation_cache(compilation_cache)
    return Configuration(devices=devices, cpu_isa=isa, compilation_cache=cache)


def require_x64(what: str) -> None:
    """Raise :class:`~rattlefit.RattlefitError` naming ``what`` when JAX's 64-bit mode is off
    (that is, :func:`configure` was not called)."""
    if not jax.config.read("jax_enable_x64"):
        raise RattlefitError(
            f"{what} needs JAX's 64-bit mode: call rattlefit.configure() before any "
            "computation (or jax.config.update('jax_enable_x64', True))"
        )


def quietly_configure(**options) -> Configuration:
    """:func:`configure`, without the warnings about JAX having started already (for the
    command line, which may run inside a process that has used JAX, such as a test)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return configure(**options)
