"""Ensemble statistics: regimes set aside, the mean and spread of the common regime."""

import numpy as np
import pytest

from rattlefit.features.ensemble import band_sigma, ensemble_mean, regime_weights

N, B = 6, 30
THRESHOLD = 9.0

# Seeds: each test draws its own ensembles.
GAUSSIAN_SEED = 0
OTHER_REGIME_SEED = 1
NO_MAJORITY_SEED = 2
SPREAD_SEED = 3
TRACED_SEED = 4
RARE_REGIME_SEED = 5
LONE_SEED = 6
RECORDING_REGIME_TRACED_SEED = 7
REGIME_SHARE_SEED = 8

# Margins.
KEPT_SHARE = 0.995  # of Gaussian realisations kept: a second regime is not invented
DECIDED_SHARE = 0.99  # of trials in which a realisation 4–8 sd off is told apart
PULL_TOLERANCE = 0.01  # relative, on the plain mean's pull by one excursion in six
UNPULLED = 0.005  # the common regime's mean moves less than this (log10) on average
SPREAD_TOLERANCE = 0.03  # relative, on a band variance's mean over 400 trials
INFLATED = 3.0  # the plain spread with three excursions in 24 exceeds this × the true one


def _gaussian(rng, trials, sd=0.1):
    level = np.linspace(-5.0, -11.0, B)
    return level + sd * rng.standard_normal((trials, N, B))


def test_gaussian_realisations_are_all_kept():
    # a Gaussian ensemble has no second regime: almost nothing may be set aside, or the
    # robust mean would lose efficiency for nothing
    ens = _gaussian(np.random.default_rng(GAUSSIAN_SEED), 4000)
    w = np.asarray(regime_weights(ens, THRESHOLD))
    assert w.mean() > KEPT_SHARE


def test_a_realisation_in_another_regime_is_set_aside():
    # one realisation of six moved by 4 sd in every band (as a locked orbit moves a spectrum):
    # it must leave the mean, which is then the mean of the other five
    rng = np.random.default_rng(OTHER_REGIME_SEED)
    ens = _gaussian(rng, 2000)
    ens[:, 2] += 0.4
    w = np.asarray(regime_weights(ens, THRESHOLD))
    assert np.mean(w[:, 2] == 0) > DECIDED_SHARE
    assert np.mean(w[:, [0, 1, 3, 4, 5]]) > DECIDED_SHARE
    others = ens[:, [0, 1, 3, 4, 5]].mean(axis=1)
    both = np.all(w[:, [0, 1, 3, 4, 5]] == 1, axis=1) & (w[:, 2] == 0)
    got = np.asarray(ensemble_mean(ens, THRESHOLD))
    assert got[both] == pytest.approx(others[both], abs=1e-12)
    plain = ens.mean(axis=1)
    # the plain mean is pulled by a sixth of the excursion; the common regime's is not
    assert np.mean(plain - others) == pytest.approx(0.4 / 6, rel=PULL_TOLERANCE)
    assert abs(np.mean(got - others)) < UNPULLED


def test_never_more_than_half_and_never_with_few_realisations():
    rng = np.random.default_rng(NO_MAJORITY_SEED)
    ens = _gaussian(rng, 500)
    ens[:, :3] += 1.0  # half in each of two regimes: no majority, so nothing is set aside
    assert np.all(np.asarray(regime_weights(ens, THRESHOLD)).sum(axis=1) >= N / 2)
    few = _gaussian(rng, 50)[:, :4]
    few[:, 0] += 5.0
    assert np.all(np.asarray(regime_weights(few, THRESHOLD)) == 1)  # 4 < MIN_FOR_REGIMES
    assert np.all(np.asarray(regime_weights(ens, None)) == 1)
    assert np.asarray(ensemble_mean(ens, None)) == pytest.approx(ens.mean(axis=1))


