"""Inference: from recordings to parameters with honest uncertainty.

- :mod:`.parameters`: the fitted parameters, their coordinates and priors;
- :mod:`.options`: :class:`FitOptions`;
- :mod:`.problem`: the problem and its seeded realisations; :mod:`.forward`: the feature map;
- :mod:`.noise`: the noise model (a synthetic likelihood from the simulated ensemble);
- :mod:`.starts` and :mod:`.least_squares`: the search (Levenberg–Marquardt from many starts);
- :mod:`.laplace`: the covariance at the optimum; :mod:`.profile`: the profile intervals;
- :mod:`.result`: estimates and :class:`FitResult`; :mod:`.identify`: the orchestration;
- :mod:`.posterior`: the Bayesian posterior by emcee, with a resumable HDF5 chain.
"""

from .identify import identify
from .noise import NoiseModel
from .options import FitOptions
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
