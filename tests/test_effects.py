"""The effects catalogue against closed forms: each effect's hook, through the simulator."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rattlefit as rf
from rattlefit.physics import effects as fx

STEADY = dict(burn_in=0.0, rtol=1e-10, atol=1e-15)


def _steady_drive(speed=52.36):
    """Constant primary speed (no fluctuation): θ1 = Ω t."""
    return rf.Drive.commanded(speed, 0.0, 8.0)


def _resting(model, drive, params, *, duration, rate, y0):
    """Resting on the drive flank from ``y0``, sampled at ``rate``. The contact has no
    damping, so a release off the static deflection rings for ever: ``y0`` must be it."""
    return rf.simulate(model, params, drive, duration=duration, sample_rate=rate, y0=y0, **STEADY)


DRAG = 0.05  # N m: far above the rattle threshold of a steady drive, and a tiny deflection
#: Resting on a flank, the undamped contact rings at every change of K(θ1), and the smoothed
#: contact law rests at a gap of ~ contact_width: a sharp contact and slowly varying windows
#: make the static deflection exact to within a few per cent of itself.
RESTING = rf.Smoothing(contact_width=1e-10, mesh_width=0.3)


def _static(pair2, model, theta1, extra_compliance=0.0):
    """The drive flank's static deflection under DRAG: q + c = −F (1/K(θ1) + compliance)."""
    force = DRAG / pair2.pitch_radius_driven
    k = np.asarray([float(model.mesh_stiffness(t)) for t in np.atleast_1d(theta1)])
    return -0.5 * pair2.backlash - force * (1 / k + extra_compliance)


def test_runout_moves_the_resting_flank_with_each_wheel(pair2):
    # Under a steady drive the driven wheel rests on the drive flank at its static
    # deflection; with run-out the flank, and the wheel with it, moves by the gap error
    # e1 sin θ1 + e2 sin(θ1 r1/r2), up to m·ë/K (≈1e-10 m here).
    omega = 52.36
    drive = _steady_drive(omega)
    params = rf.RattleParams(0.0, DRAG, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2, smoothing=RESTING)
    e1, e2 = 8e-6, 5e-6
    r = pair2.pitch_radius_driving / pair2.pitch_radius_driven
    q0 = float(_static(pair2, model, 0.0)[0])
    opts = dict(duration=0.3, rate=2000.0)
    plain = _resting(model, drive, params, y0=[q0, 0.0], **opts)
    runout = fx.Runout(driving_amplitude=e1, driven_amplitude=e2)
    moving = [q0, omega * (e1 + e2 * r)]  # the flank's velocity at t = 0
    moved = _resting(model.with_effects(runout), drive, params, y0=moving, **opts)
    theta1 = np.asarray(plain.theta1)
    np.testing.assert_allclose(np.asarray(plain.q), _static(pair2, model, theta1), atol=3e-9)
    expected = e1 * np.sin(theta1) + e2 * np.sin(theta1 * r)
    np.testing.assert_allclose(np.asarray(moved.q) - np.asarray(plain.q), expected, atol=1e-8)


def test_tooth_errors_repeat_once_per_driving_tooth(pair2):
    omega, amp = 5.0, 2e-6  # slow, so that the mesh order is resolved
    drive = _steady_drive(omega)
    params = rf.RattleParams(0.0, DRAG, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2, smoothing=RESTING)
    z1 = pair2.teeth_driving
    q0 = float(_static(pair2, model, 0.0)[0])
    opts = dict(duration=0.2, rate=5000.0)
    plain = _resting(model, drive, params, y0=[q0, 0.0], **opts)
    errors = model.with_effects(fx.ToothErrors(amplitude=amp))
    moved = _resting(errors, drive, params, y0=[q0, amp * z1 * omega], **opts)
    theta1 = np.asarray(plain.theta1)
    expected = amp * np.sin(theta1 * z1)
    np.testing.assert_allclose(np.asarray(moved.q) - np.asarray(plain.q), expected, atol=1e-8)


