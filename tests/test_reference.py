"""rattlefit.simulation.reference, the sharp-switching scipy reference solver, against closed
forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rattlefit.errors import ParameterError
from rattlefit.physics.drive import Drive
from rattlefit.physics.geometry import table2_pair
from rattlefit.simulation.reference import ReferenceSolution, simulate_reference


@pytest.fixture(scope="module")
def geom():
    return table2_pair("II", center_distance_mm=65.6)


def frozen_drive(geom, fraction=0.3):
    """θ1 ≡ fraction·Θp: no forcing and a constant mesh stiffness."""
    return Drive(0.0, 8.0, [0.0], [0.0], offset=fraction * geom.base_pitch_angle)


def sharp_stiffness(geom, theta1, scale=1.0):
    """K(θ1) of eq. (4) written out for one angle, N/m."""
    eps, eps_a = geom.total_contact_ratio, geom.transverse_contact_ratio
    u0 = (theta1 / geom.base_pitch_angle) % 1.0
    total = 0.0
    for j in range(4):
        u = u0 + j
        if 0.0 <= u <= eps:
            total += math.exp(geom.stiffness_shape * abs((u - eps / 2) / (1.125 * eps_a)) ** 3)
    return scale * geom.pitch_point_stiffness * total


@pytest.mark.parametrize("fluctuation", [0.0, 10.472])
def test_free_flight_under_drag_is_a_parabola(geom, fluctuation):
    """No contact, no squeeze: m q̈ = −T_b/r2 − m r1 θ̈1(t), integrated in closed form.

    At constant speed q = q0 + v0 t − (T_b/(r2 m)) t²/2; the commanded speed
    Ω + ΔΩ sin(w t) adds −r1 (ΔΩ/w)(1 − cos w t) (the primary shaft runs away from the gear).
    """
    t_b, q0, v0, w = 0.025, -1.0e-3, 0.1, 2 * math.pi * 16.0
    drive = (
        Drive.commanded(52.36, fluctuation, 16.0) if fluctuation else Drive(50.0, 8.0, [0.0], [0.0])
    )
    sol = simulate_reference(
        geom,
        drive,
        film_half_length=0.0,
        drag_torque=t_b,
        viscosity=0.494,
        backlash=20e-3,
        duration=0.02,
        sample_rate=10_000.0,
        burn_in=0.0,
        initial_state=(q0, v0),
    )
    assert isinstance(sol, ReferenceSolution)
    decel = t_b / (geom.pitch_radius_driven * geom.equivalent_mass)
    r1 = geom.pitch_radius_driving
    t = sol.time
    np.testing.assert_allclose(t, np.arange(200) / 10_000.0)
    q_closed = q0 + v0 * t - 0.5 * decel * t**2 - r1 * fluctuation / w * (1 - np.cos(w * t))
    v_closed = v0 - decel * t - r1 * fluctuation * np.sin(w * t)
    assert np.ptp(q_closed) > 1e-3
    np.testing.assert_allclose(sol.q, q_closed, rtol=0, atol=1e-10)
    np.testing.assert_allclose(sol.v, v_closed, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.relative_motion, -sol.q / r1)
    assert sol.n_events == 0 and sol.event_times.size == 0
    assert sol.n_rhs > 0


def test_elastic_bounce_is_a_half_sine(geom):
    """Dry contact with constant K: contact lasts π√(m/K) and returns −v0 (no loss)."""
    c = geom.backlash / 2
    q0, v0 = 0.0, 0.05
    drive = frozen_drive(geom)
    sol = simulate_reference(
        geom,
        drive,
        film_half_length=0.0,
        drag_torque=0.0,
        viscosity=0.494,
        backlash=geom.backlash,
        duration=0.02,
        sample_rate=20_000.0,
        burn_in=0.0,
        initial_state=(q0, v0),
    )
    k = sharp_stiffness(geom, 0.3 * geom.base_pitch_angle)
    t_in, t_out = sol.event_times[:2]
    assert sol.n_events == 2  # onset and exit at the coast flank; the drive flank is not reached
    assert t_in == pytest.approx((c - q0) / v0, rel=1e-8)
    assert t_out - t_in == pytest.approx(math.pi * math.sqrt(geom.equivalent_mass / k), rel=1e-4)
    after = sol.time > t_out
    assert np.count_nonzero(after) > 100
    np.testing.assert_allclose(sol.v[after], -v0, rtol=1e-6)  # energy conserved to 2e-6
    np.testing.assert_allclose(sol.q[after], c - v0 * (sol.time[after] - t_out), atol=1e-10)
    before = sol.time < t_in
    np.testing.assert_allclose(sol.q[before], q0 + v0 * sol.time[before], atol=1e-12)


@pytest.mark.parametrize("speed", [1e-3, -1e-3])
@pytest.mark.parametrize("edge", ["pair enters", "pair leaves"])
def test_mesh_window_switch_during_contact(geom, edge, speed):
    """A tooth pair enters or leaves mid-bounce: two half-sines joined at the stiffness jump.

    The drive turns so slowly that K is constant on either side of the jump (to ~1e-7), so the
    contact is the free oscillation at ω1 = √(K1/m) up to the switch, then at ω2 = √(K2/m).
    """
    c, m = geom.backlash / 2, geom.equivalent_mass
    q0, v0 = 0.0, 0.05
    t_in = (c - q0) / v0
    p_switch = 5.0 + (geom.total_contact_ratio if edge == "pair leaves" else 0.0)
    theta_s = p_switch * geom.base_pitch_angle
    k1 = sharp_stiffness(geom, theta_s - math.copysign(1e-9, speed))
    k2 = sharp_stiffness(geom, theta_s + math.copysign(1e-9, speed))
    assert abs(k2 - k1) > 0.2 * k1  # a real jump
    w1, w2 = math.sqrt(k1 / m), math.sqrt(k2 / m)
    tau_s = 0.4 * math.pi / w1
    drive = Drive(speed, 8.0, [0.0], [0.0], offset=theta_s - speed * (t_in + tau_s))
    sol = simulate_reference(
        geom,
        drive,
        film_half_length=0.0,
        drag_torque=0.0,
        viscosity=0.494,
        backlash=geom.backlash,
        duration=0.012,
        sample_rate=20_000.0,
        burn_in=0.0,
        initial_state=(q0, v0),
    )
    x_s, v_s = (v0 / w1) * math.sin(w1 * tau_s), v0 * math.cos(w1 * tau_s)
    amplitude = math.hypot(x_s, v_s / w2)
    phase = math.atan2(x_s * w2, v_s)
    assert sol.n_events == 2
    t_enter, t_exit = sol.event_times
    assert t_enter == pytest.approx(t_in, rel=1e-8)
    assert t_exit - t_enter == pytest.approx(tau_s + (math.pi - phase) / w2, rel=1e-6)
    after = sol.time > t_exit
    np.testing.assert_allclose(sol.v[after], -amplitude * w2, rtol=1e-6)


def test_resting_on_the_drive_flank_is_the_static_deflection(geom):
    """Default start: at rest on the drive flank, pressed in by the drag: it stays there."""
    t_b = 2.0
    sol = simulate_reference(
        geom,
        frozen_drive(geom, 0.7),
        film_half_length=0.085e-3,
        drag_torque=t_b,
        viscosity=0.494,
        backlash=geom.backlash,
        stiffness_scale=0.8,
        duration=0.01,
        burn_in=0.01,
    )
    k = sharp_stiffness(geom, 0.7 * geom.base_pitch_angle, scale=0.8)
    deflection = t_b / geom.pitch_radius_driven / k
    expected = -geom.backlash / 2 - deflection
    np.testing.assert_allclose(sol.q, expected, rtol=0, atol=1e-6 * deflection)
    np.testing.assert_allclose(sol.v, 0.0, atol=1e-9)
    assert sol.n_events == 0


def test_squeeze_approach_follows_the_long_film_closed_form(geom):
    """a ≫ √(Rh): m v dv/dq = −C h^{-3/2} v, so v = v0 − (2C/m)(h^{-1/2} − h0^{-1/2})."""
    mu, v0, h0 = 0.5, 2e-3, 300e-6
    c = geom.backlash / 2
    sol = simulate_reference(
        geom,
        Drive(50.0, 8.0, [0.0], [0.0]),
        film_half_length=1.0,
        drag_torque=0.0,
        viscosity=mu,
        backlash=geom.backlash,
        min_film=1e-9,
        duration=0.5,
        sample_rate=1000.0,
        burn_in=0.0,
        initial_state=(c - h0, v0),
    )
    cc = 1.5 * math.pi * mu * geom.axial_width * geom.curvature_radius**1.5
    h = c - sol.q
    v_closed = v0 - (2 * cc / geom.equivalent_mass) * (h**-0.5 - h0**-0.5)
    assert sol.n_events == 0
    assert sol.v[-1] < 0.2 * v0  # the film has taken most of the speed away
    assert np.all(h > 50e-6)  # ... before the flanks meet
    np.testing.assert_allclose(sol.v, v_closed, rtol=0, atol=1e-6 * v0)
    for i in (10, 50, 100, 300):  # and relative to the speed left at a few sample times
        assert sol.v[i] == pytest.approx(v_closed[i], rel=1e-6)


def test_rattling_case_locates_contacts_and_bounds_penetration(geom):
    sol = simulate_reference(
        geom,
        Drive.commanded(52.36, 10.472, 16.0),
        film_half_length=0.085e-3,
        drag_torque=0.025,
        viscosity=0.494,
        backlash=geom.backlash,
        duration=1.0,
    )
    c = geom.backlash / 2
    assert sol.time.shape == sol.q.shape == sol.v.shape == (10_000,)
    assert np.all(np.isfinite(sol.q)) and np.all(np.isfinite(sol.v))
    in_record = sol.event_times[sol.event_times >= 0]
    assert in_record.size > 10
    assert sol.n_events == sol.event_times.size
    assert np.all(np.diff(sol.event_times) > 0)
    assert np.max(np.abs(sol.q)) - c < 100e-6
    assert np.max(sol.q) > -c  # it does leave the drive flank
    # Both flanks are hit: the motion spans the play.
    assert np.ptp(sol.q) > 1.5 * c


def test_invalid_parameters_are_refused(geom):
    drive = Drive(50.0, 8.0, [0.0], [0.0])
    base = dict(film_half_length=0.0, drag_torque=0.0, viscosity=0.5, backlash=geom.backlash)
    for bad in (dict(backlash=0.0), dict(min_film=-1e-6), dict(viscosity=np.nan)):
        with pytest.raises(ParameterError):
            simulate_reference(geom, drive, **{**base, **bad}, duration=0.01)
    with pytest.raises(ParameterError):
        simulate_reference(geom, drive, **base, duration=1e-6)
