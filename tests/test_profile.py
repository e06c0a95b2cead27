"""The profile-likelihood machinery of :mod:`rattlefit.inference.profile` against closed forms.

Each test builds a profile whose exact interval is known (a quadratic, a valley of known
shape with noise of known spread) and checks the stage that should find it: the threshold's
coverage of noisy profiles, bisection of a coarse scan's brackets, the polish's descent to
the profile minimum, the continuation along a bent valley, the rivals and the re-centring.
The fits that use them on simulated recordings are in test_fit.py.
"""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import brentq

from rattlefit.inference.profile import (
    PROFILE_JITTER,
    PROFILE_MIN_STEP,
    PROFILE_RESOLUTION,
    admit_rivals,
    bisect_profile_ends,
    continue_profiles,
    keep_lower,
    lower_profile_point,
    polish_profile,
    profile_guesses,
    profile_interval,
    profile_threshold,
    span_profile_points,
    threshold_crossing,
)

# Seeds of the Monte Carlo profiles.
NOISY_PROFILES_SEED = 7  # estimates and cost noise of 1000 scanned profiles
JITTER_SETS_SEED = 3  # the noise on 200 sets of jitter Δcosts

# Margins.
#: the share of 1000 noisy profiles whose interval must hold the truth: the aim 95 % less
#: three binomial sd (0.7 % each); with the roughness allowance the intervals are wider
COVERAGE = {"analytic": 0.93, "rough": 0.98}
NOISE_SD_TOLERANCE = 0.05  # the noise sd recovered from 200 sets
PAIR_VARIANCE_TOLERANCE = 0.15  # the mean square of 100 two-set estimates (χ²₁ scatter)
VALLEY_END_TOLERANCE = 0.1  # an end found along the bent valley, against the exact one
SHORT_OF_THE_END = 0.85  # the straight scan stops short of the exact ends, inside this share
WAVY_END_TOLERANCE = 0.05  # an end found along the wavy valley with the physics' hook


def test_threshold_crossing_interpolates_the_profile():
    ts = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
    dc = ts**2  # a quadratic profile: Δcost = 3 is crossed at ±√3
    assert threshold_crossing(ts, dc, 3, 4, 3.0) == pytest.approx(1.0 + (3 - 1) / 3)
    assert threshold_crossing(ts, dc, 1, 0, 3.0) == pytest.approx(-1.0 - (3 - 1) / 3)
    assert threshold_crossing(ts, dc, 4, 5, 3.0) == 2.0  # no value outside: the last inside


def _valley(points):
    # a curved valley: with z0 fixed at t the other coordinates can zero their rows, so the
    # profile cost is (t − 0.3)² exactly
    z0, z1, z2 = points.T
    return np.stack([(z1 - 2 * np.sin(z0)) / 0.05, z0 - 0.3, (z2 - z0**2) / 0.1], axis=1)


def test_polish_profile_reaches_the_profile_minimum():
    calls = []

    def residuals(points):
        calls.append(points.shape)
        return _valley(points)

    starts = np.array([[1.5, 0.0, 0.0], [-1.0, 0.5, 2.0], [0.3, 2 * np.sin(0.3), 0.09]])
    ends = polish_profile(residuals, starts, [0, 0, 0], np.full((3, 3), 1e-4), iterations=2)
    cost = np.sum(_valley(ends) ** 2, axis=1)
    assert cost == pytest.approx((starts[:, 0] - 0.3) ** 2, abs=5e-3)
    assert np.array_equal(ends[:, 0], starts[:, 0])  # the profiled coordinate stays fixed
    assert np.allclose(ends[2], starts[2])  # already at the profile minimum: not moved
    # batched contract: per iteration one call with each point and its differences along the
    # free coordinates only (3 × (1 + 2)), one with the trials (3 × 3 damping values)
    assert calls == [(9, 3), (9, 3), (9, 3), (9, 3)]
    # the scan's guess (the others unchanged) overstates the profile cost by orders of magnitude
    assert np.sum(_valley(starts[:1]) ** 2) > 100 * cost[0]


def test_profile_interval_spans_values_below_the_threshold():
    z = np.zeros(2)
    prof = {t: (t**2, z) for t in (-3.0, -2.0, -1.0, 0.0, 1.0, 2.0)}
    (lo, hi), brackets = profile_interval(prof, 3.0)
    assert (lo, hi) == pytest.approx((-1.0 - 2 / 3, 1.0 + 2 / 3))
    assert brackets == [(-1.0, -2.0), (1.0, 2.0)]  # (inside, outside): they decide the ends
    prof[2.0] = (1.0, z)  # lowered (e.g. re-optimised): the upper end runs to the last value
    (lo, hi), brackets = profile_interval(prof, 3.0)
    assert hi == 2.0 and brackets == [(-1.0, -2.0)]


