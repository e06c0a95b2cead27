"""The golden pin: restructuring the code moves no result, to the last bit.

``tests/pins/<platform>.json`` holds the JSON documents of three fixed pipelines (see
``tests/golden_pin.py``), recorded on that platform. A seeded result depends on the platform
(JAX version, device count, CPU model and its instruction-set cap), so on a platform with no
pin the test is skipped with a message saying how to record one; it never passes silently.
"""

from __future__ import annotations

import difflib
import json

import pytest

import golden_pin


def test_outputs_match_the_golden_pin():
    path = golden_pin.pin_path()
    if not path.exists():
        key, info = golden_pin.platform_key()
        pytest.skip(
            f"no golden pin for this platform ({key}: {info}); record one on the commit to "
            "compare against with `python tests/golden_pin.py --record`"
        )
    pinned = json.loads(path.read_text())["outputs"]
    now = golden_pin.compute()
    assert sorted(now) == sorted(pinned)
    for name in pinned:
        # compared as JSON text: floats by their repr, so to the last bit (and NaN == NaN)
        want = json.dumps(pinned[name], indent=1, sort_keys=True).splitlines()
        got = json.dumps(now[name], indent=1, sort_keys=True).splitlines()
        diff = list(difflib.unified_diff(want, got, "pinned", "now", n=2, lineterm=""))
        assert not diff, f"{name} moved:\n" + "\n".join(diff[:60])
