"""Diagnosis: where the model misses the data, which unmodelled effect explains the gap,
and how far it shrinks once that effect is in (:func:`diagnose`)."""

from .diagnose import DiagnoseOptions, diagnose
from .outcome import EffectOutcome
from .policy import MISSED_Z
from .result import Diagnosis
from .verdict import Evidence, Verdict, decide

__all__ = [
    "MISSED_Z",
    "DiagnoseOptions",
    "Diagnosis",
    "EffectOutcome",
    "Evidence",
    "Verdict",
    "decide",
    "diagnose",
]
