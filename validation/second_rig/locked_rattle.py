"""The second rig's clean recording whose rattle locks to the primary's revolution.

Case 33 of the validation set drawn with seed 20261210 (pair II, boundary lubrication, clean),
its drive fluctuating once per revolution of the primary: the impacts repeat with the
primary's angle. ``tests/test_null.py`` reads it from ``tests/data/second_rig/`` (simulating
it takes most of a minute); ``python -m validation.second_rig.locked_rattle`` writes it again,
with the rig's values in rattlefit's terms (``a_mm``, ``drag_torque_Nm``,
``viscosity_Pa_s``: the numbers of its truth entry) as its truth.
"""

from __future__ import annotations

import math
from pathlib import Path

from validation.second_rig import validation_set

SEED = 20261210
CASE = 33
PATH = Path(__file__).resolve().parents[2] / "tests" / "data" / "second_rig" / "locked_rattle.h5"


def locked_case():
    """The drawn case, at a drive frequency of one per revolution of the primary."""
    case = next(c for c in validation_set.plan(SEED) if c.number == CASE)
    drawn = validation_set.draw(case)
    at = round(validation_set.MEAN_SPEED / (2 * math.pi), 3)
    return validation_set.at_drive_frequency(drawn, at)


def main(path: Path = PATH) -> Path:
    import rattlefit as rf

    rf.configure()
    locked = locked_case()
    (rec,), _ = validation_set.simulate_cases([locked])
    path.parent.mkdir(parents=True, exist_ok=True)
    truth = {k: v for k, v in validation_set.truth_of(locked).items() if isinstance(v, int | float)}
    return rf.write_recording(rec, path, extra_attrs=truth)


if __name__ == "__main__":
    print(main())
