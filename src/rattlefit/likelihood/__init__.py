"""The learned likelihood: the recordings' features given the parameters, learned from
simulations (:mod:`.design`, :mod:`.emulator`, :mod:`.model`, :mod:`.learn`)."""

from .emulator import EmulatorOptions, FeatureEmulator, fit_emulator
from .learn import Design, LearningOptions, RoundRecord, learn_likelihood
from .model import LearnedLikelihood

__all__ = [
    "Design",
    "EmulatorOptions",
    "FeatureEmulator",
    "LearnedLikelihood",
    "LearningOptions",
    "RoundRecord",
    "fit_emulator",
    "learn_likelihood",
]
