"""The same seed gives the same numbers on the same kind of CPU, and says which that was.

XLA compiles for the CPU it finds: with a wider instruction set a vectorised transcendental or
a fused multiply–add rounds differently from the same code compiled for a narrower one. Rattle
is chaotic, so that last-bit difference grows into another realisation of the motion within
tens of milliseconds of simulated time, and a seeded synthetic recording, fit or diagnosis
comes out differently under different instruction sets (``benchmarks/isa_cost.py`` shows the
effect and its cost).

:func:`rattlefit.configure` therefore caps XLA's CPU instruction set at :data:`DEFAULT_CPU_ISA`
(AVX2, with FMA: every x86-64 server CPU since about 2015 has it) by adding
``--xla_cpu_max_isa`` to ``XLA_FLAGS``. It must do so before JAX starts its CPU backend; a
cap the user already set in ``XLA_FLAGS`` is kept. ``RATTLEFIT_CPU_ISA`` chooses another cap,
or ``native`` for none. On other architectures (aarch64) and on GPUs nothing is changed.

numpy's own vectorised kernels (its ``exp``, ``log``, ``sin`` and the like, which the
encoders, drives and features use) choose an instruction set once, when numpy is imported, and
round differently with AVX-512 too. :func:`cap_numpy_simd` keeps them below AVX-512 through
``NPY_DISABLE_CPU_FEATURES``, which numpy reads at import: the command line does so before it
imports numpy, and :func:`rattlefit.configure` does so for the processes a script starts
(campaign workers, notebook kernels), since the script's own numpy is usually imported by then.

The cap is not the whole story: the CPU model matters too, because LLVM tunes its instruction
selection (which multiply–adds it fuses, how it orders a vectorised sum) for the CPU it finds,
so the same code, JAX version and cap can give another realisation on another CPU model.
Results are therefore reproducible for a given seed, JAX version, instruction-set cap **and
CPU model** (the device count does not matter), not across machines in general;
:func:`platform_info` reports them (every fit's JSON carries it), and a seeded statistical
test must hold with a margin over realisations, not at one.
"""

from __future__ import annotations

import os
import platform
import re
import warnings

#: The instruction-set cap rattlefit applies to XLA on x86-64 unless told otherwise.
DEFAULT_CPU_ISA = "AVX2"
#: The environment variable that overrides it ("native": no cap).
ISA_ENV = "RATTLEFIT_CPU_ISA"

#: The environment variable numpy reads, once at import, for the instruction-set extensions
#: its kernels must leave unused.
NUMPY_FEATURES_ENV = "NPY_DISABLE_CPU_FEATURES"
#: What lies above AVX2 in numpy's names: its 2.x level and its 1.x features (numpy ignores a
#: name the CPU lacks or it does not know).
NUMPY_ABOVE_AVX2 = (
    "X86_V4",
    "AVX512F",
    "AVX512CD",
    "AVX512_KNL",
    "AVX512_KNM",
    "AVX512_SKX",
    "AVX512_CLX",
    "AVX512_CNL",
    "AVX512_ICL",
    "AVX512_SPR",
)

_FLAG = re.compile(r"--xla_cpu_max_isa=(\S+)")
_X86 = ("x86_64", "amd64", "i386", "i686")


def backend_started() -> bool:
    """Whether JAX has started its backends (after which XLA flags and the device count are
    fixed)."""
    try:
        from jax._src import xla_bridge

        return bool(xla_bridge.backends_are_initialized())
    except (ImportError, AttributeError):  # pragma: no cover - a JAX without the helper
        return False


def requested_cap(isa: str | None = None) -> str:
    """The instruction-set cap asked for: a cap already in ``XLA_FLAGS``, else ``isa``, else
    ``$RATTLEFIT_CPU_ISA``, else :data:`DEFAULT_CPU_ISA`; ``"native"`` (no cap) when that says
    so or the CPU is not x86-64."""
    already = _FLAG.search(os.environ.get("XLA_FLAGS", ""))
    isa = already.group(1) if already else isa or os.environ.get(ISA_ENV) or DEFAULT_CPU_ISA
    if isa.lower() == "native" or platform.machine().lower() not in _X86:
        return "native"
    return isa


