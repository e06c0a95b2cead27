"""The learned likelihood (rattlefit.likelihood) against closed forms and rattlefit's own data.

References the code under test did not produce: a closed-form feature distribution (the
emulator must recover its mean and spread), the exact Gaussian profile of a linear-Gaussian
simulator (the learned profile interval must match it), and a recording rattlefit simulated
with known truth (the learned intervals must hold it).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rattlefit as rf
from rattlefit.inference.parameters import ParameterSpec
from rattlefit.inference.problem import problem_from
from rattlefit.io.recording import read_truth
from rattlefit.likelihood import (
    EmulatorOptions,
    LearnedLikelihood,
    LearningOptions,
    fit_emulator,
    learn_likelihood,
)
from rattlefit.likelihood.design import prior_box, sobol_design, z_of_unit
from rattlefit.likelihood.estimate import CHI2_95, fit_learned
from rattlefit.likelihood.learn import best_points

QUICK = EmulatorOptions(steps=800, width=32)


def closed_form(u, w):
    """Mean (N, F) and sd (N, F) of a heteroscedastic feature distribution."""
    mean = np.sin(2 * u @ w / 3) + u[:, :1] ** 2
    sd = (0.05 + 0.2 * u[:, 1:2]) * np.ones((1, w.shape[1]))
    return mean, sd


def test_the_emulator_recovers_a_closed_form_mean_and_spread():
    rng = np.random.default_rng(0)
    w = rng.normal(size=(4, 12))
    u = rng.uniform(size=(1500, 4))
    mean, sd = closed_form(u, w)
    y = mean + sd * rng.normal(size=mean.shape)
    em, _ = fit_emulator(u, y, (0, 1, 2, 3), QUICK, np.random.SeedSequence(1))
    ut = rng.uniform(size=(200, 4))
    m_true, sd_true = closed_form(ut, w)
    m, c = jax.vmap(em.predict)(jnp.asarray(ut))
    err = (np.asarray(m) - m_true) / sd_true
    ratio = np.sqrt(np.diagonal(np.asarray(c), axis1=1, axis2=2)) / sd_true
    assert np.sqrt(np.mean(err**2)) < 0.5  # the mean to half its spread
    assert 0.8 < np.median(ratio) < 1.3  # the spread itself
    # the emulator's own error grows outside the design
    inside = np.mean(jax.vmap(em.emulator_variance)(jnp.asarray(ut)))
    outside = np.mean(jax.vmap(em.emulator_variance)(jnp.asarray(ut + 1.5)))
    assert outside > 5 * inside


def test_emulator_training_is_deterministic_for_a_seed():
    rng = np.random.default_rng(3)
    u = rng.uniform(size=(200, 2))
    y = np.c_[u[:, 0], u[:, 1] ** 2] + 0.1 * rng.normal(size=(200, 2))
    opts = EmulatorOptions(steps=50, width=8)
    a, la = fit_emulator(u, y, (0, 1), opts, np.random.SeedSequence(7))
    b, lb = fit_emulator(u, y, (0, 1), opts, np.random.SeedSequence(7))
    np.testing.assert_array_equal(la, lb)
    np.testing.assert_array_equal(a.predict(jnp.asarray(u[0]))[0], b.predict(jnp.asarray(u[0]))[0])


def linear_gaussian_likelihood(seed):
    """A learned likelihood of a linear-Gaussian simulator y = A·log(v) + ε, ε ~ N(0, s²I),
    with its data at a known truth, and the exact Gaussian interval of the first parameter."""
    rng = np.random.default_rng(seed)
    specs = (ParameterSpec("p0", "1", 0.1, 10.0), ParameterSpec("p1", "1", 0.1, 10.0))
    a = rng.normal(size=(8, 2))
    s = 0.3

    def simulate(u, noise):
        logv = np.log(0.1) + np.log(100.0) * u
        return logv @ a.T + s * noise.normal(size=(u.shape[0], 8))

    u = rng.uniform(0.05, 0.95, size=(2000, 2))
    em, _ = fit_emulator(
        u,
        simulate(u, rng),
        (0, 1),
        EmulatorOptions(steps=1500, width=32),
        np.random.SeedSequence(seed),
    )
    truth_u = np.array([[0.45, 0.6]])
    data = simulate(truth_u, rng)
    like = LearnedLikelihood((em,), jnp.asarray(data), specs)
    # exact: the profile of log v0 is Gaussian with variance [(AᵀA)⁻¹]₀₀ s²
    sd_log = s * np.sqrt(np.linalg.inv(a.T @ a)[0, 0])
    return like, truth_u[0], sd_log


@pytest.mark.parametrize("seed", [0, 1])
def test_learned_profile_interval_matches_the_exact_gaussian_one(seed):
    like, truth_u, sd_log = linear_gaussian_likelihood(seed)
    fit = fit_learned(like, z_of_unit(truth_u)[None], [0])
    prof = fit.profiles[0]
    spec = like.specs[0]
    width = np.log(float(spec.value(prof.upper)) / float(spec.value(prof.lower)))
    exact = 2 * np.sqrt(CHI2_95) * sd_log
    assert 0.75 < width / exact < 1.35
    truth = np.log(0.1) + np.log(100.0) * truth_u[0]
    assert np.log(float(spec.value(prof.lower))) < truth < np.log(float(spec.value(prof.upper)))
    assert prof.delta.min() > -1e-3  # no profile point below the optimum
    assert fit.p_value > 1e-3


@pytest.fixture(scope="module")
def learned_boundary():
    """The bundled boundary recording (rattlefit's own, truth known) with its likelihood learned
    at a small budget."""
    path = "data/pairII_boundary_65.6_20pct_16Hz.h5"
    problem, _, _ = problem_from([rf.read_recording(path)], rf.FitOptions(seed=0))
    options = LearningOptions(initial=512, rounds=1, per_round=256)
    like, design, records = learn_likelihood(problem, options, seed=0)
    return problem, like, design, records, read_truth(path)


def test_the_design_starts_inside_the_prior_box(learned_boundary):
    problem, _, design, records, _ = learned_boundary
    lo, hi = prior_box(problem)
    first = design.u[: records[0].simulations]
    assert np.all(first >= lo) and np.all(first <= hi)
    assert design.features.shape == (1, sum(r.simulations for r in records), problem.data.shape[1])
    assert all(r.per_second_per_core > 0 for r in records)
    np.testing.assert_array_equal(
        sobol_design(8, lo, hi, np.random.SeedSequence(0)),
        sobol_design(8, lo, hi, np.random.SeedSequence(0)),
    )


def test_the_learned_intervals_hold_rattlefits_own_truth(learned_boundary):
    problem, like, design, _, truth = learned_boundary
    names = [s.name for s in problem.specs]
    free = [names.index(n) for n in ("a", "drag_torque", "viscosity_scale")]
    fit = fit_learned(like, best_points(like, design.u, 8), free)
    assert fit.p_value > 1e-3  # its own data are explained
    true = {
        "a": truth["film_half_length"],
        "drag_torque": truth["drag_torque"],
        "viscosity_scale": truth["viscosity"] / float(problem.viscosities[0]),
    }
    for i in free:
        spec, prof = problem.specs[i], fit.profiles[i]
        lo, hi = float(spec.value(prof.lower)), float(spec.value(prof.upper))
        assert lo < true[spec.name] < hi, (spec.name, lo, hi)
        assert prof.delta.min() > -1e-3
    # a 3 s boundary recording bounds the drag torque on both sides under this likelihood
    prof = fit.profiles[names.index("drag_torque")]
    spec = problem.specs[names.index("drag_torque")]
    assert float(spec.value(prof.lower)) > 1.05 * spec.lower
    assert float(spec.value(prof.upper)) < 0.95 * spec.upper
