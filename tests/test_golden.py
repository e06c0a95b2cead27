"""The golden pin: restructuring the code moves no result (see ``tests/golden_pin.py``).

Within rounding, on every platform: the stages that are not chaotic (features, 30 ms of
motion, a closed form) against ``tests/pins/stable.json``. The seeded pipelines, whose chaos
grows a last-bit difference of another CPU or JAX version into another realisation, are
compared to the last bit only on one machine, before and after a change
(``python tests/golden_pin.py --record``/``--compare``), never against a committed file.
"""

from __future__ import annotations

import json

import numpy as np

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
    # a tolerance so loose that a real change passes would make the pin useless: 0.1 % more
    # drag torque must move the motion beyond it
    from rattlefit import RattleParams, read_recording, rig, simulate

    s = rig.setup(read_recording(golden_pin.DATA / golden_pin.FILES[0]))
    runs = [
        simulate(s.model, RattleParams(0.085e-3, t, 0.4942, s.geometry.backlash), s.drive,
                 duration=golden_pin.MOTION_S, burn_in=0.0).q
        for t in (0.025, 0.025 * 1.001)
    ]  # fmt: skip
    assert (
        np.max(np.abs(np.asarray(runs[1]) - np.asarray(runs[0])))
        > golden_pin.TOLERANCES["motion"][1]
    )


def test_the_exact_comparison_sees_a_last_bit_and_nothing_else():
    # the developer's before/after check (golden_pin.py --compare) must see one ulp moved, a
    # pipeline gone, and nothing where the documents are equal (NaN included)
    doc = {"identify": {"chi2": 32.8, "nan": float("nan")}, "sample": {"tau": [1.5, 2.0]}}
    same = json.loads(json.dumps(doc))
    assert golden_pin.differences(doc, same) == []
    moved = json.loads(json.dumps(doc))
    moved["sample"]["tau"][1] = float(np.nextafter(2.0, 3.0))
    (only,) = golden_pin.differences(doc, moved)
    assert only.startswith("sample moved") and "2.0000000000000004" in only
    assert "pipelines differ" in golden_pin.differences(doc, {"sample": doc["sample"]})[0]