def test_rivals_below_the_threshold_join_the_profiles_and_no_others():
    # Δcost = t² along both free parameters, threshold 3: the intervals are ±√3 without
    # rivals. A candidate at (2.5, −2.5) with Δcost 2 is inside the 95 % region (an optimum or
    # not), so both intervals must reach it; one at (−2.8, 2.8) with Δcost 3.5 is outside and
    # must change nothing, however close its cost in the fit was
    ts = (-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0)
    profiles = {i: {t: (t**2, np.full(2, t)) for t in ts} for i in (0, 1)}
    inside, outside = np.array([2.5, -2.5]), np.array([-2.8, 2.8])
    rivals = admit_rivals(profiles, [inside, outside], [2.0, 3.5], 3.0)
    assert len(rivals) == 1 and np.array_equal(rivals[0], inside)
    (lo0, hi0), _ = profile_interval(profiles[0], 3.0)
    (lo1, hi1), _ = profile_interval(profiles[1], 3.0)
    assert hi0 == pytest.approx(2.5 + 0.5 / 7) and lo1 == pytest.approx(-2.5 - 0.5 / 7)
    assert lo0 == pytest.approx(-1 - 2 / 3) and hi1 == pytest.approx(1 + 2 / 3)  # unmoved
    assert -2.8 not in profiles[0] and 2.8 not in profiles[1]


def test_profile_threshold_covers_the_truth_of_noisy_profiles():
    # χ²₁'s 95 % quantile plus 1.645 sd of a cost difference's noise: the analytic allowance,
    # or the rms of the Δcost a step from the optimum where that is larger
    assert profile_threshold(2.0) == pytest.approx(1.959964**2 + 1.645 * 2.0, rel=1e-6)
    assert profile_threshold(2.0, np.array([1.0, -1.0])) == profile_threshold(2.0)
    assert profile_threshold(2.0, np.array([6.0, -6.0, 6.0])) == pytest.approx(
        profile_threshold(6.0)
    )
    # Monte Carlo: a parameter's profile is (t − t̂)² (the truth at 0, the estimate t̂ drawn
    # as N(0, 1)), each scanned value's cost with independent noise of sd s/√2, the
    # optimum's too (so a Δcost has sd s). With the interval spanning every value below the
    # threshold, the truth is inside in ≥ 95 % of profiles — with the analytic allowance
    # alone even where s is 6× it (95 % of them, just), and with the jitter's rms (nearly all,
    # the interval 1.3× wider). So on independent noise the roughness allowance is conservative;
    # its use in identify is against roughness that is not independent (docs/identification.md)
    rng = np.random.default_rng(NOISY_PROFILES_SEED)
    offsets = [o for o in np.arange(-6.0, 6.001, 0.25) if abs(o) > 1e-9]
    s, s_mc, n = 6.0, 1.0, 1000
    hits = {"analytic": 0, "rough": 0}
    for _ in range(n):
        t_hat, e_opt = rng.normal(), rng.normal(scale=s / np.sqrt(2))

        def delta(t, t_hat=t_hat, e_opt=e_opt):
            return (t - t_hat) ** 2 + rng.normal(scale=s / np.sqrt(2)) - e_opt

        prof = {t_hat + o: (delta(t_hat + o), None) for o in offsets} | {t_hat: (0.0, None)}
        jitter = np.array([delta(t_hat + h) for h in PROFILE_JITTER])
        for key, th in (
            ("analytic", profile_threshold(s_mc)),
            ("rough", profile_threshold(s_mc, jitter)),
        ):
            (lo, hi), _ = profile_interval(prof, th)
            hits[key] += lo <= 0.0 <= hi
    assert all(hits[key] >= COVERAGE[key] * n for key in hits), hits


def test_profile_threshold_from_several_sets_counts_the_noise_not_the_structure():
    # the jitter Δcosts of one fit's optimum (the Δcosts over independent realisation sets): a
    # wall along a and a slope along T_b that repeat in every realisation set, plus noise of
    # sd 3 that does not. Over several sets the allowance is the noise's sd, not the
    # structure's rms (20.8) that one set's root mean square measures.
    structure = np.array([47.0, 10.3, -2.8, -0.5, -12.1, -2.0, 12.5, 28.8])
    rng = np.random.default_rng(JITTER_SETS_SEED)
    sets = structure + rng.normal(scale=3.0, size=(200, len(structure)))
    assert profile_threshold(1.0, sets[0]) == pytest.approx(
        profile_threshold(float(np.sqrt(np.mean(sets[0] ** 2))))
    )
    assert profile_threshold(1.0, sets[:1]) == profile_threshold(1.0, sets[0])
    sd_many = (profile_threshold(1.0, sets) - profile_threshold(0.0)) / 1.645
    assert sd_many == pytest.approx(3.0, rel=NOISE_SD_TOLERANCE)
    # two sets: unbiased for the variance, so over many pairs the mean square is 9
    pairs = [
        (profile_threshold(0.0, sets[k : k + 2]) - profile_threshold(0.0)) / 1.645
        for k in range(0, 200, 2)
    ]
    assert np.mean(np.square(pairs)) == pytest.approx(9.0, rel=PAIR_VARIANCE_TOLERANCE)
    # never below the analytic allowance
    assert profile_threshold(5.0, sets[:2]) >= profile_threshold(5.0)


