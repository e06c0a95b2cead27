"""The simulator against closed forms and physical thresholds."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rattlefit as rf
from rattlefit.physics.model import equivalent_viscosity, squeeze_coefficient

LONG_SEED = 7  # the 30 s recording of the headline point
STILL = rf.Drive(0.0, 8.0, [0.0], [0.0])  # θ1 ≡ 0: no forcing, frozen mesh stiffness


def test_free_flight_under_drag(pair2):
    # No film, gap much larger than the motion: q = q0 + v0 t − (T_b/(r2 m)) t²/2.
    model = rf.RattleModel.from_geometry(pair2)
    p = rf.RattleParams(0.0, 0.05, 0.5, 0.02)  # 20 mm backlash: no contact in 20 ms
    v0 = 0.3
    sol = rf.simulate(
        model,
        p,
        STILL,
        duration=0.02,
        sample_rate=1e4,
        burn_in=0.0,
        y0=[0.0, v0],
        rtol=1e-10,
        atol=1e-14,
    )
    t = np.asarray(sol.time)
    decel = 0.05 / pair2.pitch_radius_driven / pair2.equivalent_mass
    np.testing.assert_allclose(np.asarray(sol.q), v0 * t - 0.5 * decel * t**2, atol=1e-12)
    np.testing.assert_allclose(
        np.asarray(sol.relative_motion), -np.asarray(sol.q) / pair2.pitch_radius_driving
    )


def test_squeeze_approach_long_film(pair2):
    # a ≫ √(Rh): S = C h^{-3/2}, C = (3π/2) μ Z R^{3/2}; m v dv = −C h^{-3/2} v dq with dh = −dq
    # integrates to v(h) = v0 − (2C/m)(h^{-1/2} − h0^{-1/2}).
    model = rf.RattleModel.from_geometry(pair2)
    mu, backlash = 2.0, 2e-3
    p = rf.RattleParams(10.0, 0.0, mu, backlash, min_film=1e-9)
    c = backlash / 2
    h0, v0 = 600e-6, 0.05  # the film stops it at h ≈ 13 µm
    sol = rf.simulate(
        model,
        p,
        STILL,
        duration=0.03,
        sample_rate=5e4,
        burn_in=0.0,
        y0=[c - h0, v0],
        rtol=1e-10,
        atol=1e-14,
    )
    h = c - np.asarray(sol.q)
    v = np.asarray(sol.velocity)
    C = 1.5 * math.pi * mu * pair2.axial_width * pair2.curvature_radius**1.5
    expected = v0 - 2 * C / pair2.equivalent_mass * (h**-0.5 - h0**-0.5)
    assert np.all(h > 5e-6)  # stayed in the film regime, far from h_min and contact
    assert v[-1] < 0.5 * v0  # the film did real work
    np.testing.assert_allclose(v, expected, rtol=2e-4, atol=1e-7)


def test_squeeze_coefficient_limits():
    R, Z, mu = 5e-3, 12e-3, 0.5
    h = np.array([5e-6, 50e-6, 500e-6])
    # short film: parallel-plate strip of width 2a, S = μ Z (2a)³ / h³
    a = 1e-6
    np.testing.assert_allclose(
        squeeze_coefficient(h, a, mu, R, Z), 8 * mu * Z * a**3 / h**3, rtol=1e-3
    )
    # long film: S = (3π/2) μ Z R^{3/2} h^{-3/2}
    np.testing.assert_allclose(
        squeeze_coefficient(h, 10.0, mu, R, Z), 1.5 * np.pi * mu * Z * R**1.5 * h**-1.5, rtol=1e-3
    )
    # the series branch joins the exact formula continuously and differentiably
    y_edge = 1e-2
    a_edge = y_edge * np.sqrt(R * h[1])
    lo = squeeze_coefficient(h[1], a_edge * (1 - 1e-9), mu, R, Z)
    hi = squeeze_coefficient(h[1], a_edge * (1 + 1e-9), mu, R, Z)
    assert float(hi) == pytest.approx(float(lo), rel=1e-6)
    grad = jax.grad(lambda a: squeeze_coefficient(50e-6, a, mu, R, Z))(0.0)
    assert np.isfinite(grad)


def test_equivalent_viscosity_keeps_the_squeeze_coefficient_in_both_film_limits():
    R, mu = 5e-3, 0.5
    h = np.array([5e-6, 50e-6, 500e-6])
    # short films both (S ∝ μ a³): μ' = μ (a/a')³
    np.testing.assert_allclose(equivalent_viscosity(h, 1e-7, mu, 2e-7, R), mu / 8, rtol=1e-3)
    # long films both (S independent of a): μ' = μ
    np.testing.assert_allclose(equivalent_viscosity(h, 10.0, mu, 20.0, R), mu, rtol=1e-3)
    # a short film made long: μ' 8 a³/h³ = (3π/2) μ' R^{3/2} h^{-3/2} … = μ 8 a³/h³
    short = 8 * 1e-7**3 / h**3
    long = 1.5 * np.pi * R**1.5 * h**-1.5
    np.testing.assert_allclose(
        equivalent_viscosity(h, 1e-7, mu, 10.0, R), mu * short / long, rtol=1e-3
    )


def test_mesh_mode_frequency(pair2):
    # Rest on the drive flank under drag, nudge: the contact rings at sqrt(K(θ1)/m).
    model = rf.RattleModel.from_geometry(pair2)
    # a large drag (10 N m) presses the flanks ~1 µm together, ten smoothing widths deep
    p = rf.RattleParams(0.0, 10.0, 0.5, pair2.backlash)
    c = pair2.backlash / 2
    static = 10.0 / pair2.pitch_radius_driven / pair2.mesh_stiffness_iso
    y0 = [-c - 1.5 * static, 0.0]
    # θ1 frozen half a base pitch in, away from the pair windows' edges
    still = rf.Drive(0.0, 8.0, [0.0], [0.0], offset=0.5 * pair2.base_pitch_angle)
    sol = rf.simulate(
        model, p, still, duration=0.01, sample_rate=2e5, burn_in=0.0, y0=y0, rtol=1e-10, atol=1e-15
    )
    q = np.asarray(sol.q)
    assert np.all(q < -c - 0.3 * static)  # stayed in contact
    x = q - q.mean()
    crossings = np.flatnonzero(np.diff(np.sign(x)) > 0)
    f_measured = (len(crossings) - 1) / ((crossings[-1] - crossings[0]) / 2e5)
    # eq. (4) by hand: pairs at engagement angles 0.5, 1.5, 2.5 base pitches, those within ε
    eps, eps_a = pair2.total_contact_ratio, pair2.transverse_contact_ratio
    k = sum(
        pair2.pitch_point_stiffness
        * math.exp(pair2.stiffness_shape * abs((u - eps / 2) / (1.125 * eps_a)) ** 3)
        for u in (0.5, 1.5, 2.5)
        if u < eps
    )
    assert f_measured == pytest.approx(
        math.sqrt(k / pair2.equivalent_mass) / (2 * math.pi), rel=5e-3
    )


@pytest.mark.parametrize("ratio, rattles", [(0.7, False), (1.5, True)])
def test_no_rattle_threshold(pair2, ratio, rattles):
    # Singh et al. (1989): no rattle while I2 (r1/r2) max θ̈1 < T_b.
    model = rf.RattleModel.from_geometry(pair2)
    f = 8.0
    t_b = 0.02
    critical_amplitude = t_b / (
        pair2.driven_inertia
        * pair2.pitch_radius_driving
        / pair2.pitch_radius_driven
        * 2
        * math.pi
        * f
    )
    drive = rf.Drive.commanded(52.36, ratio * critical_amplitude, f)
    p = rf.RattleParams(0.085e-3, t_b, 0.5, pair2.backlash)
    assert model.rattle_threshold(p, drive) == rattles
    sol = rf.simulate(model, p, drive, duration=1.0, burn_in=0.3)
    separation = float(np.max(np.asarray(sol.q))) + pair2.backlash / 2  # distance from drive flank
    if rattles:
        assert separation > 0.25 * pair2.backlash
    else:
        assert separation < 1e-6


def test_batch_equals_single(pair2):
    model = rf.RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.472, 16.0)
    a = jnp.array([0.05e-3, 0.2e-3])
    p = rf.RattleParams(a, 0.025, 0.49, pair2.backlash)
    from rattlefit.simulation.solve import broadcast_params

    # short and without burn-in: rattle is chaotic, so round-off differences between the
    # batched and the single solve would grow over longer runs
    opts = dict(duration=0.05, burn_in=0.0, rtol=1e-9, atol=1e-12)
    batch = rf.simulate_batch(model, broadcast_params(p, 2), drive, **opts)
    single = rf.simulate(model, rf.RattleParams(a[1], 0.025, 0.49, pair2.backlash), drive, **opts)
    np.testing.assert_allclose(np.asarray(batch.q[1]), np.asarray(single.q), atol=1e-9)
    assert batch.q.shape == (2, 500)


def test_failure_is_reported_not_nan(pair2):
    model = rf.RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.472, 16.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.49, pair2.backlash)
    sol = rf.simulate(model, p, drive, duration=0.5, max_steps=50)
    assert not bool(sol.success)
    assert np.all(np.isfinite(np.asarray(sol.q)))
    with pytest.raises(rf.SolverError, match="failed"):
        from rattlefit.simulation.solve import raise_if_failed

        raise_if_failed(sol)


def test_absolute_tolerance_per_state_component(pair2):
    # through diffrax: a pair (a, a) is the scalar a; the velocity's own, looser tolerance
    # (the fit's rtol × 30 mm/s against rtol × 1 mm/s) takes fewer steps; anything but one or
    # two numbers is refused
    model = rf.RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 5.236, 8.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.49, pair2.backlash)
    kw = dict(duration=0.1, burn_in=0.1, rtol=1e-5)
    one = rf.simulate(model, p, drive, atol=1e-8, **kw)
    pair = rf.simulate(model, p, drive, atol=(1e-8, 1e-8), **kw)
    np.testing.assert_array_equal(np.asarray(one.q), np.asarray(pair.q))
    loose = rf.simulate(model, p, drive, atol=(1e-8, 3e-7), **kw)
    assert bool(loose.success) and int(loose.num_steps) < int(one.num_steps)
    with pytest.raises(ValueError, match="atol"):
        rf.simulate(model, p, drive, atol=(1e-8, 1e-8, 1e-8), **kw)


def test_invalid_parameters_refused():
    with pytest.raises(rf.ParameterError, match="viscosity"):
        rf.RattleParams(1e-4, 0.02, -0.5, 1e-3)
    with pytest.raises(rf.ParameterError, match="min_film"):
        rf.RattleParams(1e-4, 0.02, 0.5, 1e-5, min_film=1e-5)


def test_forward_sensitivity_is_finite(pair2):
    from rattlefit.features.spectra import BandSpec, spectral_features

    model = rf.RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.472, 16.0)
    bands = BandSpec()

    def features(log_a):
        p = rf.RattleParams(jnp.exp(log_a), 0.025, 0.49, pair2.backlash)
        return spectral_features(
            rf.simulate(model, p, drive, duration=1.0).relative_motion, bands, noise_floor=1e-12
        )

    jac = jax.jacfwd(features)(jnp.log(0.085e-3))
    assert np.all(np.isfinite(np.asarray(jac)))
    assert float(jnp.max(jnp.abs(jac))) > 0.0


def test_quantised_output_has_eq8_resolution(pair2):
    from rattlefit.io.recording import quantisation_std
    from rattlefit.simulation.solve import quantised_relative_motion

    model = rf.RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.472, 16.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.49, pair2.backlash)
    sol = rf.simulate(model, p, drive, duration=1.0)
    measured = quantised_relative_motion(sol, model)
    exact = np.asarray(sol.relative_motion) - float(sol.relative_motion[0])
    err = measured - exact
    err -= err.mean()
    # eq. (8): (1/(2√3)) (2π/40000) √(1 + (z2/z1)²), by hand for pair II (z = 19/41)
    by_hand = (2 * np.pi / 40000) / (2 * np.sqrt(3)) * np.sqrt(1 + (41 / 19) ** 2)
    assert quantisation_std(40000, 41 / 19) == pytest.approx(by_hand)
    assert np.std(err) == pytest.approx(by_hand, rel=0.1)
    assert np.max(np.abs(err)) < 2 * 2 * np.pi / 40000 * (1 + 41 / 19)


def test_effects_plug_in(pair2):
    # The Effect contract: an extra force of −ΔT/r2 is extra drag; a constant gap error δ
    # shifts the flanks, i.e. the motion q by δ.
    import jax.numpy as jnp

    class ExtraDrag(rf.Effect):
        torque: float

        def force(self, t, q, v, f_mesh, model, params, drive):
            return -self.torque / model.r2

    class Offset(rf.Effect):
        delta: float

        def gap_error(self, t, theta1, model, params, drive):
            return jnp.asarray(self.delta)

    drive = rf.Drive.commanded(52.36, 10.472, 16.0)
    base = rf.RattleModel.from_geometry(pair2)
    opts = dict(duration=0.05, burn_in=0.0, rtol=1e-10, atol=1e-14)
    c = pair2.backlash / 2
    p = rf.RattleParams(0.085e-3, 0.02, 0.49, pair2.backlash)
    more = rf.RattleParams(0.085e-3, 0.03, 0.49, pair2.backlash)
    a = rf.simulate(base.with_effects(ExtraDrag(0.01)), p, drive, y0=[-c, 0.0], **opts)
    b = rf.simulate(base, more, drive, y0=[-c, 0.0], **opts)
    np.testing.assert_allclose(np.asarray(a.q), np.asarray(b.q), atol=1e-12)
    d = 20e-6
    shifted = rf.simulate(base.with_effects(Offset(d)), p, drive, y0=[-c + d, 0.0], **opts)
    plain = rf.simulate(base, p, drive, y0=[-c, 0.0], **opts)
    np.testing.assert_allclose(np.asarray(shifted.q) - d, np.asarray(plain.q), atol=1e-11)


def test_a_long_recording_gets_a_step_budget_in_proportion():
    # the paper's headline point simulated for 30 s at synthesize's tolerance: a fixed budget
    # of 200,000 steps (enough for 3 s) made it fail; the budget grows with the simulated time
    from rattlefit.io.recording import OperatingPoint
    from rattlefit.simulation.solve import STEPS_PER_3_5_S, step_budget
    from rattlefit.simulation.synthetic import synthesize

    assert step_budget(3.0, 0.5) == STEPS_PER_3_5_S
    assert step_budget(30.0, 0.5) == pytest.approx(STEPS_PER_3_5_S * 30.5 / 3.5, abs=1)
    g = rf.table2_pair("II", center_distance_mm=65.6)
    op = OperatingPoint("boundary", 20.0, 52.36, 10.472, 16.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
    rec, _ = synthesize(g, op, p, seed=LONG_SEED, duration=30.0)
    assert rec.n_samples == 300_000
