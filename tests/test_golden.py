"""The golden pin: restructuring the code moves no result (see ``tests/golden_pin.py``).

Within rounding, on every platform: the stages that are not chaotic (features, 20 ms of
motion, a closed form) against ``tests/pins/stable.json``. To the last bit, where the platform
matches a pin in ``tests/pins/<platform>.json``: three seeded pipelines, whose chaos grows a
last-bit difference of another CPU or JAX version into another realisation, so another
platform has nothing to compare them with.
"""

from __future__ import annotations

import difflib
import json

import numpy as np
import pytest

import golden_pin


def test_stable_outputs_match_the_pin_within_rounding():
    pin = json.loads(golden_pin.STABLE.read_text())
    now = golden_pin.compute_stable()
    assert sorted(now) == sorted(pin["outputs"])
    moved = []
    for name, want in pin["outputs"].items():
        rtol, atol = golden_pin.TOLERANCES[name.split("/")[0]]
        got, want = np.asarray(now[name]), np.asarray(want)
        if got.shape != want.shape or not np.allclose(got, want, rtol=rtol, atol=atol):
            worst = np.max(np.abs(got - want)) if got.shape == want.shape else got.shape
            moved.append(f"{name}: moved by up to {worst} (rtol {rtol}, atol {atol})")
    assert not moved, "\n".join(moved)


def test_the_stable_tolerances_catch_a_change_of_the_model():
    # a tolerance so loose that a real change passes would make the pin useless: 1 % more
    # drag torque must move the motion beyond it
    from rattlefit import RattleParams, read_recording, rig, simulate

    s = rig.setup(read_recording(golden_pin.DATA / golden_pin.FILES[0]))
    runs = [
        simulate(s.model, RattleParams(0.085e-3, t, 0.4942, s.geometry.backlash), s.drive,
                 duration=golden_pin.MOTION_S, burn_in=0.0).q
        for t in (0.025, 0.025 * 1.01)
    ]  # fmt: skip
    assert (
        np.max(np.abs(np.asarray(runs[1]) - np.asarray(runs[0])))
        > golden_pin.TOLERANCES["motion"][1]
    )


def test_outputs_match_the_golden_pin_to_the_last_bit():
    path = golden_pin.pin_path()
    if not path.exists():
        key, info = golden_pin.platform_key()
        pytest.skip(
            f"no exact pin for this platform ({key}: {info}); the pin within rounding ran. "
            "Record one on the commit to compare against with `python tests/golden_pin.py "
            "--record`"
        )
    pinned = json.loads(path.read_text())["outputs"]
    now = golden_pin.compute()
    assert sorted(now) == sorted(pinned)
    moved = []
    for name in pinned:
        # compared as JSON text: floats by their repr, so to the last bit (and NaN == NaN)
        want = json.dumps(pinned[name], indent=1, sort_keys=True).splitlines()
        got = json.dumps(now[name], indent=1, sort_keys=True).splitlines()
        diff = list(difflib.unified_diff(want, got, "pinned", "now", n=2, lineterm=""))
        if diff:
            moved.append(f"{name} moved:\n" + "\n".join(diff[:60]))
    assert not moved, "\n".join(moved)
