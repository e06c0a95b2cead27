"""Critical values of the profile-likelihood ratio by simulation, against closed forms.

On a linear-Gaussian model whose cost assumes a noise sd ``k`` times the true one, the profile
likelihood ratio of any one parameter (or linear combination) at its truth is exactly
``χ²₁ / k²``: its 95 % critical value is ``3.84 / k²``. A calibrated likelihood (k = 1) must
get χ²₁'s 3.84; one that is twice too narrow (k = 1/2) must get four times it.
"""

from __future__ import annotations

import types

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import rattlefit as rf
from rattlefit.confidence import CHI2_1_95
from rattlefit.inference.critical import critical_value, ratio_statistics

rf.configure()


class LinearGaussian(eqx.Module):
    """The cost ``|(data − A z) / sd|²`` of one recording (1, F) at parameters ``z`` (P,)."""

    data: jax.Array
    design: jax.Array
    sd: float

    def cost(self, z):
        return jnp.sum(((self.data[0] - self.design @ z) / self.sd) ** 2)

    def replace_data(self, data):
        return eqx.tree_at(lambda m: m.data, self, jnp.asarray(data))


def simulated(n: int, assumed_sd: float, seed: int):
    """``n`` data sets (n, 1, F) with unit noise at truths around 0, the model assuming
    ``assumed_sd``, and the truths (n, P)."""
    rng = np.random.default_rng(seed)
    design = rng.normal(size=(8, 3))
    truths = 0.3 * rng.normal(size=(n, 3))
    data = truths @ design.T + rng.normal(size=(n, 8))
    model = LinearGaussian(jnp.zeros((1, 8)), jnp.asarray(design), assumed_sd)
    return model, data[:, None, :], truths


@pytest.mark.parametrize("assumed_sd", [1.0, 0.5])
@pytest.mark.parametrize("seed", [0, 1])
def test_critical_values_match_the_closed_form(assumed_sd, seed):
    model, data, truths = simulated(400, assumed_sd, seed)
    fit = types.SimpleNamespace(optimum=types.SimpleNamespace(z=np.zeros(3)))
    derived = {"sum": lambda z: z[0] + z[1]}
    statistics = ratio_statistics(model, fit, data, truths, [0, 2], derived)
    exact = CHI2_1_95 / assumed_sd**2
    for key, s in statistics.items():
        # the statistics are χ²₁ / k² (a Kolmogorov–Smirnov test far from rejecting) …
        assert stats.kstest(s * assumed_sd**2, stats.chi2(1).cdf).pvalue > 1e-3, key
        # … and the critical value is their 95 % quantile: the sample quantile of 400 draws
        # has a relative sd of about 10 %
        assert critical_value(s) == pytest.approx(exact, rel=0.3), key


def test_a_critical_value_is_an_order_statistic_never_below_chi2_1():
    s = np.arange(1.0, 101.0)  # 1 … 100
    assert critical_value(s) == 96.0  # ⌈0.95 × 101⌉ = 96th smallest
    assert critical_value(s / 100) == CHI2_1_95  # all below 3.84: never narrower than χ²₁
    assert critical_value(np.arange(1.0, 11.0) + 10) == 20.0  # too few: the largest
    assert critical_value(np.array([np.nan, np.inf])) == CHI2_1_95
