"""The squeeze-film group G = μ a³/h_min²: its coordinate, and its profile interval in a fit."""

from __future__ import annotations

import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import rattlefit as rf
from rattlefit.inference.group import group_problem, group_value, to_group
from rattlefit.inference.options import FitOptions
from rattlefit.inference.parameters import nuisance_prior
from rattlefit.inference.problem import problem_from

BOUNDARY = Path(__file__).resolve().parents[1] / "data" / "pairII_boundary_65.6_20pct_16Hz.h5"


@pytest.fixture(scope="module")
def boundary_problem():
    problem, _, _ = problem_from([rf.read_recording(BOUNDARY)], FitOptions.quick(seed=3))
    values = [0.08e-3, 0.02, 1.3, 0.9, 3e-6, float(problem.specs[5].center)]
    z = np.array([s.z_of(v) for s, v in zip(problem.specs, values, strict=True)])
    return problem, z


def test_the_group_coordinate_gives_every_realisation_the_films_parameters(boundary_problem):
    # a = (G h_min²/μ)^(1/3) with G's dither 3× the film's plus the viscosity's: each
    # realisation's parameters are those of the same point in a, to rounding
    problem, z = boundary_problem
    grouped, i = group_problem(problem, "a")
    z_g, _ = to_group(problem, grouped, i, z, np.eye(len(z)))
    mu = 1.3 * float(problem.viscosities[0])
    assert group_value(problem, z, "a") == pytest.approx(mu * 0.08e-3**3 / 3e-6**2, rel=1e-9)
    assert float(grouped.specs[i].value(z_g[i])) == pytest.approx(
        group_value(problem, z, "a"), rel=1e-9
    )
    m = problem.dither.shape[0]
    d, d_g = problem.dither_offsets(m), grouped.dither_offsets(m)
    assert d.shape == d_g.shape  # the same dithered columns, one of them recombined
    for k in range(m):
        want = problem.params_for(jnp.asarray(z), 0, jnp.asarray(problem._dither(m)[k]))
        got = grouped.params_for(jnp.asarray(z_g), 0, jnp.asarray(grouped._dither(m)[k]))
        for name, value in want.as_dict().items():
            assert float(got.as_dict()[name]) == pytest.approx(float(value), rel=1e-12), name


def test_the_group_covariance_is_carried_by_the_coordinate_changes_jacobian(boundary_problem):
    # against central differences of the map z → z_g
    problem, z = boundary_problem
    grouped, i = group_problem(problem, "a")
    p = len(z)
    jac = np.zeros((p, p))
    for j in range(p):
        h = 1e-6 * np.eye(p)[j]
        up, down = (to_group(problem, grouped, i, z + s * h, np.eye(p))[0] for s in (1, -1))
        jac[:, j] = (up - down) / 2e-6
    cov = np.diag(np.linspace(0.1, 0.6, p)) + 0.02
    np.testing.assert_allclose(
        to_group(problem, grouped, i, z, cov)[1], jac @ cov @ jac.T, rtol=1e-6
    )


def test_with_the_nuisances_known_the_groups_interval_is_the_films_cubed():
    # h_min and the viscosity pinned by priors of 1 %: G ∝ a³, so the group's log width is
    # three times the film's, whatever the data say (to the profiles' Monte Carlo roughness,
    # with one analytic threshold for both and their ends bisected); and its estimate is
    # μ a³/h_min² at the optimum
    rec = rf.read_recording(BOUNDARY)
    priors = {
        "min_film": nuisance_prior("min_film", 2e-6, 0.01),
        "viscosity_scale": nuisance_prior("viscosity_scale", 1.0, 0.01),
    }
    options = FitOptions.quick(
        seed=0, priors=priors, profile_bisections=4, profile_rounds=1, profile_roughness=False
    )
    result = rf.identify([rec], options)
    a, g = result.parameters["a"], result.parameters["squeeze_film_group"]
    mp = result.map_params[0]
    assert g.estimate == pytest.approx(
        mp["viscosity"] * mp["film_half_length"] ** 3 / mp["min_film"] ** 2, rel=1e-6
    )
    assert a.lower > 0 and g.lower > 0 and a.bound != "lower" and g.bound != "lower", (a, g)
    ratio = math.log(g.upper / g.lower) / math.log(a.upper / a.lower)
    assert 2.4 < ratio < 3.6, (ratio, a, g)
    assert list(result.parameters)[3] == "squeeze_film_group"
    assert result.to_json()["parameters"]["squeeze_film_group"]["unit"] == "Pa s m"