def pin_cpu_isa(isa: str | None = None) -> str:
    """Cap XLA's CPU instruction set so that results do not depend on which instruction-set
    extensions the CPU offers beyond the cap.

    ``isa`` defaults to ``$RATTLEFIT_CPU_ISA``, else :data:`DEFAULT_CPU_ISA`; ``"native"``
    leaves XLA alone. A cap already in ``XLA_FLAGS`` wins. Returns the cap in effect
    ("native" for none). If JAX's backend has already started, the flag can no longer take
    effect: a warning says so and nothing is changed.
    """
    flags = os.environ.get("XLA_FLAGS", "")
    isa = requested_cap(isa)
    if _FLAG.search(flags) or isa == "native":
        return isa
    if backend_started():
        warnings.warn(
            "rattlefit: JAX started before rattlefit.configure() was called, so XLA's CPU "
            f"instruction set is not capped at {isa}; seeded results may differ between "
            "machines. Call rattlefit.configure() before running any JAX computation.",
            RuntimeWarning,
            stacklevel=2,
        )
        return "native"
    os.environ["XLA_FLAGS"] = f"{flags} --xla_cpu_max_isa={isa}".strip()
    return isa


def cap_numpy_simd(isa: str | None = None) -> None:
    """Keep numpy's vectorised kernels below AVX-512 wherever XLA's cap is below it, by
    naming :data:`NUMPY_ABOVE_AVX2` in ``$NPY_DISABLE_CPU_FEATURES``.

    numpy reads that variable once, when it is first imported: the cap holds in this process
    if numpy is imported after the call, and in every process started after it. ``isa`` is
    the XLA cap as :func:`requested_cap` resolves it (a cap in ``XLA_FLAGS`` wins); an
    AVX-512 or ``"native"`` cap, a CPU that is not x86-64, or a value the user has already set
    leaves the variable alone. :func:`numpy_simd` says what numpy uses."""
    cap = requested_cap(isa).upper()
    if cap != "NATIVE" and "AVX512" not in cap and NUMPY_FEATURES_ENV not in os.environ:
        os.environ[NUMPY_FEATURES_ENV] = " ".join(NUMPY_ABOVE_AVX2)


def numpy_simd() -> str:
    """The instruction-set extensions numpy's kernels use in this process, beyond its
    baseline, as numpy names them (e.g. "X86_V3", or "X86_V3 X86_V4 AVX512_ICL" with
    AVX-512); "baseline" for none, "unknown" for a numpy that does not say."""
    try:
        from numpy._core import _multiarray_umath as umath
    except ImportError:  # pragma: no cover - numpy 1.x
        from numpy.core import _multiarray_umath as umath
    try:
        found, dispatch = umath.__cpu_features__, umath.__cpu_dispatch__
    except AttributeError:  # pragma: no cover - a numpy without the registry
        return "unknown"
    return " ".join(f for f in dispatch if found.get(f)) or "baseline"


def cpu_isa() -> str:
    """The instruction-set cap XLA runs under ("native" for none)."""
    found = _FLAG.search(os.environ.get("XLA_FLAGS", ""))
    return found.group(1) if found and platform.machine().lower() in _X86 else "native"


def cpu_model(cpuinfo: str | None = None) -> str:
    """The CPU's name, vendor, family and model, as ``"<model name> (<vendor_id> family <n>
    model <n>)"``: a seeded result depends on it (the module's docstring). From
    ``/proc/cpuinfo`` (or the text ``cpuinfo``) where there is one, else what
    :func:`platform.processor` says ("" if nothing)."""
    if cpuinfo is None:
        try:
            with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
                cpuinfo = f.read()
        except OSError:
            return platform.processor()
    fields: dict[str, str] = {}
    for line in cpuinfo.splitlines():  # the first processor's values; "Hardware" (some ARM
        key, _, value = line.partition(":")  # kernels) comes after every processor's block
        if value.strip():
            fields.setdefault(key.strip(), value.strip())
    name = fields.get("model name") or fields.get("Hardware") or platform.processor()
    ids = [fields[k] for k in ("vendor_id",) if k in fields]
    ids += [f"{k.split()[-1]} {fields[k]}" for k in ("cpu family", "model") if k in fields]
    return f"{name} ({' '.join(ids)})" if ids else name


def platform_info() -> dict:
    """What a seeded result depends on besides its inputs: rattlefit's and JAX's versions,
    the backend, the device count, the machine architecture, XLA's CPU instruction-set cap,
    the extensions numpy's kernels use (:func:`numpy_simd`) and the CPU model. Every JSON
    output records it under ``platform``."""
    import jax

    from .version import __version__

    return {
        "rattlefit": __version__,
        "jax": jax.__version__,
        "backend": jax.default_backend(),
        "devices": len(jax.local_devices()),
        "machine": platform.machine(),
        "cpu_isa": cpu_isa(),
        "numpy_simd": numpy_simd(),
        "cpu": cpu_model(),
    }
