"""Exceptions raised by rattlefit.

Every error a user can cause derives from :class:`RattlefitError`, so that the command line
can turn it into one clean message and a non-zero exit instead of a traceback.
"""

from __future__ import annotations

import os


class RattlefitError(Exception):
    """Base class of every error rattlefit raises on bad input or a failed computation."""


class RecordingError(RattlefitError):
    """A recording file is unreadable or breaks the recording-format contract.

    The message always names the file, the field (an HDF5 path such as
    ``/gear_pair@teeth_driving`` or ``/encoders/primary``) and the problem.
    """

    def __init__(self, file: str | os.PathLike[str], field: str, problem: str):
        self.file = os.fspath(file)
        self.field = field
        self.problem = problem
        super().__init__(f"{self.file}: {field}: {problem}")


class ParameterError(RattlefitError, ValueError):
    """A model parameter is outside its physical range."""


class SolverError(RattlefitError):
    """The ODE solver failed (step-size collapse or too many steps)."""
