"""Batches split over several JAX CPU devices give the single-device results."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import jax
import numpy as np
import pytest

import rattlefit as rf
from rattlefit.simulation.parallel import map_blocks, map_rows
from rattlefit.simulation.solve import broadcast_params

#: A lax.map member is computed the same way whatever the batch, so a long run agrees to the
#: last bits. The lockstep batch vectorises each device's share, and a vectorised
#: transcendental may round differently in another batch layout; rattle's chaos grows that
#: to everything within ~50 ms, so the lockstep run is short (still ~400 steps with impacts).
RUNS = {
    "map": dict(duration=0.2, burn_in=0.05),
    "lockstep": dict(duration=0.01, burn_in=0.002),
}
TOLERANCE = {"map": 1e-12, "lockstep": 1e-9}

SCRIPT = textwrap.dedent(
    """
    import sys
    import numpy as np
    import rattlefit as rf
    from rattlefit.simulation.solve import broadcast_params
    RUNS = {runs!r}
    n = rf.configure(cpu_cores=2).devices
    assert n == 2, n
    g = rf.table2_pair("II", center_distance_mm=65.6)
    model = rf.RattleModel.from_geometry(g)
    drive = rf.Drive.commanded(52.36, 10.47, 16.0)
    params = broadcast_params(
        rf.RattleParams([1e-4, 2e-4, 5e-4], 0.025, 0.49, g.backlash), 3
    )
    for mode, path in (("map", sys.argv[1]), ("lockstep", sys.argv[2])):
        kw = RUNS[mode]
        sol = rf.simulate_batch(model, params, drive, rtol=1e-5, batch=mode, **kw)
        np.save(path, np.asarray(sol.relative_motion))
    """
).format(runs=RUNS)


def test_map_rows_pads_and_matches_lax_map():
    rows = (np.arange(5.0), np.arange(5.0) ** 2)
    out = map_rows(lambda r: r[0] + r[1], rows)
    np.testing.assert_array_equal(out, rows[0] + rows[1])


def test_map_blocks_gives_the_whole_batch_to_a_batched_function():
    rows = (np.arange(5.0), np.arange(5.0) ** 2)
    out = map_blocks(lambda r: r[0][:, None] * r[1][:, None] + np.ones((1, 3)), rows)
    np.testing.assert_array_equal(out, (rows[0] * rows[1])[:, None] + np.ones((1, 3)))


@pytest.mark.parametrize("mode", ["map", "lockstep"])
def test_two_cpu_devices_reproduce_one(tmp_path, pair2, mode):
    # three members over two devices: one device gets a padded copy that must be dropped
    paths = [tmp_path / "map.npy", tmp_path / "lockstep.npy"]
    subprocess.run([sys.executable, "-c", SCRIPT, *map(str, paths)], check=True, timeout=600)
    assert len(jax.local_devices()) == 1
    model = rf.RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.47, 16.0)
    params = broadcast_params(rf.RattleParams([1e-4, 2e-4, 5e-4], 0.025, 0.49, pair2.backlash), 3)
    one = rf.simulate_batch(model, params, drive, rtol=1e-5, batch=mode, **RUNS[mode])
    two = np.load(tmp_path / f"{mode}.npy")
    assert two.shape == one.relative_motion.shape
    np.testing.assert_allclose(two, np.asarray(one.relative_motion), rtol=0, atol=TOLERANCE[mode])
    # the members are in their places: each differs from its neighbour by more
    assert np.min(np.abs(np.diff(two, axis=0)).max(axis=1)) > 20 * TOLERANCE[mode]