def test_bisection_finds_the_profile_ends_a_coarse_scan_misses():
    # a profile Δ(t) = 100 (t − 0.3)² of parameter 0 of two, scanned as profile_scan does:
    # at the optimum, at ±1 and ±2 of its Laplace sd (0.05) and at coarse fractions of the
    # range. The exact 95 % ends are 0.3 ± √3.84/10 = 0.3 ± 0.196, well beyond ±2 sd.
    z = np.array([0.3, 0.0])
    cov = np.diag([0.05**2, 1.0])
    threshold = 3.84

    def delta(points):
        return 100.0 * (np.asarray(points)[:, 0] - 0.3) ** 2

    ts = [-8.0, -3.0, 0.2, 0.25, 0.3, 0.35, 0.4, 3.0, 8.0]
    profiles = {0: {t: (float(delta([[t, 0.0]])[0]), np.array([t, 0.0])) for t in ts}}
    (lo0, hi0), _ = profile_interval(profiles[0], threshold)
    # linear across (0.4, 3.0), where Δ jumps from 1 to 729: the end sticks to 0.4
    assert hi0 < 0.42 and lo0 > 0.18

    n = bisect_profile_ends(profiles, threshold, z, cov, delta, rounds=12)
    (lo, hi), brackets = profile_interval(profiles[0], threshold)
    assert n > 0 and hi == pytest.approx(0.3 + np.sqrt(threshold) / 10, abs=0.01)
    # each bracket is now narrower than the resolution asked for (or the minimum step)
    width = max(PROFILE_RESOLUTION * (hi - lo), PROFILE_MIN_STEP)
    assert all(abs(t_out - t_in) <= width for t_in, t_out in brackets)
    # points inside keep the other parameter where the value inside had it
    assert all(abs(zk[1]) < 1e-12 for _, zk in profiles[0].values())


def _narrow_bent_valley(points):
    # z0 profiled, z1 a nuisance with a prior (sd 10), z2 an unidentified one: the valley
    # floor z1 = 2 sin z0 is 0.2 wide and bends; off it the cost saturates at 30² with no
    # slope (as where rattle switches regime). On the floor the profile of z0 is z0² + the
    # prior's (2 sin z0 / 10)², so its 95 % ends are near ±1.93.
    z0, z1, z2 = np.asarray(points).T
    return np.stack([30 * np.tanh((z1 - 2 * np.sin(z0)) / 0.2), z0, z1 / 10, 0 * z2], axis=1)


def test_continuation_follows_a_bent_valley_that_the_straight_scan_leaves():
    def delta(points):
        return np.sum(_narrow_bent_valley(points) ** 2, axis=1)

    def polish(starts, fixed):
        return polish_profile(_narrow_bent_valley, starts, fixed, np.full(starts.shape, 1e-4))

    threshold = 3.84
    exact = brentq(lambda t: t**2 + (0.2 * np.sin(t)) ** 2 - threshold, 0.5, 3.0)
    z = np.zeros(3)
    cov = np.diag([0.5**2, 1.01, 1.0])
    cov[0, 1] = cov[1, 0] = 0.5  # the Laplace path: the valley's tangent z1 = 2 z0
    profiles = {0: {0.0: (0.0, z)}}
    for t in (-8.0, -3.0, -1.0, -0.5, 0.5, 1.0, 3.0, 8.0):  # as profile_scan: both guesses
        for g in profile_guesses(z, cov, 0, t):
            keep_lower(profiles[0], t, float(delta(g[None])[0]), g)
    bisect_profile_ends(profiles, threshold, z, cov, delta, rounds=4)
    (lo, hi), _ = profile_interval(profiles[0], threshold)
    # the tangent and the value inside both leave the floor before the ends: the scan and
    # its bisection stop short of them
    assert hi < SHORT_OF_THE_END * exact and lo > -SHORT_OF_THE_END * exact

    n = continue_profiles(profiles, threshold, delta, polish, lambda i, t: 0.25, rounds=6)
    bisect_profile_ends(profiles, threshold, z, cov, delta, rounds=4)
    (lo, hi), _ = profile_interval(profiles[0], threshold)
    assert n > 0
    end = pytest.approx(exact, abs=VALLEY_END_TOLERANCE)
    assert hi == end and -lo == end
    # every point inside is on the floor, and the nuisance's interval is widened to span them
    z_lo, z_hi = np.array([lo, -0.5, -1.0]), np.array([hi, 0.5, 1.0])
    specs = [SimpleNamespace(log_sd=v, nuisance=v is not None) for v in (None, 10.0, None)]
    span_profile_points(profiles, threshold, z_lo, z_hi, specs)
    assert z_hi[1] == pytest.approx(2 * np.sin(exact), abs=0.15)
    assert z_lo[1] == pytest.approx(-2 * np.sin(exact), abs=0.15)
    assert (z_lo[2], z_hi[2]) == (-1.0, 1.0)  # no prior: a free parameter's is its profile's
    # past the true ends the valley's cost exceeds the threshold: a further continuation
    # spends one round (two guesses at each end) and does not run past them
    n = continue_profiles(profiles, threshold, delta, polish, lambda i, t: 0.25, rounds=6)
    (lo, hi), _ = profile_interval(profiles[0], threshold)
    assert n <= 4 and hi == end and -lo == end