def test_tooth_defect_moves_the_resting_flank_once_per_revolution(pair2):
    # Resting on the drive flank under a steady drive, a notch of depth d on one driving tooth
    # moves the flank, and the wheel with it, by −d·b(θ1): b the raised cosine over one base
    # pitch about θ1 ≡ position (mod 2π), so only while that tooth is in mesh, once per
    # revolution of the driving wheel, up to m·q̈/K (≈1e-9 m here). The flank retreats at
    # most at d (π/L)² Ω²/2 ≈ 0.5 m/s², L = Θp/2, below the drag's 2.5 m/s²: the wheel follows.
    omega, depth, position, atol = 52.36, 1e-6, 2.0, 1e-8
    drive = _steady_drive(omega)
    params = rf.RattleParams(0.0, DRAG, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2, smoothing=RESTING)
    q0 = float(_static(pair2, model, 0.0)[0])
    opts = dict(duration=0.3, rate=20000.0, y0=[q0, 0.0])
    plain = _resting(model, drive, params, **opts)
    defect = fx.ToothDefect(depth=depth, position=position)
    moved = _resting(model.with_effects(defect), drive, params, **opts)
    theta1 = np.asarray(plain.theta1)
    x = np.mod(theta1 - position + np.pi, 2 * np.pi) - np.pi
    half = 0.5 * pair2.base_pitch_angle
    bump = np.where(np.abs(x) < half, 0.5 * (1 + np.cos(np.pi * x / half)), 0.0)
    shift = np.asarray(moved.q) - np.asarray(plain.q)
    np.testing.assert_allclose(shift, -depth * bump, rtol=0, atol=atol)
    # met once in each of the 2.5 revolutions, at the defect tooth only
    revolution = np.round((theta1 - position) / (2 * np.pi))
    assert np.unique(revolution[bump > 0.5]).size == 3
    assert np.all(np.abs(shift[bump == 0.0]) < atol)
    assert np.abs(shift).max() > 0.99 * depth


def test_shaft_compliance_adds_its_deflection_in_series(pair2):
    # Two springs in series under the drag force F = T_b/r2: q + c = −F (1/K(θ1) + compliance).
    drive = _steady_drive()
    params = rf.RattleParams(0.0, DRAG, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2, smoothing=RESTING)
    compliance = 1e-7
    q0 = float(_static(pair2, model, 0.0, compliance)[0])
    soft = model.with_effects(fx.ShaftCompliance(compliance=compliance))
    sol = _resting(soft, drive, params, y0=[q0, 0.0], duration=0.1, rate=2000.0)
    expected = _static(pair2, model, np.asarray(sol.theta1), compliance)
    np.testing.assert_allclose(np.asarray(sol.q), expected, rtol=0, atol=3e-9)
    # the compliance's share of the deflection is far above the tolerance
    assert DRAG / pair2.pitch_radius_driven * compliance > 30 * 3e-9


V_IMPACT = 0.2  # m/s


def _impact(pair2, effect, v0=V_IMPACT, smoothing=None):
    """Released mid-gap at ``v0`` towards the coast flank with the primary at rest: dry, no
    drag, constant mesh stiffness K(0). Returns (q, v) sampled at 1 MHz for 6 ms."""
    drive = rf.Drive(0.0, 8.0, [0.0], [0.0])
    params = rf.RattleParams(0.0, 0.0, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2, smoothing=smoothing)
    if effect is not None:
        model = model.with_effects(effect)
    sol = rf.simulate(model, params, drive, duration=6e-3, sample_rate=1e6, y0=[0.0, v0], **STEADY)
    return np.asarray(sol.q), np.asarray(sol.velocity)


@pytest.mark.parametrize("mu", [0.0, 0.15, 0.4])
def test_flank_friction_gives_the_coulomb_restitution(pair2, mu):
    # A linear contact with Coulomb friction μ|F| against the motion: the spring is stiffer
    # by (1+μ) while compressing and softer by (1−μ) while rebounding, so the rebound speed is
    # v0·√((1−μ)/(1+μ)); without friction the model's contact is perfectly elastic.
    q, v = _impact(pair2, fx.FlankFriction(coefficient=mu) if mu else None)
    c = 0.5 * pair2.backlash
    assert q.max() > c  # it did hit the coast flank
    back = np.flatnonzero((np.arange(q.size) > np.argmax(q)) & (q < 0.5 * c))[0]
    restitution = -v[back] / V_IMPACT
    assert restitution == pytest.approx(math.sqrt((1 - mu) / (1 + mu)), rel=0.01)


