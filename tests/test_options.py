"""FitOptions: one flat frozen form that result JSON and chain files rely on, the validation
of every option where it is set, and the code paths of the alternatives no default uses."""

from __future__ import annotations

import dataclasses
import importlib
import json
import types

import numpy as np
import pytest

import rattlefit as rf
from rattlefit.inference.profile import stage as stage_module
from rattlefit.problem.options import OPTION_NAMES, FitOptions
from rattlefit.problem.parameters import parameter_prior

# the module, not the function that rattlefit.inference exports under the same name
identify_module = importlib.import_module("rattlefit.inference.identify")


def test_options_are_one_flat_frozen_form():
    options = FitOptions(n_realisations=3, profile_rounds=0, screen="nearest", seed=7)
    assert options.n_realisations == 3 and options.profile_rounds == 0 and options.seed == 7
    assert not hasattr(options, "ensemble") and not hasattr(options, "profile")
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.seed = 8  # type: ignore[misc]
    # a replacement is checked like a construction
    with pytest.raises(rf.RattlefitError, match=r"FitOptions\.n_realisations"):
        options.replace(n_realisations=1)
    with pytest.raises(rf.RattlefitError, match="unknown option"):
        options.replace(n_realization=3)


def test_to_dict_is_flat_in_the_stored_order_and_from_dict_inverts_it():
    spec = parameter_prior("min_film", 2e-6, 0.1)
    options = FitOptions.quick(seed=3, priors={"min_film": spec})
    doc = options.to_dict()
    assert list(doc) == list(OPTION_NAMES)
    assert doc["n_realisations"] == 3 and doc["priors"]["min_film"]["log_sd"] == 0.1
    again = FitOptions.from_dict(json.loads(json.dumps(doc)))
    assert again == options
    assert dataclasses.replace(options, n_realisations=5).n_realisations == 5
    assert options.replace(seed=4).seed == 4


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("regime", "mine"),
        ("drive", "measure"),
        ("quantisation", "pink"),
        ("screen", "best"),
    ],
)
def test_every_string_option_is_checked_where_it_is_set(option, value):
    with pytest.raises(rf.RattlefitError, match=f"FitOptions.{option} must be one of"):
        FitOptions(**{option: value})


def test_an_unknown_option_is_named():
    with pytest.raises(TypeError, match="n_realization"):
        FitOptions(n_realization=3)
    with pytest.raises(rf.RattlefitError, match=r"unknown option.*'n_realization'"):
        FitOptions.from_dict({"n_realization": 3})


@pytest.mark.parametrize(
    ("option", "value"),
    [
        ("n_realisations", 1),
        ("rtol", 0.0),
        ("burn_in", -1.0),
        ("sigma_floor", 0.0),
        ("start_realisations", 0),
        ("n_refine", 0),
        ("profile_screen", -1),
        ("recentre_rounds", -1),
    ],
)
def test_out_of_range_values_are_refused_with_the_options_name(option, value):
    with pytest.raises(rf.RattlefitError, match=f"FitOptions.{option}"):
        FitOptions(**{option: value})


# -- the alternatives no default uses ---------------------------------------------------------


def _stand_in_problem(n_params: int = 3):
    specs = tuple(
        types.SimpleNamespace(name=f"p{i}", log_sd=None if i < 2 else 0.1) for i in range(n_params)
    )
    return types.SimpleNamespace(specs=specs, data=np.zeros((1, 4)), n_rec=1)


@pytest.mark.parametrize("rounds", [0, 1, 2])
def test_recentre_rounds_restart_the_covariance_and_profiles_from_a_lower_point(
    monkeypatch, rounds
):
    # a profile stage that always finds a point 5 below the optimum, 1 further along p0: the
    # stages must start again from it exactly `rounds` times, each from the point found
    problem = _stand_in_problem()
    centres = []

    def laplace_at(prob, z, y0, options, dof_rec):
        centres.append(np.array(z))
        return types.SimpleNamespace(problem=prob, chi2=1.0)

    def profile_stage(lap, z, contenders, y0, options, **kw):
        lower = (-5.0, np.asarray(z) + np.array([1.0, 0.0, 0.0]))
        return types.SimpleNamespace(lower=lower, noise_sd=1.0)

    monkeypatch.setattr(identify_module, "laplace_at", laplace_at)
    monkeypatch.setattr(identify_module, "profile_stage", profile_stage)
    monkeypatch.setattr(identify_module, "film_valley", lambda prob: None)
    refined = types.SimpleNamespace(problem=problem, optimum=np.zeros(3), contenders=[])
    options = FitOptions(recentre_rounds=rounds)
    unc = identify_module.uncertainty(refined, np.zeros((1, 2, 2)), options, None, print)
    assert unc.recentred == rounds
    assert [c[0] for c in centres] == list(range(rounds + 1))
    assert unc.z[0] == rounds


def test_roughness_sets_cost_the_jitter_points_on_independent_realisation_sets(monkeypatch):
    # stand-ins: each set's realisation settings are one draw from its own generator, and a
    # point's cost is that draw plus the point's first coordinate, so each extra set's
    # Δcosts must equal the first coordinates' differences, and the sets must differ in
    # their draws (independent children of the fit's generator)
    draws = []

    def redrawn(problem, options, rng):
        draws.append(rng.uniform())
        return problem

    monkeypatch.setattr(stage_module, "redrawn", redrawn)
    monkeypatch.setattr(stage_module, "release_states", lambda problem, z, n, rng: None)
    monkeypatch.setattr(
        stage_module, "evaluate", lambda problem, points, y0: [draws[-1]] * len(points)
    )
    monkeypatch.setattr(
        stage_module,
        "synthetic_cost",
        lambda problem, options, noise, per, z: per + float(z[0]),
    )
    lap = types.SimpleNamespace(problem=None, noise=None)
    points = np.array([[0.0, 0.0], [0.5, 0.0], [2.0, 0.0]])
    first = np.array([0.4, 1.9])
    options = FitOptions(roughness_sets=3)
    out = stage_module.roughness_costs(
        lap, options, points, first, np.zeros((1, 4, 2)), np.random.default_rng(0)
    )
    assert out.shape == (3, 2)
    np.testing.assert_array_equal(out[0], first)
    np.testing.assert_allclose(out[1:], [[0.5, 2.0], [0.5, 2.0]])
    assert len(set(draws)) == 2
