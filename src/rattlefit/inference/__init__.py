"""Inference: from recordings to parameters with honest uncertainty.

What is fitted (parameters, options, the problem and its feature map) is
:mod:`rattlefit.problem`; this package searches and measures uncertainty:

- :mod:`.noise`: the noise model (a synthetic likelihood from the simulated ensemble);
- :mod:`.starts` and :mod:`.least_squares`: the search (Levenberg–Marquardt from many starts);
- :mod:`.laplace`: the covariance at the optimum; :mod:`.profile`: the profile intervals;
- :mod:`.result`: estimates and :class:`FitResult`; :mod:`.identify`: the orchestration;
- :mod:`.posterior`: the Bayesian posterior by emcee, with a resumable HDF5 chain.
"""

from ..likelihood.noise import NoiseModel
from ..problem.options import FitOptions
from .identify import identify
from .posterior import Posterior, SampleOptions, sample
from .result import (
    Estimates,
    FitResult,
    FittedState,
    ParameterEstimate,
    Provenance,
    Spectra,
    Statistics,
)

__all__ = [
    "Estimates",
    "FitOptions",
    "FitResult",
    "FittedState",
    "NoiseModel",
    "ParameterEstimate",
    "Posterior",
    "Provenance",
    "SampleOptions",
    "Spectra",
    "Statistics",
    "identify",
    "sample",
]
