"""The lockstep integrator against closed forms, diffrax and the sharp scipy reference."""

from __future__ import annotations

import itertools

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rattlefit as rf
from rattlefit.features.spectra import BandSpec, spectral_features
from rattlefit.physics.model import RattleModel
from rattlefit.simulation.lockstep import STEP_LIMIT, SUCCESS, solve_lockstep
from rattlefit.simulation.solve import broadcast_params, simulate, simulate_batch

FS = 10_000.0


def _oscillator(t, y, omega):
    return jnp.stack([y[1], -(omega**2) * y[0]])


@pytest.mark.parametrize("rtol", [1e-5, 1e-8])
def test_harmonic_oscillators_of_several_frequencies_match_the_closed_form(rtol):
    # each member its own frequency and start: x = x0 cos ωt + (v0/ω) sin ωt from t0 = -0.1 s
    omega = jnp.asarray([2 * np.pi * 3.0, 2 * np.pi * 40.0, 2 * np.pi * 700.0])
    y0 = jnp.asarray([[1.0, 0.0], [0.5, 20.0], [0.0, -3.0]])
    n = 2000
    ys, _, result = solve_lockstep(
        _oscillator, y0, omega, t0=-0.1, n_samples=n, sample_rate=FS, rtol=rtol, atol=rtol
    )
    assert np.all(np.asarray(result) == SUCCESS)
    t = np.arange(n) / FS + 0.1
    w, x0, v0 = np.asarray(omega)[:, None], np.asarray(y0[:, :1]), np.asarray(y0[:, 1:])
    exact = x0 * np.cos(w * t) + v0 / w * np.sin(w * t)
    amplitude = np.sqrt(x0**2 + (v0 / w) ** 2)
    err = np.max(np.abs(np.asarray(ys[..., 0]) - exact) / amplitude, axis=1)
    # the global error of a tolerance-controlled method grows with the phase travelled (ωT
    # radians, up to 1300 here) ...
    assert np.all(err < 10 * rtol * (1 + np.asarray(omega) * t[-1])), err
    # ... and is that of diffrax's Tsit5 with the same controller, sampled by its own
    # interpolation (the same method, so the same error within a small factor)
    for b in range(3):
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(lambda tt, y, w: _oscillator(tt, y, w)),
            diffrax.Tsit5(),
            t0=-0.1,
            t1=float(t[-1] - 0.1),
            dt0=1e-5,
            y0=y0[b],
            args=omega[b],
            saveat=diffrax.SaveAt(ts=jnp.asarray(t - 0.1)),
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=rtol, pcoeff=0.3, icoeff=0.4),
            max_steps=100_000,
        )
        err_dfx = np.max(np.abs(np.asarray(sol.ys[:, 0]) - exact[b]) / amplitude[b])
        assert err[b] < 5 * err_dfx + 1e-12, (b, err[b], err_dfx)


def test_tighter_tolerance_takes_fifth_order_more_steps():
    # Tsit5 is fifth order: 100× tighter rtol takes about 100^(1/5) ≈ 2.5× more steps, and
    # the error falls with the tolerance
    omega = jnp.asarray([2 * np.pi * 50.0])
    y0 = jnp.asarray([[1.0, 0.0]])
    t = np.arange(3000) / FS + 0.05
    errs, steps = [], []
    for rtol in (1e-6, 1e-8, 1e-10):
        ys, n, _ = solve_lockstep(
            _oscillator, y0, omega, t0=-0.05, n_samples=3000, sample_rate=FS, rtol=rtol, atol=rtol
        )
        errs.append(np.max(np.abs(np.asarray(ys[0, :, 0]) - np.cos(2 * np.pi * 50.0 * t))))
        steps.append(int(n[0]))
    assert errs[0] > 10 * errs[1] > 100 * errs[2], errs
    for coarse, fine in itertools.pairwise(steps):
        assert 1.8 < fine / coarse < 3.5, steps


