"""What is fitted and how a parameter point is simulated: the layer below every likelihood.

- :mod:`.parameters`: the fitted parameters, their coordinates, priors and roles;
- :mod:`.space`: :class:`ParameterSpace`, what the fit's vector means and each recording's
  model parameters;
- :mod:`.options`: :class:`FitOptions`;
- :mod:`.problem`: :class:`Problem`, the recordings with their seeded realisations;
- :mod:`.forward`: the batched feature map (the simulations of a fit, spread over devices).

:mod:`rattlefit.likelihood` (how features are scored) and :mod:`rattlefit.inference` (the
search, the intervals and the posterior) both build on it; it imports neither.
"""

from .options import FitOptions
from .parameters import ParameterSpec, default_specs, parameter_prior, parse_prior
from .problem import Problem, build_problem, problem_from
from .space import ParameterSpace

__all__ = [
    "FitOptions",
    "ParameterSpace",
    "ParameterSpec",
    "Problem",
    "build_problem",
    "default_specs",
    "parameter_prior",
    "parse_prior",
    "problem_from",
]