def test_band_sigma_is_the_spread_of_the_common_regime():
    # 24 realisations, 3 of them in another regime: with the threshold the spread is the
    # Gaussian one (unbiased over many trials), without it the excursions inflate it
    rng = np.random.default_rng(SPREAD_SEED)
    trials, n, sd = 400, 24, 0.1
    level = np.linspace(-5.0, -11.0, B)
    ens = level + sd * rng.standard_normal((trials, n, B))
    ens[:, :3] += 0.6
    kw = dict(m=6, floor=0.0, noise_floor=np.zeros(trials), floor_sd=0.0)
    robust = np.asarray(band_sigma(ens, threshold=THRESHOLD, **kw))
    plain = np.asarray(band_sigma(ens, **kw))
    expected = sd * np.sqrt(1 + 1 / 6)
    assert np.mean(robust**2) == pytest.approx(expected**2, rel=SPREAD_TOLERANCE)
    assert np.mean(plain**2) > INFLATED * expected**2


def test_the_traced_path_is_the_host_path():
    # the fit's residual traces regime_weights and ensemble_mean inside its compiled loop,
    # while its host-side costs and band spreads call them on concrete arrays in numpy: both
    # must set the same realisations aside and give the same mean
    import jax

    rng = np.random.default_rng(TRACED_SEED)
    ens = _gaussian(rng, 50)
    ens[:, 2] += 0.4
    ens[::3, 4] -= 0.5  # a second excursion in some trials
    w_host = regime_weights(ens, THRESHOLD)
    assert isinstance(w_host, np.ndarray)  # concrete in, numpy out: nothing compiled
    w_traced = jax.jit(lambda f: regime_weights(f, THRESHOLD))(ens)
    np.testing.assert_array_equal(np.asarray(w_traced), w_host)
    assert 0 < np.mean(w_host == 0) < 0.5  # the test sees both kinds
    m_traced = jax.jit(lambda f: ensemble_mean(f, THRESHOLD))(ens)
    np.testing.assert_allclose(np.asarray(m_traced), ensemble_mean(ens, THRESHOLD), rtol=1e-14)


def _two_regimes(rng, trials, rare: int, shift=0.8):
    """Six realisations, the first ``rare`` of them moved by ``shift`` (8 sd) in every band,
    and a recording (0.1 sd of noise) of each regime."""
    ens = _gaussian(rng, trials)
    ens[:, :rare] += shift
    level = np.linspace(-5.0, -11.0, B)
    in_rare = level + shift + 0.1 * rng.standard_normal((trials, B))
    in_common = level + 0.1 * rng.standard_normal((trials, B))
    return ens, in_rare, in_common


def test_a_recording_of_the_rarer_regime_is_matched_by_that_regime():
    # coexisting attractors: two of six releases settle into a regime the recording is in;
    # its mean must be that regime's (the mean of those two), not the common one's
    rng = np.random.default_rng(RARE_REGIME_SEED)
    ens, in_rare, in_common = _two_regimes(rng, 1000, rare=2)
    w = np.asarray(regime_weights(ens, THRESHOLD, target=in_rare))
    assert np.mean(np.all(w == [1, 1, 0, 0, 0, 0], axis=1)) > DECIDED_SHARE
    got = np.asarray(ensemble_mean(ens, THRESHOLD, target=in_rare))
    exact = np.all(w == [1, 1, 0, 0, 0, 0], axis=1)
    np.testing.assert_allclose(got[exact], ens[exact, :2].mean(axis=1), rtol=1e-14)
    # a recording of the common regime keeps the common regime, exactly as without a target
    w_common = np.asarray(regime_weights(ens, THRESHOLD, target=in_common))
    np.testing.assert_array_equal(w_common, regime_weights(ens, THRESHOLD))
    assert np.mean(np.all(w_common == [0, 0, 1, 1, 1, 1], axis=1)) > DECIDED_SHARE


def test_a_lone_realisation_is_not_a_regime():
    # one release of six in the recording's regime gives no spread: the common regime stays
    rng = np.random.default_rng(LONE_SEED)
    ens, in_rare, _ = _two_regimes(rng, 200, rare=1)
    np.testing.assert_array_equal(
        regime_weights(ens, THRESHOLD, target=in_rare), regime_weights(ens, THRESHOLD)
    )


