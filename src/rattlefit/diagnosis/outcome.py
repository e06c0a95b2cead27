"""One effect tried on top of the identification, and the share of the gap it closes."""

from __future__ import annotations

import dataclasses

import numpy as np

from .policy import effects_of


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
    p_after : probability of a χ² at least ``chi2_with`` from the model with the effect at
        its fitted point, by that model's simulated null
        (:func:`~rattlefit.diagnosis.trial.misfit_p`; the χ² tail on the dof less the
        effect's fields where the null is not simulated): small when the effect leaves a
        significant misfit.
    moves : how the free parameters move once the effect is in: name → (without, with), SI.
    residuals : (R, B) standardised band residuals with the effect.
    failure : why the effect could not be judged (its simulation failed at the fitted
        point, so ``chi2_with`` is not finite); empty when it was judged. A failed effect is
        never supported.
    intervals : 95 % intervals (SI) of the effect's size (its first field), from a profile
        of the χ² over it (:mod:`rattlefit.diagnosis.size`): key → (lower, upper); computed
        for the effects a verdict names (whose ``values`` then hold the profile's estimate),
        empty otherwise.
    relevant : False when the size was profiled and its interval reaches below the effect's
        relevance floor, a share of its typical size
        (:func:`~rattlefit.diagnosis.size.relevance_floor`): the band spectrum cannot tell
        it from no effect, and it is not named. True until profiled.
    interval_caveat : why ``intervals`` are not a 95 % interval of the size, or empty when
        they are: a candidate that leaves a significant misfit (``p_after`` below the
        family-wise level) is a model known to miss, and its profile measures how precisely
        that model's best fit is located, not where the size lies (on a periodic, locked
        rattle the χ² over the size is rough: a size a tenth off the truth can fit better).

    Two effects fitted together have the name ``"<effect>+<effect>"``, their values keyed
    ``"<effect>.<field>"``, and:

    p_beyond : F-test p of their χ² against their better member's alone.
    beyond_single : ``p_beyond`` below the level and the drop above the Monte Carlo noise:
        the second effect removes a significant part of what the first leaves.
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
    p_after: float = 1.0
    moves: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    failure: str = ""
    intervals: dict[str, tuple[float, float]] = dataclasses.field(default_factory=dict)
    relevant: bool = True
    interval_caveat: str = ""
    p_beyond: float = float("nan")
    beyond_single: bool = False

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects in this outcome: one, or two fitted together."""
        return effects_of(self.name)

    def as_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["parameters"] = {
            k: {"value": v, "unit": self.units[k]} for k, v in d.pop("values").items()
        }
        d.pop("units")
        d["residuals"] = None if self.failure else np.asarray(self.residuals).tolist()
        d["intervals"] = {k: list(v) for k, v in self.intervals.items()}
        for k in ("chi2_with", "delta_chi2", "p_value", "noise_threshold", "p_after", "p_beyond"):
            d[k] = d[k] if np.isfinite(d[k]) else None  # JSON has no NaN; null: not judged
        d["moves"] = {k: {"without": a, "with": b} for k, (a, b) in self.moves.items()}
        return d


def gap_closed(chi2_without: float, chi2_with: float, dof: int) -> float:
    """Share of the excess misfit χ² − dof that the effect removes, in [0, 1]; 0 when there
    is no excess (the model without the effect already explains the data)."""
    excess = chi2_without - dof
    if excess <= 0:
        return 0.0
    return float(np.clip((chi2_without - chi2_with) / excess, 0.0, 1.0))