def test_absolute_tolerance_may_differ_between_state_components():
    # x = cos ωt: the velocity is ω = 314 times the position, so the same absolute tolerance on
    # both holds the velocity 314 times tighter relative to its size. A pair (a, a) is the
    # scalar a exactly; loosening the velocity's alone takes fewer steps than holding both and
    # more than loosening both, and the position's error stays that of its own tolerance's order
    omega = jnp.asarray([2 * np.pi * 50.0])
    y0 = jnp.asarray([[1.0, 0.0]])
    t = np.arange(3000) / FS + 0.05
    kw = dict(t0=-0.05, n_samples=3000, sample_rate=FS, rtol=1e-14)
    out = {}
    for atol in (1e-8, (1e-8, 1e-8), (1e-8, 314e-8), (314e-8, 314e-8)):
        ys, n, result = solve_lockstep(_oscillator, y0, omega, atol=atol, **kw)
        assert int(result[0]) == SUCCESS
        err = np.max(np.abs(np.asarray(ys[0, :, 0]) - np.cos(2 * np.pi * 50.0 * t)))
        out[atol] = (np.asarray(ys), int(n[0]), err)
    np.testing.assert_array_equal(out[1e-8][0], out[(1e-8, 1e-8)][0])
    tight, mixed, loose = (out[k] for k in ((1e-8, 1e-8), (1e-8, 314e-8), (314e-8, 314e-8)))
    assert tight[1] > mixed[1] > loose[1], (tight[1], mixed[1], loose[1])
    assert tight[2] < mixed[2] < loose[2], (tight[2], mixed[2], loose[2])


def test_members_do_not_depend_on_their_batch():
    omega = jnp.asarray([2 * np.pi * 3.0, 2 * np.pi * 700.0, 2 * np.pi * 40.0])
    y0 = jnp.asarray([[1.0, 0.0], [0.0, -3.0], [0.5, 20.0]])
    kw = dict(t0=-0.1, n_samples=500, sample_rate=FS, rtol=1e-7, atol=1e-7)
    both, _, _ = solve_lockstep(_oscillator, y0, omega, **kw)
    alone, _, _ = solve_lockstep(_oscillator, y0[1:2], omega[1:2], **kw)
    np.testing.assert_allclose(np.asarray(both[1]), np.asarray(alone[0]), rtol=0, atol=1e-12)


def test_failures_are_reported_not_hidden():
    omega = jnp.asarray([2 * np.pi * 3.0, 2 * np.pi * 700.0])
    y0 = jnp.asarray([[1.0, 0.0], [0.0, -3.0]])
    # the fast member needs more steps than the budget; the slow one does not
    ys, steps, result = solve_lockstep(
        _oscillator,
        y0,
        omega,
        t0=0.0,
        n_samples=3000,
        sample_rate=FS,
        rtol=1e-8,
        atol=1e-8,
        max_steps=400,
    )
    assert np.asarray(result).tolist() == [SUCCESS, STEP_LIMIT]
    assert int(steps[1]) == 400
    assert np.all(np.isfinite(np.asarray(ys)))

    def blows_up(t, y, _):  # non-finite after t = 0.01 s: every step is rejected
        return jnp.where(t > 0.01, jnp.nan, 1.0) * jnp.ones_like(y)

    ys, _, result = solve_lockstep(
        blows_up,
        y0,
        omega,
        t0=0.0,
        n_samples=300,
        sample_rate=FS,
        rtol=1e-6,
        atol=1e-6,
        max_steps=2000,
    )
    assert np.all(np.asarray(result) == STEP_LIMIT)
    assert np.all(np.isfinite(np.asarray(ys)))


def test_rattle_agrees_with_diffrax_before_chaos_parts_them(pair2):
    # 20 ms of rattle with impacts: the trajectories of two accurate solvers agree closely
    # before the chaos separates them (later only statistics can be compared)
    model = RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.47, 16.0)
    params = broadcast_params(rf.RattleParams([8.5e-5, 1e-3], 0.025, 0.49, pair2.backlash), 2)
    y0 = jnp.asarray([[-0.4 * pair2.backlash, 0.0], [0.3 * pair2.backlash, 0.0]])
    kw = dict(y0=y0, duration=0.02, burn_in=0.01, rtol=1e-9, atol=1e-12)
    lock = simulate_batch(model, params, drive, batch="lockstep", **kw)
    ref = simulate_batch(model, params, drive, batch="map", **kw)
    assert np.all(np.asarray(lock.success))
    scale = 0.5 * pair2.backlash
    assert np.max(np.abs(np.asarray(lock.q) - np.asarray(ref.q))) < 1e-4 * scale
    # the run did rattle: the gear crossed most of the backlash
    assert np.ptp(np.asarray(ref.q)) > 0.5 * scale