def _restitution(pair2, q, v):
    """The rebound speed over the impact speed of an :func:`_impact`."""
    c = 0.5 * pair2.backlash
    assert q.max() > c  # it did hit the coast flank
    back = np.flatnonzero((np.arange(q.size) > np.argmax(q)) & (q < 0.5 * c))[0]
    return -v[back] / V_IMPACT


@pytest.mark.parametrize("zeta", [0.05, 0.25])
def test_mesh_damping_gives_the_spring_dashpot_restitution(pair2, zeta):
    # A sharp linear contact with a dashpot in parallel, switched on and off at the flank, is
    # half a period of a damped oscillator: e = exp(−ζ'π/√(1−ζ'²)). The primary at rest holds
    # the spring at K(0), while c_m = 2ζ√(K̄ m) takes the mean stiffness K̄ over a mesh cycle,
    # so against K(0) the damping ratio is ζ' = ζ√(K̄/K(0)).
    sharp = rf.Smoothing(contact_width=1e-10)
    model = rf.RattleModel.from_geometry(pair2, smoothing=sharp)
    theta = np.linspace(0.0, pair2.base_pitch_angle, 4096, endpoint=False)
    k_mean = float(np.mean(jax.vmap(model.mesh_stiffness)(jnp.asarray(theta))))
    ratio = zeta * math.sqrt(k_mean / float(model.mesh_stiffness(0.0)))
    assert ratio > 1.05 * zeta  # K(0) is the cycle's least stiffness: the ratio is seen
    q, v = _impact(pair2, fx.MeshDamping(damping_ratio=zeta), smoothing=sharp)
    expected = math.exp(-ratio * math.pi / math.sqrt(1 - ratio**2))
    assert _restitution(pair2, q, v) == pytest.approx(expected, rel=1e-3)


def test_pitch_point_friction_reverses_at_the_pitch_point(pair2):
    # Resting on the drive flank, the contact force F balances the drag and the friction
    # μ F g: F (1 + μ g) = T_b/r2, so q = −c − T_b / (r2 K(θ1) (1 + μ g(s))), with
    # g(s) = tanh((s − s_p)/w) tanh(sin(πs)/(πw)) and s = θ1/Θp mod 1: the friction holds the
    # driven wheel back (a deeper deflection) before the pitch point s_p and pulls it forward
    # after it, reversing once per mesh cycle at s_p (and back at the hand-over, s = 0).
    omega, mu, s_p, w, drag = 5.0, 0.3, 0.3, 0.05, 2.0  # slow: the wheel follows quasi-statically
    drive = _steady_drive(omega)
    params = rf.RattleParams(0.0, drag, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2, smoothing=RESTING)
    friction = fx.PitchPointFriction(coefficient=mu, pitch_point=s_p, width=w)
    c, force = 0.5 * pair2.backlash, drag / pair2.pitch_radius_driven

    def g(theta1):
        s = np.mod(theta1 / pair2.base_pitch_angle, 1.0)
        return np.tanh((s - s_p) / w) * np.tanh(np.sin(np.pi * s) / (np.pi * w))

    def resting(theta1, mu):
        k = np.asarray([float(model.mesh_stiffness(x)) for x in np.atleast_1d(theta1)])
        return -c - force / (k * (1 + mu * g(theta1)))

    h = 1e-6  # rad: the resting curve's slope at θ1 = 0 gives the release velocity
    v0 = omega * float(resting(h, mu)[0] - resting(-h, mu)[0]) / (2 * h)
    sol = _resting(
        model.with_effects(friction),
        drive,
        params,
        duration=0.2,
        rate=5000.0,
        y0=[float(resting(0.0, mu)[0]), v0],
    )
    theta1, q = np.asarray(sol.theta1), np.asarray(sol.q)
    np.testing.assert_allclose(q, resting(theta1, mu), rtol=0, atol=1e-9)
    # the friction's share of the deflection: deeper before s_p, shallower after
    share = q - resting(theta1, 0.0)
    s = np.mod(theta1 / pair2.base_pitch_angle, 1.0)
    assert np.abs(share).max() > 100 * 1e-9  # far above the tolerance
    assert np.all(share[(s > 2 * w) & (s < s_p - 2 * w)] < 0)
    assert np.all(share[(s > s_p + 2 * w) & (s < 1 - 2 * w)] > 0)
    rising = np.flatnonzero((share[:-1] < 0) & (share[1:] >= 0))
    cycles = np.floor(theta1 / pair2.base_pitch_angle - s_p)
    assert rising.size == cycles[-1] - cycles[0] >= 2  # once per mesh cycle ...
    assert np.all(
        np.abs(s[rising] - s_p) < 2 * omega / 5000.0 / pair2.base_pitch_angle
    )  # ... at s_p


