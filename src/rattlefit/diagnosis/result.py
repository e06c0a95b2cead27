"""What a diagnosis returns: each effect's outcome, the gap, and the verdict."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..inference.result import FitResult

#: A band counts as missed when its standardised residual exceeds this (in σ).
MISSED_Z = 3.0
#: diagnose warns when re-fitting a and T_b without effects lowers the identification's cost
#: below this share of it (the identification had not found the model's best fit).
REFIT_WARN_RATIO = 0.5


@dataclasses.dataclass(frozen=True)
class EffectOutcome:
    """One effect tried on top of the identification.

    values : the fitted fields (SI, see ``units``); at the lower end of a range the effect is
        absent.
    chi2_without, chi2_with : χ² of the data rows after re-fitting without and with it.
    delta_chi2 : their difference (positive: the effect explains part of the misfit).
    gap_closed : share of the excess misfit (χ² − dof) removed, in [0, 1] (0 when there is
        no excess).
    p_value : F-test of ``delta_chi2`` against the misfit that remains.
    noise_threshold : Monte Carlo noise of a χ² difference (95 % one-sided).
    supported : ``p_value`` < the significance over the number of effects tried, and
        ``delta_chi2`` > ``noise_threshold``.
    residuals : (R, B) standardised band residuals with the effect.
    """

    name: str
    values: dict[str, float]
    units: dict[str, str]
    chi2_without: float
    chi2_with: float
    delta_chi2: float
    gap_closed: float
    p_value: float
    noise_threshold: float
    supported: bool
    residuals: np.ndarray
    wall_time: float

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["parameters"] = {
            k: {"value": v, "unit": self.units[k]} for k, v in d.pop("values").items()
        }
        d.pop("units")
        d["residuals"] = np.asarray(self.residuals).tolist()
        return d


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
    warnings: tuple[str, ...] = ()
    #: what a seeded result depends on (:func:`~rattlefit.reproducibility.platform_info`),
    #: captured when the diagnosis ran
    platform: dict = dataclasses.field(default_factory=dict, compare=False)

    @property
    def missed_bands(self) -> list[dict]:
        """Bands whose standardised residual exceeds :data:`MISSED_Z`: recording index,
        band edges (Hz) and residual (positive: the recording has more power)."""
        out = []
        for k, row in enumerate(np.asarray(self.residuals)):
            for b in np.flatnonzero(np.abs(row) > MISSED_Z):
                lo, hi = self.band_edges[b], self.band_edges[b + 1]
                out.append({"recording": k, "band_hz": [float(lo), float(hi)], "z": float(row[b])})
        return out

    @property
    def verdict(self) -> EffectOutcome | None:
        """The supported effect that leaves the least misfit (lowest χ² with it), or None."""
        supported = [o for o in self.outcomes if o.supported]
        return supported[0] if supported else None

    def to_json(self) -> dict:
        v = self.verdict
        return {
            "verdict": None if v is None else v.name,
            "baseline": {
                "chi2": self.baseline.chi2,
                "dof": self.baseline.dof,
                "p_value": self.baseline.p_value,
                "converged": self.baseline.success,
                "parameters": {k: p.as_dict() for k, p in self.baseline.parameters.items()},
            },
            "band_centers_hz": np.asarray(self.band_centers).tolist(),
            "residuals": np.asarray(self.residuals).tolist(),
            "missed_bands": self.missed_bands,
            "effects": [o.as_dict() for o in self.outcomes],
            "refit": {"cost_identified": self.refit_costs[0], "cost": self.refit_costs[1]},
            "warnings": list(self.warnings),
            "seed": self.seed,
            "platform": self.platform,  # seeded results depend on it
            "wall_time_s": self.wall_time,
            "recordings": self.baseline.recordings,
        }


def baseline_warnings(converged: bool, cost_identified: float, cost_refit: float) -> list[str]:
    """Why a verdict against this identification may mislead: it stopped at its step limit,
    or re-fitting a and T_b without effects lowered its cost below :data:`REFIT_WARN_RATIO`
    of it. An effect tried against an unfinished identification can be credited with what
    finishing the fit of the model without effects would gain."""
    out = []
    if not converged:
        out.append(
            "the identification stopped at its step limit, so the model without effects may "
            "fit better than it does here and an effect may be credited with that; a full "
            "identification (without --quick-fit) is the safer start."
        )
    if cost_refit < REFIT_WARN_RATIO * cost_identified:
        out.append(
            f"the identification was far from the model's best fit: re-fitting a and T_b "
            f"without effects lowered its cost from {cost_identified:.1f} to {cost_refit:.1f}"
            "; the effects are judged against the re-fit."
        )
    return out


def gap_closed(chi2_without: float, chi2_with: float, dof: int) -> float:
    """Share of the excess misfit χ² − dof that the effect removes, in [0, 1]; 0 when there
    is no excess (the model without the effect already explains the data)."""
    excess = chi2_without - dof
    if excess <= 0:
        return 0.0
    return float(np.clip((chi2_without - chi2_with) / excess, 0.0, 1.0))
