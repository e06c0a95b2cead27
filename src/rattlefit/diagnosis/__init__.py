"""Diagnosis: where the model misses the data, which unmodelled effect explains the gap,
and how far it shrinks once that effect is in (:func:`diagnose`)."""

from .diagnose import DiagnoseOptions, diagnose
from .result import MISSED_Z, Diagnosis, EffectOutcome

__all__ = ["MISSED_Z", "DiagnoseOptions", "Diagnosis", "EffectOutcome", "diagnose"]