def test_pitch_point_friction_vanishes_apart(pair2):
    # Out of contact F_mesh is zero, and so is the friction: the vector field is the plain one.
    drive = _steady_drive()
    params = rf.RattleParams(0.0, DRAG, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2)
    rubbing = model.with_effects(fx.PitchPointFriction(coefficient=0.5))
    c = 0.5 * pair2.backlash
    for t in np.linspace(0.0, pair2.base_pitch_angle / 52.36, 7):
        for q in (-0.9 * c, 0.0, 0.9 * c):
            y = jnp.asarray([q, 0.05])
            want = model.vector_field(t, y, (params, drive))
            np.testing.assert_array_equal(rubbing.vector_field(t, y, (params, drive)), want)


def test_speed_dependent_drag_relaxes_the_flight_speed_exponentially(pair2):
    # In free flight at constant primary speed, m v̇ = −T_b/r2 − k v / r2²:
    # v(t) = v∞ + (v0 − v∞) e^{−t/τ}, τ = m r2²/k, v∞ = −T_b r2 / k.
    k, tb, v0 = 0.5, 0.01, 0.02
    drive = _steady_drive()
    params = rf.RattleParams(0.0, tb, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2).with_effects(fx.SpeedDependentDrag(coefficient=k))
    sol = rf.simulate(model, params, drive, duration=3e-3, sample_rate=1e5, y0=[0.0, v0], **STEADY)
    t, q = np.asarray(sol.time), np.asarray(sol.q)
    assert np.max(np.abs(q)) < 0.4 * pair2.backlash  # no contact in the window
    r2, m = pair2.pitch_radius_driven, float(model.mass)
    tau, v_inf = m * r2**2 / k, -tb * r2 / k
    expected = v_inf + (v0 - v_inf) * np.exp(-t / tau)
    assert tau < 3e-3  # the window sees the relaxation
    np.testing.assert_allclose(np.asarray(sol.velocity), expected, rtol=1e-6, atol=1e-9)


def test_drive_ripple_forces_the_flight_at_its_order(pair2):
    # In free flight: m v̇ = −T_b/r2 − m r1 α sin(2Ωt + φ), integrated in closed form.
    alpha, phase, omega, tb, v0 = 2000.0, 0.3, 52.36, 0.01, 0.005
    drive = _steady_drive(omega)
    params = rf.RattleParams(0.0, tb, 0.49, pair2.backlash)
    ripple = fx.DriveRipple(amplitude=alpha, phase=phase)
    model = rf.RattleModel.from_geometry(pair2).with_effects(ripple)
    sol = rf.simulate(model, params, drive, duration=4e-3, sample_rate=1e5, y0=[0.0, v0], **STEADY)
    t, q = np.asarray(sol.time), np.asarray(sol.q)
    assert np.max(np.abs(q)) < 0.4 * pair2.backlash
    m, r1, r2 = float(model.mass), pair2.pitch_radius_driving, pair2.pitch_radius_driven
    w = ripple.order * omega
    expected = v0 - tb / (m * r2) * t + r1 * alpha / w * (np.cos(w * t + phase) - np.cos(phase))
    np.testing.assert_allclose(np.asarray(sol.velocity), expected, rtol=0, atol=1e-9)


def test_viscosity_drift_scales_the_squeeze_force_in_time(pair2):
    # The vector field with the drift at time t is the plain one at viscosity μ e^{−rate t}.
    drive = rf.Drive.commanded(52.36, 10.0, 16.0)
    model = rf.RattleModel.from_geometry(pair2)
    drifting = model.with_effects(fx.ViscosityDrift(rate=0.4))
    y = jnp.asarray([0.2 * pair2.backlash, 0.03])  # approaching the coast flank
    for t in (0.0, 0.7, 2.5):
        mu = 0.49 * math.exp(-0.4 * t)
        want = model.vector_field(t, y, (rf.RattleParams(1e-4, 0.02, mu, pair2.backlash), drive))
        got = drifting.vector_field(
            t, y, (rf.RattleParams(1e-4, 0.02, 0.49, pair2.backlash), drive)
        )
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-12)


