"""rattlefit: identify the physics of idle gear rattle from encoder recordings.

The model is the one-dof gear-pair model of the seed paper (mesh stiffness in contact,
squeeze-film damping of the oil between approaching flanks, bearing drag torque). rattlefit
simulates it differentiably with JAX/diffrax and identifies the oil-film half-length ``a``, the
drag torque ``T_b`` and the effective viscosity from recordings.

Importing rattlefit changes nothing in JAX. Call :func:`configure` first: it enables JAX's
64-bit mode (the contact law spans nanometres to millimetres), caps XLA's CPU instruction set
(:mod:`rattlefit.reproducibility`) and gives JAX one device per CPU core.

The main API: :func:`read_recording`, :func:`identify` with :class:`FitOptions` (returning a
:class:`FitResult`), :func:`sample`, :func:`diagnose`, :func:`synthesize` and :func:`simulate`.
"""

from __future__ import annotations

import importlib

from .version import __version__ as __version__

#: Where each public name lives: imported on first use (PEP 562), so that importing
#: rattlefit (and starting the command line for --help) loads neither JAX nor SciPy.
_LAZY = {
    "use_compilation_cache": ".compile_cache",
    "Configuration": ".config",
    "configure": ".config",
    "DiagnoseOptions": ".diagnosis",
    "Diagnosis": ".diagnosis",
    "diagnose": ".diagnosis",
    "ParameterError": ".errors",
    "RattlefitError": ".errors",
    "RecordingError": ".errors",
    "SolverError": ".errors",
    "FitOptions": ".inference",
    "FitResult": ".inference",
    "FittedState": ".inference",
    "Posterior": ".inference",
    "SampleOptions": ".inference",
    "identify": ".inference",
    "sample": ".inference",
    "Recording": ".io.recording",
    "read_recording": ".io.recording",
    "write_recording": ".io.recording",
    "Drive": ".physics.drive",
    "GearGeometry": ".physics.geometry",
    "table2_pair": ".physics.geometry",
    "Effect": ".physics.model",
    "RattleModel": ".physics.model",
    "RattleParams": ".physics.model",
    "Smoothing": ".physics.model",
    "film_for_squeeze_momentum": ".physics.model",
    "squeeze_momentum": ".physics.model",
    "dynamic_viscosity": ".physics.oil",
    "platform_info": ".reproducibility",
    "use_cpu_cores": ".config",
    "Solution": ".simulation.solve",
    "simulate": ".simulation.solve",
    "simulate_batch": ".simulation.solve",
    "synthesize": ".simulation.synthetic",
}

__all__ = [
    "Configuration",
    "DiagnoseOptions",
    "Diagnosis",
    "Drive",
    "Effect",
    "FitOptions",
    "FitResult",
    "FittedState",
    "GearGeometry",
    "ParameterError",
    "Posterior",
    "RattleModel",
    "RattleParams",
    "RattlefitError",
    "Recording",
    "RecordingError",
    "SampleOptions",
    "Smoothing",
    "Solution",
    "SolverError",
    "configure",
    "diagnose",
    "dynamic_viscosity",
    "film_for_squeeze_momentum",
    "identify",
    "platform_info",
    "read_recording",
    "sample",
    "simulate",
    "simulate_batch",
    "squeeze_momentum",
    "synthesize",
    "table2_pair",
    "use_compilation_cache",
    "use_cpu_cores",
    "write_recording",
]


def __getattr__(name: str):
    """A public name (:data:`_LAZY`) or a submodule, imported on first use."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    try:
        return importlib.import_module(f".{name}", __name__)
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}.{name}":
            raise
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
