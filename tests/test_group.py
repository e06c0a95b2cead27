"""The squeeze-film group, the squeeze film's momentum per approach: its closed form, its
coordinate, and its profile interval in a fit."""

from __future__ import annotations

import math
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad

import rattlefit as rf
from rattlefit.inference.group import group_problem, group_value, to_group
from rattlefit.physics.model import (
    film_for_squeeze_momentum,
    squeeze_coefficient,
    squeeze_momentum,
)
from rattlefit.problem.options import FitOptions
from rattlefit.problem.parameters import parameter_prior
from rattlefit.problem.problem import problem_from

BOUNDARY = Path(__file__).resolve().parents[1] / "data" / "pairII_boundary_65.6_20pct_16Hz.h5"


@pytest.fixture(scope="module")
def boundary_problem():
    problem, _, _ = problem_from([rf.read_recording(BOUNDARY)], FitOptions.quick(seed=3))
    values = [0.08e-3, 0.02, 1.3, 0.9, 3e-6, float(problem.specs[5].center)]
    z = np.array([s.z_of(v) for s, v in zip(problem.specs, values, strict=True)])
    return problem, z


@pytest.mark.parametrize("a", [1e-6, 2e-5, 8.5e-5, 3e-4, 5e-3])
def test_the_squeeze_momentum_is_the_integral_of_the_squeeze_coefficient(a):
    # against quadrature of eq. (5)'s S(h) over h ≥ h_min (in ln h, to 40 e-foldings), the
    # short-film limit 4 μ Z a³/h_min², and its inverse in a
    mu, h_min, radius, width = 0.5, 2e-6, 0.012, 0.01
    quad_m = quad(
        lambda u: (
            float(squeeze_coefficient(h_min * math.exp(u), a, mu, radius, width))
            * h_min
            * math.exp(u)
        ),
        0.0,
        40.0,
        limit=400,
        epsrel=1e-10,
    )[0]
    m = float(squeeze_momentum(a, mu, h_min, radius, width))
    assert m == pytest.approx(quad_m, rel=1e-7)
    if a / math.sqrt(radius * h_min) < 0.05:
        assert m == pytest.approx(4 * mu * width * a**3 / h_min**2, rel=0.01)
    back = film_for_squeeze_momentum(jnp.asarray(m), mu, h_min, radius, width)
    assert float(back) == pytest.approx(a, rel=1e-12)


def test_the_group_coordinate_gives_every_realisation_the_films_parameters(boundary_problem):
    # the film follows from the group at the undithered viscosity and h_min and is then
    # dithered by the film's own column: each realisation's parameters are those of the same
    # point in a, to rounding
    problem, z = boundary_problem
    grouped, i = group_problem(problem, "film_half_length")
    # the group takes the film's place and declares its role: the physical parameters left
    # are the drag torque alone
    assert grouped.specs[i].role == "group"
    assert grouped.space.of_role("physical") == ("drag_torque",)
    z_g, _ = to_group(problem, grouped, i, z, np.eye(len(z)))
    mu = 1.3 * float(problem.viscosities[0])
    radius, width = (
        float(problem.models.curvature_radius[0]),
        float(problem.models.axial_width[0]),
    )
    assert group_value(problem, z, "film_half_length") == pytest.approx(
        float(squeeze_momentum(0.08e-3, mu, 3e-6, radius, width)), rel=1e-12
    )
    assert float(grouped.specs[i].value(z_g[i])) == pytest.approx(
        group_value(problem, z, "film_half_length"), rel=1e-9
    )
    dither = problem.rows(z[None])[3]  # each realisation's dither, as a simulation gets it
    dither_g = grouped.rows(z_g[None])[3]
    for d, d_g in zip(dither, dither_g, strict=True):
        want = problem.params_for(jnp.asarray(z), 0, jnp.asarray(d))
        got = grouped.params_for(jnp.asarray(z_g), 0, jnp.asarray(d_g))
        for name, value in want.as_dict().items():
            assert float(got.as_dict()[name]) == pytest.approx(float(value), rel=1e-9), name


def test_the_group_covariance_is_carried_by_the_coordinate_changes_jacobian(boundary_problem):
    # against central differences of the map z → z_g
    problem, z = boundary_problem
    grouped, i = group_problem(problem, "film_half_length")
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


def test_with_the_nuisances_known_the_groups_interval_is_the_films_carried_through():
    # h_min and the viscosity pinned by priors of 1 %: M is then a function of a alone, so
    # the group's interval is the film's carried through M(a), whatever the data say, with one
    # analytic threshold for both; and its estimate is M at the optimum. On the learned
    # likelihood, whose profiles are smooth: the synthetic one's Monte Carlo roughness can
    # keep a profile near its threshold over a factor of 1.5 in a, and the two intervals'
    # ends then fall anywhere in it
    rec = rf.read_recording(BOUNDARY)
    priors = {
        "min_film": parameter_prior("min_film", 2e-6, 0.01),
        "viscosity_scale": parameter_prior("viscosity_scale", 1.0, 0.01),
    }
    # the property is the profiles', not the density's quality: the quick preset's first two
    # learnings (768 simulations) without refinement suffice; the ratio held within its band
    # at seeds 0–2, and a budget of 384 did not (a at its prior's lower edge)
    options = FitOptions.quick(
        seed=0,
        priors=priors,
        likelihood="learned",
        calibration_simulations=0,
        learning_rounds=1,
        learning_refinements=0,
        check_realisations=8,
    )
    result = rf.identify([rec], options)
    a, g = (
        result.estimates.parameters["film_half_length"],
        result.estimates.parameters["squeeze_momentum"],
    )
    mp = result.estimates.map_params[0]
    problem = result.state.problem
    radius, width = (
        float(problem.models.curvature_radius[0]),
        float(problem.models.axial_width[0]),
    )

    def momentum(film):
        return float(squeeze_momentum(film, mp["viscosity"], mp["min_film"], radius, width))

    assert g.estimate == pytest.approx(momentum(mp["film_half_length"]), rel=1e-6)
    assert a.lower > 0 and g.lower > 0 and a.bound != "lower" and g.bound != "lower", (a, g)
    ratio = math.log(g.upper / g.lower) / math.log(momentum(a.upper) / momentum(a.lower))
    assert 0.8 < ratio < 1.2, (ratio, a, g)
    assert list(result.estimates.parameters)[3] == "squeeze_momentum"
    assert result.to_json()["parameters"]["squeeze_momentum"]["unit"] == "N s"
