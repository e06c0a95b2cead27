"""What a diagnosis returns: each effect's outcome, the model-free findings, the verdict."""

from __future__ import annotations

import dataclasses
import enum

import numpy as np
from scipy import stats

from ..documents import DIAGNOSIS
from ..inference.result import FitResult
from .cycle_gap import CycleGap
from .evidence import Finding
from .outcome import EffectOutcome
from .policy import MISSED_Z, REFIT_WARN_RATIO, SIGNIFICANCE, Skipped, misses
from .verdict import Evidence, Verdict, decide


@dataclasses.dataclass(frozen=True)
class Diagnosis:
    """What :func:`diagnose` returns: the gap and the effects, best first."""

    baseline: FitResult
    residuals: np.ndarray  # (R, B) standardised residuals of the identification
    band_centers: np.ndarray
    band_edges: np.ndarray
    outcomes: list[EffectOutcome]
    seed: int
    wall_time: float
    refit_costs: tuple[float, float]  # cost at the identification, after the re-fit
    warnings: tuple[Caveat, ...] = ()
    #: the model-free tests of every recording (:func:`~rattlefit.diagnosis.evidence.findings`)
    findings: tuple[Finding, ...] = ()
    #: the family-wise level of the diagnosis (:attr:`DiagnoseOptions.significance`)
    significance: float = SIGNIFICANCE
    #: χ² of the model without effects after the re-fit, on the fresh realisations of the
    #: effects' comparison (NaN: not measured; the identification's χ² is used instead)
    chi2_without: float = float("nan")
    #: p of :attr:`chi2_without` under the model without effects' simulated null
    #: (:func:`~rattlefit.diagnosis.trial.misfit_p`; NaN: the χ² tail on the dof instead)
    gap_p: float = float("nan")
    #: effects not fitted to the band spectrum, and why
    skipped: dict[str, Skipped] = dataclasses.field(default_factory=dict)
    #: what a seeded result depends on (:func:`~rattlefit.reproducibility.platform_info`),
    #: captured when the diagnosis ran
    platform: dict = dataclasses.field(default_factory=dict, compare=False)
    #: the drive-cycle statistics against the model without effects
    #: (:func:`~rattlefit.diagnosis.cycle.cycle_gap`); None: not compared
    drive_cycle: CycleGap | None = None
    #: what the diagnosis concludes (:func:`~rattlefit.diagnosis.verdict.decide` of the
    #: outcomes against :attr:`evidence`), decided once at construction
    verdict: Verdict = dataclasses.field(init=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "verdict", decide(self.outcomes, self.evidence))

    @property
    def cycle_missed(self) -> bool:
        """The drive-cycle statistics miss somewhere beyond their family-wise threshold."""
        return self.drive_cycle is not None and self.drive_cycle.significant

    @property
    def missed_bands(self) -> list[dict]:
        """Bands whose standardised residual exceeds :data:`~.policy.MISSED_Z`: recording index,
        band edges (Hz) and residual (positive: the recording has more power)."""
        out = []
        for k, row in enumerate(np.asarray(self.residuals)):
            for b in np.flatnonzero(np.abs(row) > MISSED_Z):
                lo, hi = self.band_edges[b], self.band_edges[b + 1]
                out.append({"recording": k, "band_hz": [float(lo), float(hi)], "z": float(row[b])})
        return out

    @property
    def gap_chi2(self) -> tuple[float, int, float]:
        """χ², dof and p of the model without extra effects: after the re-fit, on the fresh
        realisations every effect is judged on, p under its simulated null (:attr:`gap_p`;
        the χ² tail where that was not simulated); the identification's own when not
        measured."""
        dof = self.baseline.statistics.dof
        if np.isfinite(self.chi2_without):
            p = self.gap_p if np.isfinite(self.gap_p) else stats.chi2.sf(self.chi2_without, dof)
            return self.chi2_without, dof, float(p)
        return self.baseline.statistics.chi2, dof, self.baseline.statistics.p_value

    @property
    def band_gap(self) -> bool:
        """The model without extra effects misses the band spectrum: its χ² (:attr:`gap_chi2`)
        has p below the significance."""
        return misses(self.gap_chi2[2], self.significance)

    @property
    def evidence(self) -> Evidence:
        """What every candidate is judged against
        (:class:`~rattlefit.diagnosis.verdict.Evidence`)."""
        return Evidence(
            findings=tuple(self.findings),
            band_gap=self.band_gap,
            cycle_missed=self.cycle_missed,
            significance=self.significance,
        )

    def to_json(self) -> dict:
        """The diagnosis as JSON (:data:`rattlefit.documents.DIAGNOSIS`; without the
        verdict's sentence: :func:`rattlefit.report.diagnosis_document` adds it)."""
        v = self.verdict
        return {
            **DIAGNOSIS.header(),
            "verdict": v.label,
            "verdict_kind": v.kind,
            "verdict_effects": list(v.effects),
            "band_gap": v.band_gap,
            "gap_chi2": {
                **dict(zip(("chi2", "dof", "p_value"), self.gap_chi2, strict=True)),
                "p_from": "simulated null" if np.isfinite(self.gap_p) else "chi2 tail",
            },
            "band_gap_explained": v.band_gap_explained,
            "nearest": None if v.nearest is None else v.nearest.name,
            "indistinguishable": [o.name for o in v.indistinguishable],
            "verdict_contradicted": list(v.contradicted),
            "significance": self.significance,
            "findings": [f.as_dict() for f in self.findings],
            "skipped": {k: str(v) for k, v in self.skipped.items()},
            "baseline": {
                "chi2": self.baseline.statistics.chi2,
                "dof": self.baseline.statistics.dof,
                "p_value": self.baseline.statistics.p_value,
                "converged": self.baseline.statistics.success,
                "likelihood": self.baseline.state.options.likelihood,
                "options": self.baseline.state.options.to_dict(),
                "parameters": {
                    k: p.as_dict() for k, p in self.baseline.estimates.parameters.items()
                },
            },
            "band_centers_hz": np.asarray(self.band_centers).tolist(),
            "residuals": np.asarray(self.residuals).tolist(),
            "missed_bands": self.missed_bands,
            "drive_cycle": None if self.drive_cycle is None else self.drive_cycle.as_dict(),
            "effects": [o.as_dict() for o in self.outcomes],
            "refit": {"cost_identified": self.refit_costs[0], "cost": self.refit_costs[1]},
            "warnings": [str(c) for c in self.warnings],
            "seed": self.seed,
            "platform": self.platform,  # seeded results depend on it
            "wall_time_s": self.wall_time,
            "recordings": self.baseline.provenance.recordings,
        }


class Caveat(enum.StrEnum):
    """Why a verdict against its identification may mislead (worded by
    :func:`rattlefit.report.wording.caveat_sentence`)."""

    #: the identification stopped at its step limit: the model without effects may fit better
    #: than it does there, and an effect may be credited with that
    UNFINISHED = "unfinished_identification"
    #: re-fitting a and T_b without effects lowered the identification's cost below
    #: :data:`~.policy.REFIT_WARN_RATIO` of it: the effects are judged against the re-fit
    FAR_FROM_BEST = "far_from_best_fit"


def baseline_caveats(
    converged: bool, cost_identified: float, cost_refit: float
) -> tuple[Caveat, ...]:
    """The :class:`Caveat` s of an identification that ``converged`` or not, whose cost the
    re-fit without effects took from ``cost_identified`` to ``cost_refit``."""
    out = []
    if not converged:
        out.append(Caveat.UNFINISHED)
    if cost_refit < REFIT_WARN_RATIO * cost_identified:
        out.append(Caveat.FAR_FROM_BEST)
    return tuple(out)