def test_drive_angle_and_acceleration_equal_the_series(pair2):
    d = rf.Drive(52.36, 16.0, [0.01, -0.002, 3e-4], [0.004, 1e-3, -2e-4], offset=0.3)
    t = jnp.linspace(0.0, 0.5, 101)
    angle, acc = jax.vmap(d.angle_and_acceleration)(t)
    np.testing.assert_allclose(angle, jax.vmap(d.angle)(t), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(acc, jax.vmap(d.acceleration)(t), rtol=1e-11, atol=1e-9)


def test_only_the_film_ahead_of_the_motion_resists(pair2):
    # the paper's eq. (3): S(x)·ẋ with x the gap the motion closes
    model = RattleModel.from_geometry(pair2)
    params = rf.RattleParams(8.5e-5, 0.025, 0.49, pair2.backlash)
    drive = rf.Drive.commanded(52.36, 10.47, 16.0)
    c = 0.5 * pair2.backlash
    for q, v in [(0.2 * c, 0.05), (0.2 * c, -0.05), (-0.7 * c, 0.3), (0.9 * c, -0.3)]:
        _, f_sq = model.forces(0.0, q, v, params, drive)
        closing = c - q if v > 0 else c + q
        expected = -float(model.squeeze(closing, params)) * v
        assert float(f_sq) == pytest.approx(expected, rel=1e-9)


def test_single_simulation_is_unchanged_in_statistics(pair2):
    # simulate() stays on diffrax; the lockstep batch gives the same band features within
    # their chaotic spread (8 realisations each, violent rattle)
    model = RattleModel.from_geometry(pair2)
    drive = rf.Drive.commanded(52.36, 10.47, 16.0)
    p = rf.RattleParams(8.5e-5, 0.025, 0.49, pair2.backlash)
    b = 8
    frac = np.linspace(-0.45, 0.45, b)
    y0 = jnp.stack([jnp.asarray(frac) * pair2.backlash, jnp.zeros(b)], axis=1)
    bands = BandSpec.for_recording(FS)
    feats = {}
    for mode in ("lockstep", "map"):
        sol = simulate_batch(
            model,
            broadcast_params(p, b),
            drive,
            y0=y0,
            batch=mode,
            duration=1.5,
            rtol=1e-5,
            atol=1e-8,
        )
        feats[mode] = np.asarray(spectral_features(sol.relative_motion, bands))
    single = simulate(model, p, drive, y0=y0[0], duration=1.5, rtol=1e-5, atol=1e-8)
    assert bool(single.success)
    a, m = feats["lockstep"], feats["map"]
    se = np.sqrt((a.var(0) + m.var(0)) / b + 0.03**2)
    z = (a.mean(0) - m.mean(0)) / se
    assert np.sqrt(np.mean(z**2)) < 2.0, z


def test_dense_output_is_diffraxs_tsit5_interpolation():
    # the monomial (Horner) form of the interpolant against diffrax's factored polynomials
    from diffrax._solver.tsit5 import _Tsit5Interpolation

    from rattlefit.simulation.lockstep import dense_output

    rng = np.random.default_rng(5)
    y0 = rng.normal(size=(4, 2))
    k = rng.normal(size=(4, 7, 2))
    h = np.array([1e-4, 3e-3, 0.5, 2.0])
    s = rng.uniform(0, 1, size=(4, 9))
    got = np.asarray(
        dense_output(
            jnp.asarray(y0), [jnp.asarray(h[:, None] * k[:, i]) for i in range(7)], jnp.asarray(s)
        )
    )
    for b in range(4):
        interp = _Tsit5Interpolation(
            t0=0.0, t1=h[b], y0=jnp.asarray(y0[b]), y1=None, k=jnp.asarray(h[b] * k[b])
        )
        want = np.stack([np.asarray(interp.evaluate(sk * h[b])) for sk in s[b]])
        scale = np.abs(y0[b]) + h[b] * np.abs(k[b]).sum(axis=0)
        assert np.all(np.abs(got[b] - want) <= 1e-13 * scale), (b, got[b] - want)
