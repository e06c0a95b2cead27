"""Test planning (rattlefit.inference.design): the information estimate against closed forms."""

import math
from pathlib import Path

import numpy as np
import pytest

import rattlefit as rf
from rattlefit.inference.design import (
    add_information,
    interval_factors,
    planned_recording,
    suggest,
)
from rattlefit.io.recording import OperatingPoint
from rattlefit.likelihood.information import fisher_information
from rattlefit.simulation.synthetic import synthesize

N, F = 24, 3
STEP = 0.4
TRIALS = 2000
LINEAR_SEED = 0
NULL_SEED = 1
RECORDING_SEED = 2
SUGGEST_SEED = 0
DATA = Path(__file__).resolve().parents[1] / "data"

# Margins.
UNBIASED = 0.15  # relative: the spread's 1/s² is biased high by ν/(ν − 2) ≈ 10 % at ν = 23
VISCOSITY_PINNED = 1.5  # the companion's predicted viscosity factor, against the prior's 2.66
NULL_SHARE = 0.5  # of the uncorrected bias left where nothing depends on θ (the clip at zero)


def _draws(rng, d, sd, trials):
    """Central-difference derivatives and centre deviations of a linear Gaussian model:
    features = d · u + noise (sd), n realisations at u = 0 and at u = ±STEP."""
    noise = lambda: sd * rng.standard_normal((trials, N, F))  # noqa: E731
    plus = STEP * d[:, 0] + noise().mean(axis=1)
    minus = -STEP * d[:, 0] + noise().mean(axis=1)
    centre = noise()
    deriv = ((plus - minus) / (2 * STEP))[..., None]
    return deriv, centre - centre.mean(axis=1, keepdims=True)


def test_the_information_of_a_linear_gaussian_model_is_its_closed_form():
    rng = np.random.default_rng(LINEAR_SEED)
    sd = np.array([0.1, 0.2, 0.05])
    d = np.array([[0.3], [-0.2], [0.1]])
    truth = float(np.sum((d[:, 0] / sd) ** 2))  # Dᵀ C⁻¹ D
    deriv, dev = _draws(rng, d, sd, TRIALS)
    got = [
        fisher_information(deriv[t], dev[t], N - 1, [2 * STEP], 0.0)[0, 0] for t in range(TRIALS)
    ]
    assert np.mean(got) == pytest.approx(truth, rel=UNBIASED)


def test_the_monte_carlo_noise_of_the_derivative_is_not_information():
    # nothing depends on the parameter: the uncorrected DᵀC⁻¹D averages 2F/(nΔ²) (Δ = 2·STEP);
    # the estimate must remove it
    rng = np.random.default_rng(NULL_SEED)
    sd = np.array([0.1, 0.2, 0.05])
    deriv, dev = _draws(rng, np.zeros((F, 1)), sd, TRIALS)
    bias = 2 * F / (N * (2 * STEP) ** 2)
    got = [
        fisher_information(deriv[t], dev[t], N - 1, [2 * STEP], 0.0)[0, 0] for t in range(TRIALS)
    ]
    raw = [float(np.sum((deriv[t][:, 0] / dev[t].std(axis=0, ddof=1)) ** 2)) for t in range(TRIALS)]
    assert np.mean(raw) == pytest.approx(bias, rel=UNBIASED)
    assert np.mean(got) < NULL_SHARE * bias


def test_interval_factors_and_adding_information():
    # a parameter with information 1/σ² has the interval exp(±1.96σ): factor exp(2·1.96σ)
    names, info = add_information(
        ["film_half_length", "drag_torque"], np.diag([4.0, 0.0]), ["drag_torque"], [[1.0]]
    )
    assert names == ["film_half_length", "drag_torque"]
    f = interval_factors(names, info)
    assert f["film_half_length"] == pytest.approx(math.exp(2 * 1.959963984540054 * 0.5))
    assert f["drag_torque"] == pytest.approx(math.exp(2 * 1.959963984540054))
    assert interval_factors(["film_half_length"], np.zeros((1, 1)))["film_half_length"] == math.inf
    names, info = add_information(names, info, ["film_half_length[oil_jet]"], [[9.0]])
    assert names[-1] == "film_half_length[oil_jet]" and info[2, 2] == 9.0 and info[0, 2] == 0.0


def test_a_parameter_along_an_uninformed_direction_is_unbounded_and_information_never_widens():
    # information that pins a + T_b but not a − T_b leaves each of them unbounded (a
    # pseudo-inverse would give the uninformed direction zero variance and a finite factor)
    names = ["film_half_length", "drag_torque", "viscosity_scale"]
    v = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    f = interval_factors(names, 50.0 * np.outer(v, v) + np.diag([0.0, 0.0, 4.0]))
    assert f["film_half_length"] == f["drag_torque"] == math.inf
    assert f["viscosity_scale"] == pytest.approx(math.exp(2 * 1.959963984540054 * 0.5))
    # information from independent recordings adds (positive semi-definite, here of rank < 3):
    # no factor may widen, whichever directions the fitted information leaves nil
    rng = np.random.default_rng(0)
    for _ in range(200):
        now = rng.normal(size=(3, 2)) * rng.uniform(0, 30, size=2)
        more = rng.normal(size=(3, 1)) * rng.uniform(0, 30)
        before = interval_factors(names, now @ now.T)
        after = interval_factors(names, now @ now.T + more @ more.T)
        for name in names:
            assert after[name] <= before[name] * (1 + 1e-9), (name, before, after)


def test_a_planned_centre_distance_opens_the_backlash_as_the_involute_relation_says():
    # the paper's relation: Δ(backlash) = 2 Δa tan αt / r1 (primary angle); the measured
    # backlash of the template is kept and moved by that much
    g = rf.table2_pair("II", center_distance_mm=65.6)
    op = OperatingPoint("boundary", 20.0, 52.36, 10.47, 16.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
    rec, _ = synthesize(g, op, p, seed=RECORDING_SEED, duration=0.6, burn_in=0.1)
    moved = planned_recording(rec, {"cd": 0.4}, p, seed=RECORDING_SEED)
    expected = 2 * 0.4e-3 * math.tan(g.transverse_pressure_angle) / g.pitch_radius_driving
    backlash = moved.gear_pair.angular_backlash_rad - rec.gear_pair.angular_backlash_rad
    assert backlash == pytest.approx(expected, rel=1e-9)
    assert moved.gear_pair.center_distance_mm == pytest.approx(66.0)
    assert moved.duration == pytest.approx(rec.duration)


@pytest.mark.slow  # a quick identification and nine candidate ensembles (about two minutes)
def test_an_oil_jet_companion_is_what_pins_the_viscosity_of_a_boundary_file():
    # the paper's physics: under oil jet the squeeze force saturates in a and pins μ/√h_min,
    # which a boundary recording cannot separate from a and h_min. Of the candidates, the
    # oil-jet companion must be predicted to narrow the viscosity most, and to narrow it
    # clearly below its prior's factor (exp(2·1.96·0.25) = 2.66)
    rec = rf.read_recording(DATA / "pairII_boundary_65.6_20pct_16Hz.h5")
    fit = rf.identify([rec], rf.FitOptions.quick(seed=0))
    rows = suggest(fit, [rec], seed=SUGGEST_SEED)
    by_label = {r.label: r.factors for r in rows}
    companion = by_label["an oil-jet companion"]["viscosity_scale"]
    others = [f["viscosity_scale"] for k, f in by_label.items() if "oil-jet" not in k]
    assert companion < min(others)
    assert companion < VISCOSITY_PINNED
