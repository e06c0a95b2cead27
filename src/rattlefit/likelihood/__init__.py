"""The learned likelihood: the recordings' features given the parameters, learned from
simulations (:mod:`.design`, :mod:`.density`, :mod:`.model`, :mod:`.learn`)."""

from .density import DensityOptions, FeatureDensity, fit_density
from .learn import Design, LearningOptions, RoundRecord, learn_likelihood
from .model import LearnedLikelihood

__all__ = [
    "DensityOptions",
    "Design",
    "FeatureDensity",
    "LearnedLikelihood",
    "LearningOptions",
    "RoundRecord",
    "fit_density",
    "learn_likelihood",
]