@pytest.mark.parametrize("name", sorted(fx.EFFECTS))
def test_absent_effects_leave_the_vector_field_alone(pair2, name):
    # At the lower end of its range an effect changes the acceleration, anywhere along a
    # rattle trajectory, by less than 1e-3 of the drag's plus 1e-4 of the acceleration.
    # (Trajectories cannot be compared: rattle is chaotic, and any change grows.)
    drive = rf.Drive.commanded(52.36, 10.472, 16.0)
    params = rf.RattleParams(0.085e-3, 0.02, 0.49, pair2.backlash)
    model = rf.RattleModel.from_geometry(pair2)
    options = dict(duration=0.2, sample_rate=1e5, burn_in=0.0, rtol=1e-8, atol=1e-12)
    sol = rf.simulate(model, params, drive, **options)
    plain_states = jnp.stack([sol.q, sol.velocity], axis=1)

    def acceleration(m):
        # along the plain trajectory; an effect with a state of its own along its own, where
        # that state has the values the effect gives it (the plain model sees (q, v) alone)
        states = plain_states if m.state_size == 2 else full_states(m, params, drive, options)
        at = lambda t, y: m.vector_field(t, y, (params, drive))[1]  # noqa: E731
        return np.asarray(jax.vmap(at)(sol.time, states)), states

    plain, _ = acceleration(model)
    assert np.abs(plain).max() > 100 * 0.02 / pair2.pitch_radius_driven / float(model.mass)
    drag = 0.02 / pair2.pitch_radius_driven / float(model.mass)
    changed, states = acceleration(model.with_effects(fx.absent(name)))
    if states.shape[1] > 2:
        plain, _ = acceleration_at(model, params, drive, sol.time, states[:, :2])
    assert np.all(np.abs(changed - plain) < 1e-3 * drag + 1e-4 * np.abs(plain))
    # ... while halfway up its (log) range it does matter
    cls = type(fx.absent(name))
    some = cls(**{k: lo * (hi / lo) ** 0.5 for k, (_, lo, hi) in cls.ranges.items()})
    changed, states = acceleration(model.with_effects(some))
    plain, _ = acceleration_at(model, params, drive, sol.time, states[:, :2])
    assert np.any(np.abs(changed - plain) > 1e-2 * drag)
    for field, (unit, lo, hi) in cls.ranges.items():
        assert float(getattr(fx.absent(name), field)) == lo < hi
        assert unit
    # its size (the first ranged field) has a physical reference inside its range, and the
    # smallest size a diagnosis names lies well (a decade and more) above the absent end
    from rattlefit.diagnosis.size import relevance_floor

    (_, lo, hi), (typical, source) = next(iter(cls.ranges.values())), cls.typical
    assert 10 * lo <= relevance_floor(name) < typical < hi and source


def acceleration_at(model, params, drive, ts, states):
    """The model's acceleration at each state (rows) and time."""
    at = lambda t, y: model.vector_field(t, y, (params, drive))[1]  # noqa: E731
    return np.asarray(jax.vmap(at)(ts, states)), states


def full_states(model, params, drive, options):
    """The whole state (q, v and the effects' own components) along the model's trajectory
    from rest on the drive flank, sampled as ``rf.simulate`` samples (which returns q and v
    alone)."""
    import diffrax

    ts = jnp.arange(round(options["duration"] * options["sample_rate"])) / options["sample_rate"]
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(model.vector_field),
        diffrax.Tsit5(),
        t0=0.0,
        t1=float(ts[-1]),
        dt0=1e-6,
        y0=model.full_state(jnp.array([-0.5 * float(params.backlash), 0.0])),
        args=(params, drive),
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=options["rtol"], atol=options["atol"]),
        max_steps=2_000_000,
    )
    return sol.ys


