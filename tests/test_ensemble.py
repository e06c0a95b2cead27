"""Ensemble statistics: regimes set aside, the mean and spread of the common regime."""

import numpy as np
import pytest

from rattlefit.ensemble import band_sigma, ensemble_mean, regime_weights

N, B = 6, 30
THRESHOLD = 9.0


def _gaussian(rng, trials, sd=0.1):
    level = np.linspace(-5.0, -11.0, B)
    return level + sd * rng.standard_normal((trials, N, B))


def test_gaussian_realisations_are_all_kept():
    # a Gaussian ensemble has no second regime: almost nothing may be set aside, or the
    # robust mean would lose efficiency for nothing
    ens = _gaussian(np.random.default_rng(0), 4000)
    w = np.asarray(regime_weights(ens, THRESHOLD))
    assert w.mean() > 0.995


def test_a_realisation_in_another_regime_is_set_aside():
    # one realisation of six moved by 4 sd in every band (as a locked orbit moves a spectrum):
    # it must leave the mean, which is then the mean of the other five
    rng = np.random.default_rng(1)
    ens = _gaussian(rng, 2000)
    ens[:, 2] += 0.4
    w = np.asarray(regime_weights(ens, THRESHOLD))
    assert np.mean(w[:, 2] == 0) > 0.99
    assert np.mean(w[:, [0, 1, 3, 4, 5]]) > 0.99
    others = ens[:, [0, 1, 3, 4, 5]].mean(axis=1)
    both = np.all(w[:, [0, 1, 3, 4, 5]] == 1, axis=1) & (w[:, 2] == 0)
    got = np.asarray(ensemble_mean(ens, THRESHOLD))
    assert got[both] == pytest.approx(others[both], abs=1e-12)
    plain = ens.mean(axis=1)
    # the plain mean is pulled by a sixth of the excursion; the common regime's is not
    assert np.mean(plain - others) == pytest.approx(0.4 / 6, rel=0.01)
    assert abs(np.mean(got - others)) < 0.005


def test_never_more_than_half_and_never_with_few_realisations():
    rng = np.random.default_rng(2)
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
    rng = np.random.default_rng(3)
    trials, n, sd = 400, 24, 0.1
    level = np.linspace(-5.0, -11.0, B)
    ens = level + sd * rng.standard_normal((trials, n, B))
    ens[:, :3] += 0.6
    kw = dict(m=6, floor=0.0, noise_floor=np.zeros(trials), floor_sd=0.0)
    robust = np.asarray(band_sigma(ens, threshold=THRESHOLD, **kw))
    plain = np.asarray(band_sigma(ens, **kw))
    expected = sd * np.sqrt(1 + 1 / 6)
    assert np.mean(robust**2) == pytest.approx(expected**2, rel=0.03)
    assert np.mean(plain**2) > 3 * expected**2


def test_the_traced_path_is_the_host_path():
    # the fit's residual traces regime_weights and ensemble_mean inside its compiled loop,
    # while its host-side costs and band spreads call them on concrete arrays in numpy: both
    # must set the same realisations aside and give the same mean
    import jax

    rng = np.random.default_rng(4)
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
