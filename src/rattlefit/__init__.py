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

from .compile_cache import use_compilation_cache
from .config import Configuration, configure
from .diagnosis import DiagnoseOptions, Diagnosis, diagnose
from .errors import ParameterError, RattlefitError, RecordingError, SolverError
from .inference import (
    FitOptions,
    FitResult,
    FittedState,
    Posterior,
    SampleOptions,
    identify,
    sample,
)
from .io.recording import Recording, read_recording, write_recording
from .physics.drive import Drive
from .physics.geometry import GearGeometry, table2_pair
from .physics.model import (
    Effect,
    RattleModel,
    RattleParams,
    Smoothing,
    film_for_squeeze_momentum,
    squeeze_momentum,
)
from .physics.oil import dynamic_viscosity
from .reproducibility import platform_info
from .simulation.parallel import use_cpu_cores
from .simulation.solve import Solution, simulate, simulate_batch
from .simulation.synthetic import synthesize
from .version import __version__ as __version__

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
