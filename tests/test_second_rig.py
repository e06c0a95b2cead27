"""The second rig model (validation/second_rig) against closed forms and the recording contract."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scipy import linalg

from rattlefit.io.recording import check_recording, read_recording, write_recording
from validation.second_rig import validation_set
from validation.second_rig.rig_chain import Rig, matrices, natural_frequencies
from validation.second_rig.rig_film import flooded_momentum
from validation.second_rig.rig_geometry import Pair
from validation.second_rig.rig_mesh import MeshLaw
from validation.second_rig.rig_solver import Batch, simulate

PAIR = Pair("II", 65.6e-3)
K0 = 1.5e8  # a constant mesh stiffness, N/m, where a test needs the mesh linear


def constant_table(k=K0, lr=0.0, reff=5e-3):
    """A mesh table with constant stiffness and film integrals on both flanks."""
    rows = PAIR.z2 * 128 + 1
    return np.tile([k, k, lr, lr, reff, reff, 0.0, 0.0], (rows, 1))


def bare_rig(**changes) -> Rig:
    """Pair II, dry, no controller, no drag, no damping, at rest: a chain of springs."""
    values = dict(
        mean_speed=0.0,
        speed_amplitude=0.0,
        bandwidth_hz=0.0,
        integral_hz=0.0,
        drive_damping=0.0,
        shaft_damping=0.0,
        table=constant_table(),
    )
    values.update(changes)
    return Rig(
        PAIR,
        MeshLaw(PAIR),
        values.pop("lubrication", "dry"),
        20.0,
        values.pop("drag_torque", 0.0),
        **values,
    )


def state(rig, theta, omega):
    """(θ, ω) arrays (4, 1) from four-element sequences."""
    return np.array(theta, float)[:, None], np.array(omega, float)[:, None]


def peak_frequency(x, step, near):
    """The spectral peak of ``x`` (sampled every ``step`` s) nearest ``near`` Hz, by a Hann
    window, zero padding and a parabola through the log magnitudes around the peak."""
    x = (x - x.mean()) * np.hanning(x.size)
    n = 16 * x.size
    mag = np.log(np.abs(np.fft.rfft(x, n)) + 1e-300)
    f = np.fft.rfftfreq(n, step)
    band = np.flatnonzero(np.abs(f - near) < 0.05 * near)
    k = band[np.argmax(mag[band])]
    a, b, c = mag[k - 1 : k + 2]
    return f[k] + 0.5 * (a - c) / (a - 2 * b + c) * (f[1] - f[0])


def test_free_flight_modes_are_the_two_mass_closed_forms():
    rig = bare_rig()
    free = natural_frequencies(rig)
    jm, j1, j2, js = rig.motor_inertia, rig.pinion_inertia, rig.gear_inertia, rig.far_inertia
    primary = math.sqrt(rig.drive_stiffness * (1 / jm + 1 / j1)) / (2 * math.pi)
    secondary = math.sqrt(rig.shaft_stiffness * (1 / j2 + 1 / js)) / (2 * math.pi)
    np.testing.assert_allclose(free, [0, 0, primary, secondary], rtol=1e-10, atol=1e-3)
    # the solver rings at them: the motor twisted against the pinion, the far end against the gear
    step = 5e-6
    th, om = state(rig, [2e-5, 0, 0, 1e-6], [0, 0, 0, 0])
    traj = simulate([rig], 0.05, burn_in=0.0, sample_every=1, state=(th, om))
    theta = traj.theta[:, 0]
    assert peak_frequency(theta[0] - theta[1], step, primary) == pytest.approx(primary, rel=3e-3)
    assert peak_frequency(theta[2] - theta[3], step, secondary) == pytest.approx(
        secondary, rel=3e-3
    )


def test_modes_in_contact_are_the_eigenvalues_of_the_linearised_chain():
    # preloaded on the drive flank: the motor's bias torque against an equal drag on the gear,
    # the chain turning at 10 rad/s (the drag's regularisation saturated) in static equilibrium
    drag = 0.5
    rig = bare_rig(drag_torque=drag, drag_gear_share=1.0, mean_speed=10.0)
    mass, k = matrices(rig, K0)
    w2, _ = linalg.eigh(k, mass)
    expected = np.sqrt(w2[1:]) / (2 * math.pi)
    np.testing.assert_allclose(natural_frequencies(rig, K0)[1:], expected, rtol=1e-12)
    p = rig.pair
    force = drag / p.rb2  # mesh force, N
    twist = drag / p.ratio / rig.drive_stiffness
    theta2 = -(0.5 * p.play + force / K0) / p.rb2  # drive-flank penetration force / K0
    speeds = [10.0, 10.0, 10.0 / p.ratio, 10.0 / p.ratio]
    th, om = state(rig, [twist, 0.0, theta2, theta2], speeds)
    om[:, 0] += np.array([0.2, -0.1, 0.05, 0.08]) * 1e-3  # a small kick excites every mode
    step = 5e-6
    traj = simulate([rig], 0.06, burn_in=0.0, sample_every=1, state=(th, om))
    theta = traj.theta[:, 0]
    assert np.all(-traj.x[0, 1:] - 0.5 * p.play > 0), "the contact must stay closed"
    signals = [theta[0] - theta[1], traj.x[0], theta[2] - theta[3]]
    for f in expected:
        found = [peak_frequency(s, step, f) for s in signals]
        best = min(found, key=lambda g: abs(g - f))
        assert best == pytest.approx(f, rel=3e-3)


def test_free_flight_keeps_the_relative_rate_constant():
    rig = bare_rig(mean_speed=50.0)
    p, rate = rig.pair, 0.05  # m/s along the line of action, toward the coast flank
    gear = 50.0 / p.ratio + rate / p.rb2
    th, om = state(rig, [0, 0, 0, 0], [50.0, 50.0, gear, gear])  # centred: x = 0 at t = 0
    traj = simulate([rig], 0.005, burn_in=0.0, sample_every=1, state=(th, om))
    t = np.arange(traj.x.shape[1]) * 5e-6
    assert traj.x[0, -1] < 0.5 * p.play, "no contact during the run"
    np.testing.assert_allclose(traj.x[0], rate * t, rtol=0, atol=1e-12)


def impact(restitution, speed, step=5e-6):
    """The driven gear released toward the drive flank of a pinion that cannot move; returns
    the rebound speed over the impact speed."""
    rig = bare_rig(
        motor_inertia=1e3,
        pinion_inertia=1e3,
        shaft_stiffness=0.0,
        far_inertia=1e-6,
        restitution=restitution,
        start_fraction=-0.98,
    )
    th, om = Batch([rig]).initial_state()
    om[:] = 0.0
    om[2] = -speed / rig.pair.rb2
    traj = simulate([rig], 0.002, burn_in=0.0, step=step, sample_every=1, state=(th, om))
    v = np.diff(traj.x[0]) / step
    assert v[0] == pytest.approx(-speed)
    return v[-1] / speed


@pytest.mark.parametrize("restitution", [1.0, 0.7])
def test_a_single_impact_rebounds_with_the_contact_laws_restitution(restitution):
    # linear loading K δ, unloading K/e² (δ − p): a mass on it rebounds with e at any speed
    for speed in (0.05, 0.2):
        assert impact(restitution, speed) == pytest.approx(restitution, abs=2e-3)


def test_squeeze_film_takes_its_closed_form_momentum_and_none_on_separation():
    lr, reff, a = 7e-6, 5e-3, 1e-3
    fixed = dict(motor_inertia=1e3, pinion_inertia=1e3, shaft_stiffness=0.0, far_inertia=1e-6)
    rig = bare_rig(lubrication="oil_jet", a_max=a, table=constant_table(lr=lr, reff=reff), **fixed)
    p, step, speed = rig.pair, 2e-7, 0.3
    cos_bb, mass, mu = math.cos(p.beta_b), rig.gear_inertia / p.rb2**2, rig.viscosity
    # approach from a gap of 60 µm along the line of action; read the speed at 12 µm
    th, om = state(rig, [0, 0, -(0.5 * p.play - 60e-6) / p.rb2, 0], [0, 0, -speed / p.rb2, 0])
    traj = simulate([rig], 2.2e-4, burn_in=0.0, step=step, sample_every=1, state=(th, om))
    gap = 0.5 * p.play + traj.x[0]
    k = np.flatnonzero(gap <= 12e-6)[0]
    v = (traj.x[0, k + 1] - traj.x[0, k - 1]) / (2 * step)
    normal = flooded_momentum(gap[k] * cos_bb, mu, lr, reff, a) - flooded_momentum(
        60e-6 * cos_bb, mu, lr, reff, a
    )
    assert speed + v == pytest.approx(cos_bb * normal / mass, rel=2e-3)
    assert 0.05 < cos_bb * normal / mass / speed < 0.9
    # moving off the drive flank from a 3 µm gap: a starved film that would pull hard if it
    # held tension; it cavitates, and the coast flank's film is beyond its oil layer
    rig = bare_rig(
        lubrication="boundary", h_oil=10e-6, table=constant_table(lr=lr, reff=reff), **fixed
    )
    th, om = state(rig, [0, 0, -(0.5 * p.play - 3e-6) / p.rb2, 0], [0, 0, speed / p.rb2, 0])
    traj = simulate([rig], 2e-4, burn_in=0.0, step=1e-6, sample_every=1, state=(th, om))
    np.testing.assert_allclose(np.diff(traj.x[0]) / 1e-6, speed, rtol=1e-9)


def test_the_undamped_chain_keeps_its_energy_through_impacts():
    rig = bare_rig()
    p, step = rig.pair, 1e-6
    th, om = state(rig, [0, 0, 0, 0], [0, 0, 0.2 / p.rb2, 0.2 / p.rb2])
    traj = simulate([rig], 0.01, burn_in=0.0, step=step, sample_every=10, state=(th, om))
    theta, omega = traj.theta[:, 0], traj.omega[:, 0]
    j = np.array([rig.motor_inertia, rig.pinion_inertia, rig.gear_inertia, rig.far_inertia])
    kinetic = 0.5 * (j[:, None] * omega**2).sum(axis=0)
    pen = np.maximum(np.abs(traj.x[0]) - 0.5 * p.play, 0.0)
    potential = (
        0.5 * rig.drive_stiffness * (theta[0] - theta[1]) ** 2
        + 0.5 * rig.shaft_stiffness * (theta[2] - theta[3]) ** 2
        + 0.5 * K0 * pen**2
    )
    energy = kinetic + potential
    contacts = np.count_nonzero(np.diff((pen > 0).astype(int)) == 1)
    assert contacts >= 3
    assert np.ptp(energy) / energy[0] < 2e-3
    assert abs(energy[-50:].mean() / energy[:50].mean() - 1) < 5e-4


def test_a_generated_recording_reads_back_with_the_encoders_quantisation(tmp_path):
    case = next(c for c in validation_set.plan() if c.kinds == ("runout_driven",))
    drawn = validation_set.draw(case)
    assert validation_set.truth_of(drawn) == validation_set.truth_of(validation_set.draw(case))
    name = validation_set.name_of(drawn)
    assert re.fullmatch(r"v2_pairI{1,2}_(dry|boundary|oiljet)_6[56]\.\d_\d+pct_\d+Hz_\d\d", name)
    (rec,), traj = validation_set.simulate_cases([drawn], duration=0.5, burn_in=0.05)
    path = write_recording(rec, tmp_path / f"{name}.h5")
    back = read_recording(path)
    check_recording(back)
    assert back.n_samples == 5000 and back.sample_rate_hz == 1e4 and back.counts_per_rev == 40000
    np.testing.assert_array_equal(back.primary, rec.primary)
    np.testing.assert_array_equal(back.secondary, rec.secondary)
    assert back.gear_pair.angular_backlash_rad == drawn.stated_backlash
    assert back.operating.drive_frequency_hz == drawn.frequency
    for counts, theta, zero in (
        (back.primary, traj.theta[1, 0], drawn.zeros[0]),
        (back.secondary, traj.theta[3, 0], drawn.zeros[1]),
    ):
        fraction = theta * 40000 / (2 * math.pi) - (counts - zero)
        assert fraction.min() >= 0.0 and fraction.max() < 1.0
    true = traj.theta[1, 0] - PAIR.ratio * traj.theta[3, 0]
    error = back.relative_motion - (true - true[0])
    assert np.std(error) == pytest.approx(back.quantisation_std, rel=0.15)


def test_the_set_plan_is_half_clean_and_names_its_verdicts():
    cases = validation_set.plan()
    assert len(cases) >= 40 and sum(not c.kinds for c in cases) == len(cases) // 2
    assert {c.lubrication for c in cases} == {"dry", "boundary", "oil_jet"}
    assert {c.pair for c in cases} == {"I", "II"}
    rng = np.random.default_rng(0)
    effects = [validation_set.drawn_effect(k, rng, PAIR) for k in ("flex", "runout_pinion")]
    assert validation_set.expected(effects) == ["shaft_compliance+runout", "shaft_inertia+runout"]
    assert validation_set.expected(()) == ["none", "unexplained", "model_form"]