@pytest.mark.parametrize("fluctuation", [0.0, 0.02])
def test_shaft_inertia_rings_at_its_mode_and_keeps_the_momentum(pair2, fluctuation):
    # With the mesh open (the gear mid-backlash, no film, no drag) the gear and the shaft's
    # inertia are two free masses on a spring, whatever the drive does. Started both at the
    # drive's initial speed U = r1 θ̇1(0), the shaft deflected by φ0, their deflection φ rings
    # at f√(1 − ζ²) and decays at ζ·2πf, and the momentum stays that of the mass centre, so
    # the gear's absolute position is x_g(0) + U t − m_s/(m + m_s) · (φ − φ0), and
    # q = x_g − r1 θ1 is a closed form through the simulator. A fluctuating drive (small
    # enough to keep the mesh open) moves q by r1 (θ1(0) + θ̇1(0) t − θ1(t)).
    ratio, f, zeta = 1.0, 350.0, 0.02
    shaft = fx.ShaftInertia(inertia_ratio=ratio, frequency=f, damping_ratio=zeta)
    model = rf.RattleModel.from_geometry(pair2).with_effects(shaft)
    params = rf.RattleParams(0.0, 0.0, 0.49, pair2.backlash)
    drive = rf.Drive.commanded(52.36, fluctuation, 16.0)
    phi0 = 0.3 * pair2.backlash  # the gear then moves by at most 0.3 of half the backlash
    # the state (u, u̇) = s (φ + q, φ̇ + v), s = r/(1 + r), at q = v = 0 (both at the
    # drive's speed)
    share = ratio / (1 + ratio)
    y0 = [0.0, 0.0, share * phi0, 0.0]
    sol = rf.simulate(model, params, drive, duration=0.02, sample_rate=1e5, y0=y0, **STEADY)
    t = np.asarray(sol.time)
    w = 2 * math.pi * f
    wd = w * math.sqrt(1 - zeta**2)
    phi = (
        phi0
        * np.exp(-zeta * w * t)
        * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * t))
    )
    r1 = float(model.r1)
    theta1 = np.asarray(jax.vmap(drive.angle)(sol.time))
    rigid = r1 * (float(drive.angle(0.0)) + float(drive.speed(0.0)) * t - theta1)
    q = rigid - ratio / (1 + ratio) * (phi - phi0)
    np.testing.assert_allclose(np.asarray(sol.q), q, rtol=0, atol=1e-6 * phi0)
    assert np.ptp(q) > 0.5 * phi0  # it did ring
    if fluctuation:  # the drive did move it, by far more than the tolerance
        assert np.ptp(rigid) > 1e-2 * phi0
    assert np.max(np.abs(q)) < 0.5 * float(pair2.backlash)  # the mesh stayed open
    assert model.state_size == 4
    assert model.state_atol((1e-12, 1e-9)) == (1e-12, 1e-9, 1e-12, 1e-9)


def test_shaft_inertia_starts_undeflected():
    shaft = fx.ShaftInertia(inertia_ratio=3.0)  # s = 3/4
    y = (
        rf.RattleModel.from_geometry(rf.table2_pair("II"))
        .with_effects(shaft)
        .full_state(jnp.array([[1e-5, 0.2], [-2e-5, 0.0]]))
    )
    np.testing.assert_allclose(np.asarray(y[:, 2:]), 0.75 * np.asarray(y[:, :2]), rtol=1e-15)
    # a batch of shafts (one per row, as a lockstep batch holds them)
    shafts = fx.ShaftInertia(inertia_ratio=jnp.array([3.0, 1.0]))
    y = (
        rf.RattleModel.from_geometry(rf.table2_pair("II"))
        .with_effects(shafts)
        .full_state(jnp.array([[1e-5, 0.2], [-2e-5, 0.1]]))
    )
    np.testing.assert_allclose(np.asarray(y[:, 2:]), [[0.75e-5, 0.15], [-1e-5, 0.05]], rtol=1e-15)


def test_unknown_effect_names_the_known_ones():
    with pytest.raises(rf.RattlefitError, match="runout"):
        fx.effect_class("eccentricity")


def test_replace_sets_fields_and_keeps_the_rest():
    e = fx.Runout(driving_amplitude=1e-6, driving_phase=0.5)
    f = e.replace(driven_amplitude=2e-6)
    assert float(f.driven_amplitude) == 2e-6
    assert float(f.driving_amplitude) == 1e-6 and float(f.driving_phase) == 0.5
    assert float(e.driven_amplitude) == 0.0  # immutable
