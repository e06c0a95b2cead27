"""Batches split over several JAX CPU devices give the single-device results."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import jax
import numpy as np

import rattlefit as rf
from rattlefit.parallel import map_rows
from rattlefit.simulate import broadcast_params

SCRIPT = textwrap.dedent(
    """
    import sys
    import numpy as np
    import rattlefit as rf
    from rattlefit.simulate import broadcast_params
    n = rf.use_cpu_cores(2)
    assert n == 2, n
    g = rf.table2_pair("II", center_distance_mm=65.6)
    model = rf.RattleModel.from_geometry(g)
    drive = rf.Drive.commanded(52.36, 10.47, 16.0)
    params = broadcast_params(
        rf.RattleParams([1e-4, 2e-4, 5e-4], 0.025, 0.49, g.backlash), 3
    )
    sol = rf.simulate_batch(model, params, drive, duration=0.2, burn_in=0.05, rtol=1e-5)
    np.save(sys.argv[1], np.asarray(sol.relative_motion))
    """
)


def test_map_rows_pads_and_matches_lax_map():
    rows = (np.arange(5.0), np.arange(5.0) ** 2)
    out = map_rows(lambda r: r[0] + r[1], rows)
    np.testing.assert_array_equal(out, rows[0] + rows[1])


def test_two_cpu_devices_reproduce_one(tmp_path, pair2):
    # three members over two devices: one device gets a padded copy that must be dropped
    out = tmp_path / "two.npy"
    subprocess.run([sys.executable, "-c", SCRIPT, str(out)], check=True, timeout=600)
    assert len(jax.local_devices()) == 1
    model = rf.RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.47, 16.0)
    params = broadcast_params(rf.RattleParams([1e-4, 2e-4, 5e-4], 0.025, 0.49, pair2.backlash), 3)
    one = rf.simulate_batch(model, params, drive, duration=0.2, burn_in=0.05, rtol=1e-5)
    two = np.load(out)
    assert two.shape == one.relative_motion.shape
    np.testing.assert_allclose(two, np.asarray(one.relative_motion), rtol=0, atol=1e-12)