def _wavy_cliff_valley(points):
    # z0 profiled, z1 a nuisance: the valley floor z1 = 2 sin 3 z0 is 0.02 wide and turns
    # three times over the interval; off it the cost saturates at 30² with no slope (as where
    # rattle leaves the recording's regime, the oil-jet pocket of identify's film valley). On
    # the floor the profile of z0 is z0², so its 95 % ends are ±√3.84.
    z0, z1 = np.asarray(points).T
    return np.stack([30 * np.tanh((z1 - 2 * np.sin(3 * z0)) / 0.02), z0], axis=1)


@pytest.mark.parametrize("known", [False, True])
def test_a_valley_the_physics_knows_gives_the_profile_its_whole_interval(known):
    def delta(points):
        return np.sum(_wavy_cliff_valley(points) ** 2, axis=1)

    def polish(starts, fixed):
        return polish_profile(_wavy_cliff_valley, starts, fixed, np.full(starts.shape, 1e-4))

    calls = []

    def valley(i, near, t):
        calls.append((i, np.array(near), t))
        return [np.array([t, 2 * np.sin(3 * t)])]

    hook = valley if known else None
    threshold, exact = 3.84, np.sqrt(3.84)
    z = np.zeros(2)
    cov = np.array([[0.1**2, 0.06], [0.06, 0.36 + 1e-4]])  # the floor's tangent at 0: z1 = 6 z0
    profiles = {0: {0.0: (0.0, z)}}
    # as profile_scan: coarse values over the range, and ±1, 2 Laplace sd
    for t in (-8.0, -3.0, -1.0, -0.5, -0.2, -0.1, 0.1, 0.2, 0.5, 1.0, 3.0, 8.0):
        for g in profile_guesses(z, cov, 0, t, valley=hook):
            keep_lower(profiles[0], t, float(delta(g[None])[0]), g)
    bisect_profile_ends(profiles, threshold, z, cov, delta, rounds=8, valley=hook)
    continue_profiles(profiles, threshold, delta, polish, lambda i, t: 0.25, rounds=4, valley=hook)
    bisect_profile_ends(profiles, threshold, z, cov, delta, rounds=8, valley=hook)
    (lo, hi), _ = profile_interval(profiles[0], threshold)
    if known:
        end = pytest.approx(exact, abs=WAVY_END_TOLERANCE)
        assert hi == end and -lo == end
        # the hook saw the profiled index, the point it started from, and the new value
        assert all(i == 0 and near.shape == (2,) for i, near, _ in calls)
    else:
        # the straight paths and the secant leave a floor this narrow and wavy at once
        assert hi < 0.1 * exact and lo > -0.1 * exact


def test_a_profile_clearly_below_the_optimum_is_where_the_fit_starts_again():
    # a Levenberg–Marquardt run stopped at t = 0.3 of a cost 100 (t − 0.5)²: relative to its
    # cost the profile dips to −4 at 0.5 (scanned with the other parameter moved there)
    def profile(z0):
        ts = [-8.0, 0.2, 0.3, 0.4, 0.5, 0.6, 8.0]
        return {
            0: {t: (100.0 * ((t - 0.5) ** 2 - (z0 - 0.5) ** 2), np.array([t, t - 0.3])) for t in ts}
        }

    dc, z = lower_profile_point(profile(0.3), allowance=2.0)
    assert dc == pytest.approx(-4.0) and np.allclose(z, [0.5, 0.2])
    # within the Monte Carlo allowance, or at the optimum itself, nothing moves
    assert lower_profile_point(profile(0.3), allowance=5.0) is None
    assert lower_profile_point(profile(0.5), allowance=0.0) is None
    assert lower_profile_point({}, allowance=0.0) is None