def test_a_regime_too_few_releases_reach_is_not_the_recordings():
    # of 24 releases, 3 (an eighth) in the recording's regime: too improbable, the common
    # regime stays; 4 (a sixth, MIN_REGIME_SHARE) make it the recording's
    from rattlefit.features.ensemble import MIN_REGIME_SHARE

    assert MIN_REGIME_SHARE * 24 == pytest.approx(4)
    rng = np.random.default_rng(REGIME_SHARE_SEED)
    level = np.linspace(-5.0, -11.0, B)
    target = level + 0.8 + 0.1 * rng.standard_normal((300, B))
    for rare, expect_rare in ((3, False), (4, True)):
        ens = level + 0.1 * rng.standard_normal((300, 24, B))
        ens[:, :rare] += 0.8
        w = np.asarray(regime_weights(ens, THRESHOLD, target=target))
        chosen = np.all(w[:, :rare] == 1, axis=1) & np.all(w[:, rare:] == 0, axis=1)
        assert np.mean(chosen) > DECIDED_SHARE if expect_rare else np.mean(chosen) == 0


def test_the_recording_regime_traces_as_it_computes_on_the_host():
    import jax

    rng = np.random.default_rng(RECORDING_REGIME_TRACED_SEED)
    ens, in_rare, in_common = _two_regimes(rng, 60, rare=2)
    target = np.where(np.arange(60)[:, None] % 2 == 0, in_rare, in_common)
    w_host = regime_weights(ens, THRESHOLD, target=target)
    assert isinstance(w_host, np.ndarray)
    w_traced = jax.jit(lambda f, t: regime_weights(f, THRESHOLD, target=t))(ens, target)
    np.testing.assert_array_equal(np.asarray(w_traced), w_host)
    assert 0 < np.mean(w_host[:, 0]) < 1  # both regimes chosen somewhere
    sig = np.asarray(
        band_sigma(
            ens,
            m=6,
            floor=0.0,
            noise_floor=np.zeros(60),
            floor_sd=0.0,
            threshold=THRESHOLD,
            target=target,
        )
    )
    # the spread of each trial's chosen regime: two realisations' in the rare, four's else
    assert np.all(np.isfinite(sig)) and np.all(sig > 0)


FOLDED_SEED = 9


def test_regimes_and_the_floor_term_come_from_the_bands_alone():
    # 24 realisations of 30 bands followed by 12 folded statistics: three realisations are
    # far off in the folded statistics only, three others far off in the bands only. With
    # n_bands the regimes are told apart by the bands (the band outliers leave, the folded
    # ones stay) and the quantisation floor's term, which belongs to a band PSD, is added
    # to no folded statistic even where that statistic's value would put it below the floor
    rng = np.random.default_rng(FOLDED_SEED)
    n, s, sd = 24, 12, 0.1
    level = np.concatenate([np.linspace(-5.0, -11.0, B), np.full(s, -12.0)])
    ens = level + sd * rng.standard_normal((1, n, B + s))
    ens[0, :3, B:] += 1.0
    ens[0, 3:6, :B] += 1.0
    kw = dict(m=6, floor=0.0, noise_floor=np.array([1e-11]), floor_sd=0.5, threshold=THRESHOLD)
    got = np.asarray(band_sigma(ens, n_bands=B, **kw))[0]
    keep = np.r_[0:3, 6:n]
    spread = np.std(ens[0, keep], axis=0, ddof=1) * np.sqrt(1 + 1 / 6)
    assert got[B:] == pytest.approx(spread[B:], rel=1e-9)  # no floor term, band regime
    assert got[0] == pytest.approx(spread[0], rel=1e-6)  # a band far above the floor
    # every feature taken for a band: both kinds of outliers leave, and the floor term
    # (share clipped to 1, since -12 lies below the floor's -11) is added to the statistics
    blind = np.asarray(band_sigma(ens, **kw))[0]
    rest = np.std(ens[0, 6:], axis=0, ddof=1) * np.sqrt(1 + 1 / 6)
    assert blind[B:] == pytest.approx(np.sqrt(rest[B:] ** 2 + 0.5**2), rel=1e-9)
