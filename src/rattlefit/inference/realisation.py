"""One realisation of the fitted model per recording, to draw beside the measurement."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..io.recording import Recording
from ..rig import setup
from ..simulation.solve import absolute_tolerances, simulate
from .result import FitResult


def fitted_realisations(result: FitResult, recordings: Sequence[Recording]) -> list[np.ndarray]:
    """Δθ* (rad, one array of each recording's length) of one simulation at ``result``'s
    fitted parameters on each recording's rig, with the fit's tolerances. Rattle is chaotic:
    compare its character with the measurement's, not its phase."""
    lubrications = [r.operating.lubrication for r in recordings]
    out = []
    for k, rec in enumerate(recordings):
        rig = setup(rec, drive=result.options.drive)
        sol = simulate(
            rig.model,
            result.rattle_params(k),
            rig.drive,
            duration=rec.duration,
            sample_rate=rec.sample_rate_hz,
            rtol=result.options.rtol,
            atol=absolute_tolerances(result.options.rtol, lubrications),
        )
        out.append(np.asarray(sol.relative_motion))
    return out
