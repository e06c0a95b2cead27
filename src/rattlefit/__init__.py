"""rattlefit: identify the physics of idle gear rattle from encoder recordings.

The model is the one-dof gear-pair model of the seed paper (mesh stiffness in contact,
squeeze-film damping of the oil between approaching flanks, bearing drag torque). rattlefit
simulates it differentiably with JAX/diffrax and identifies the oil-film half-length ``a``, the
drag torque ``T_b`` and the effective viscosity from recordings.

Importing rattlefit enables JAX's 64-bit mode: the contact law spans displacements from
nanometres (static deflection) to millimetres (backlash) and needs double precision. It also
caps XLA's CPU instruction set (AVX2 on x86-64), so that a seeded result depends on the CPU
model but not on its instruction set: see :mod:`rattlefit.reproducibility`.

The main API: :func:`read_recording`, :func:`identify` with :class:`FitOptions` (returning a
:class:`FitResult`), :func:`sample`, :func:`diagnose`, :func:`synthesize` and :func:`simulate`.
"""

from .reproducibility import pin_cpu_isa

pin_cpu_isa()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

from .compile_cache import use_compilation_cache  # noqa: E402
from .diagnosis import DiagnoseOptions, Diagnosis, diagnose  # noqa: E402
from .errors import ParameterError, RattlefitError, RecordingError, SolverError  # noqa: E402
from .inference import (  # noqa: E402
    FitOptions,
    FitResult,
    Posterior,
    SampleOptions,
    identify,
    sample,
)
from .io.recording import Recording, read_recording, write_recording  # noqa: E402
from .physics.drive import Drive  # noqa: E402
from .physics.geometry import GearGeometry, table2_pair  # noqa: E402
from .physics.model import (  # noqa: E402
    Effect,
    RattleModel,
    RattleParams,
    Smoothing,
    film_for_squeeze_momentum,
    squeeze_momentum,
)
from .physics.oil import dynamic_viscosity  # noqa: E402
from .reproducibility import platform_info  # noqa: E402
from .simulation.parallel import use_cpu_cores  # noqa: E402
from .simulation.solve import Solution, simulate, simulate_batch  # noqa: E402
from .simulation.synthetic import synthesize  # noqa: E402
from .version import __version__ as __version__  # noqa: E402

__all__ = [
    "DiagnoseOptions",
    "Diagnosis",
    "Drive",
    "Effect",
    "FitOptions",
    "FitResult",
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
