"""The drive-cycle statistics of the recordings against the model without effects: where in
the cycle the model misses (:mod:`rattlefit.diagnosis.cycle` computes it)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..features.folded import STATISTICS


@dataclasses.dataclass(frozen=True)
class CycleGap:
    """The drive-cycle statistics of the recordings against the model without effects.

    phases : (bins,) phase-bin centres, cycles from the drive speed's maximum.
    measured, model, sd : (R, 3, bins) the recordings' statistics, the ensemble mean and
        the spread of one recording's (:data:`~rattlefit.features.folded.STATISTICS`:
        position, upper flank's share, lower flank's share).
    threshold : the family-wise |z| threshold at the diagnosis' significance.
    p_value : Bonferroni p of the largest |z| (1 at most).
    """

    phases: np.ndarray
    measured: np.ndarray
    model: np.ndarray
    sd: np.ndarray
    threshold: float
    p_value: float

    @property
    def z(self) -> np.ndarray:
        """(R, 3, bins) standardised residuals ``(measured − model) / sd``."""
        return (self.measured - self.model) / self.sd

    @property
    def significant(self) -> bool:
        """Some statistic is beyond the family-wise threshold."""
        return bool(np.max(np.abs(self.z)) > self.threshold)

    def missed(self) -> list[dict]:
        """The statistics beyond :attr:`threshold`: recording index, statistic, phase
        (cycles) and z."""
        z = self.z
        return [
            {
                "recording": int(r),
                "statistic": STATISTICS[s],
                "phase": float(self.phases[b]),
                "z": float(z[r, s, b]),
            }
            for r, s, b in zip(*np.nonzero(np.abs(z) > self.threshold), strict=True)
        ]

    def phrase(self) -> str:
        """Where the misses are, e.g. ``upper_flank at phases 0.53–0.84 (less than
        modelled)``; empty when none."""
        parts = []
        for s, name in enumerate(STATISTICS):
            z = self.z[:, s]
            hit = np.abs(z) > self.threshold
            if not hit.any():
                continue
            phases = self.phases[np.nonzero(hit.any(axis=0))[0]]
            sign = "more" if np.sum(z[hit]) > 0 else "less"
            span = f"{phases.min():.2f}" + (
                f"–{phases.max():.2f}" if phases.max() > phases.min() else ""
            )
            parts.append(f"{name} at phase {span} ({sign} than modelled)")
        return "; ".join(parts)

    def as_dict(self) -> dict:
        return {
            "p_value": self.p_value,
            "threshold": self.threshold,
            "significant": self.significant,
            "phases": self.phases.tolist(),
            "statistics": list(STATISTICS),
            "measured": self.measured.tolist(),
            "model": self.model.tolist(),
            "sd": self.sd.tolist(),
            "missed": self.missed(),
        }
