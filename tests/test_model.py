"""The mesh stiffness K(θ1) of eq. (4): its table against the exact sum and the closed form."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rattlefit as rf
from rattlefit.physics.model import share_stiffness_tables
from test_reference import sharp_stiffness  # eq. (4) written out, sharp windows


@pytest.mark.parametrize("pair", ["I", "II"])
def test_table_matches_the_exact_sum(pair):
    g = rf.table2_pair(pair, center_distance_mm=65.6)
    tabulated = rf.RattleModel.from_geometry(g)
    assert tabulated.stiffness_table is not None
    # a window too narrow to tabulate is summed exactly: compare both at the same width by
    # forcing the exact path on a copy of the tabulated model
    exact = tabulated.__class__(
        **{k: getattr(tabulated, k) for k in tabulated.__dataclass_fields__}
        | {"stiffness_table": None}
    )
    theta = jnp.asarray(np.random.default_rng(0).uniform(0, 20, 4000)) * g.base_pitch_angle
    k_tab = np.asarray(jax.vmap(tabulated.mesh_stiffness)(theta))
    k_exact = np.asarray(jax.vmap(exact.mesh_stiffness)(theta))
    np.testing.assert_allclose(k_tab, k_exact, rtol=1e-9)


def test_a_shared_stack_of_tables_gives_each_model_its_own_stiffness():
    # two centre distances of one pair: other contact ratios, so other tables
    models = [
        rf.RattleModel.from_geometry(rf.table2_pair("II", center_distance_mm=c))
        for c in (65.0, 66.0)
    ]
    assert not np.allclose(models[0].stiffness_table, models[1].stiffness_table)
    stacked = jax.tree_util.tree_map(lambda *x: jnp.stack(x), *models)
    untabled, tables = share_stiffness_tables(stacked)
    assert untabled.stiffness_table is None and tables.shape == (
        2,
        *models[0].stiffness_table.shape,
    )
    theta = jnp.asarray(np.random.default_rng(1).uniform(0, 30, 500)) * models[0].base_pitch_angle
    for row, own in enumerate(models):
        shared = jax.tree_util.tree_map(lambda x, r=row: x[r], untabled)
        shared = eqx.tree_at(
            lambda m: m.stiffness_table, shared, tables, is_leaf=lambda x: x is None
        )
        # the same table entries and arithmetic: equal to the last bit, one by one and vmapped
        k_own = np.asarray(jax.vmap(lambda t, m=own: m.mesh_stiffness(t, 1.1))(theta))
        np.testing.assert_array_equal(
            np.asarray(jax.vmap(lambda t, m=shared: m.mesh_stiffness(t, 1.1))(theta)), k_own
        )
        assert float(shared.mesh_stiffness(theta[7])) == float(own.mesh_stiffness(theta[7]))


@pytest.mark.parametrize("u", [0.3, 0.5, 0.65])
def test_stiffness_away_from_window_edges_is_the_closed_form(pair2, u):
    model = rf.RattleModel.from_geometry(pair2)
    eps = pair2.total_contact_ratio
    # 25 window widths from every edge, a smoothed window differs from 1 or 0 by e^-25
    assert min(abs(u + j - e) for j in range(4) for e in (0.0, eps)) >= 0.25, "u is at an edge"
    k = float(model.mesh_stiffness(u * pair2.base_pitch_angle, 0.9))
    assert k == pytest.approx(sharp_stiffness(pair2, u * pair2.base_pitch_angle, 0.9), rel=1e-9)


def test_stiffness_is_continuous_across_a_base_pitch(pair2):
    # a pair entering at the base-pitch boundary has both halves of its smoothed step (summed
    # from u alone, K jumped there by half a pair's stiffness: 19 % for pair II)
    model = rf.RattleModel.from_geometry(pair2)
    p = pair2.base_pitch_angle
    for n in (1, 2, 7):
        before = float(model.mesh_stiffness(n * p * (1 - 1e-12)))
        after = float(model.mesh_stiffness(n * p * (1 + 1e-12)))
        assert after == pytest.approx(before, rel=1e-7)
    # and its derivative too (C¹: cubic Hermite between the nodes)
    slope = jax.grad(model.mesh_stiffness)
    mid = float(slope(p * 1.3))
    assert float(slope(p * (1 - 1e-9))) == pytest.approx(float(slope(p * (1 + 1e-9))), rel=1e-4)
    assert math.isfinite(mid)
