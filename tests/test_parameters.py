"""The fitted parameters' coordinates and priors (:mod:`rattlefit.problem.parameters`),
against closed forms: the map from z is ``lower · (upper/lower)^sigmoid(z)``, its
log-derivative ``log(upper/lower) · s(1 − s)``, and the priors' rows are log-normal."""

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rattlefit.errors import RattlefitError
from rattlefit.problem.parameters import (
    NUISANCES,
    Z_END,
    ParameterSpec,
    default_specs,
    film_names,
    parse_prior,
)


def test_the_coordinate_maps_onto_the_range_and_back():
    spec = ParameterSpec("film_half_length", "m", 1e-6, 5e-3)
    # the closed form: z = 0 is the geometric middle of the range
    assert spec.value(0.0) == pytest.approx(math.sqrt(1e-6 * 5e-3), rel=1e-12)
    for v in (2e-6, 85e-6, 1e-3, 4.9e-3):
        assert spec.value(spec.z_of(v)) == pytest.approx(v, rel=1e-10)
    # the ends are approached, never reached or crossed (no clipping needed)
    assert 1e-6 < spec.value(-Z_END) < 1.01e-6 and 4.95e-3 < spec.value(Z_END) < 5e-3
    # numpy and JAX agree (the fit traces it; its host side does not)
    zs = np.linspace(-6.0, 6.0, 7)
    np.testing.assert_allclose(
        np.asarray(spec.value(jnp.asarray(zs))), spec.value(zs), rtol=1e-14, atol=0
    )


def test_the_log_derivative_is_the_closed_form_and_jaxs():
    spec = ParameterSpec("drag_torque", "N m", 2e-3, 0.5)
    for z in (-3.0, -0.4, 0.0, 1.7):
        s = 1.0 / (1.0 + math.exp(-z))
        assert spec.dlog_dz(z) == pytest.approx(math.log(0.5 / 2e-3) * s * (1 - s), rel=1e-12)
        auto = jax.grad(lambda t: jnp.log(spec.value(t)))(z)
        assert float(auto) == pytest.approx(spec.dlog_dz(z), rel=1e-10)


def test_a_spec_needs_a_positive_increasing_range():
    for lower, upper in ((0.0, 1.0), (2.0, 1.0), (1.0, 1.0), (-1.0, 1.0)):
        with pytest.raises(RattlefitError, match="need 0 < lower < upper"):
            ParameterSpec("x", "1", lower, upper)


def test_default_specs_and_film_names():
    assert film_names(["boundary", "boundary"]) == ("film_half_length", "film_half_length")
    assert film_names(["boundary", "oil_jet", "boundary"]) == (
        "film_half_length[boundary]",
        "film_half_length[oil_jet]",
        "film_half_length[boundary]",
    )
    specs = default_specs([], {})
    names = [s.name for s in specs]
    assert names == [
        "film_half_length",
        "drag_torque",
        "viscosity_scale",
        "stiffness_scale",
        "min_film",
    ]
    # the free parameters have no prior; every nuisance has one, centred inside its range
    assert [s.name for s in specs if s.log_sd is None] == ["film_half_length", "drag_torque"]
    assert set(NUISANCES) == {"viscosity_scale", "stiffness_scale", "min_film"}
    for s in specs:
        if s.log_sd is not None:
            assert s.lower < s.center < s.upper


def test_a_prior_from_the_command_line():
    # the centre in the unit the table shows, named: h_min in µm
    name, spec = parse_prior("min_film=2um:0.1")
    assert (name, spec.center, spec.log_sd, spec.unit) == ("min_film", 2e-6, 0.1, "m")
    assert parse_prior("min_film=2 µm:0.1")[1].center == 2e-6
    assert parse_prior("viscosity_scale=1.2:0.05")[1].center == 1.2
    # the range stays the default's
    (default,) = (s for s in default_specs([], {}) if s.name == "min_film")
    assert (spec.lower, spec.upper) == (default.lower, default.upper)
    # the physical parameters: the film in mm (also per lubrication), the drag torque and the
    # viscosity in their SI display units, named or not; each keeps its role
    name, spec = parse_prior("film_half_length[boundary]=0.085mm:0.3")
    assert (name, spec.name, spec.center, spec.role) == (name, name, 8.5e-5, "physical")
    assert parse_prior("drag_torque=0.025:0.3")[1].center == 0.025
    assert parse_prior("drag_torque=0.025Nm:0.3")[1].center == 0.025
    name, spec = parse_prior("viscosity=0.49Pas:0.2")
    assert (name, spec.center, spec.unit) == ("viscosity", 0.49, "Pa s")
    for text, problem in (
        ("min_film=2um", "expected NAME=CENTER:LOG_SD"),
        ("min_film=x:0.1", "expected NAME=CENTER:LOG_SD"),
        ("min_film=2e-6:0.1", "is in µm and must say so, e.g. min_film=2um:0.1"),
        ("viscosity_scale=1mm:0.1", "has no unit"),
        ("min_film=1000um:0.1", "outside the range"),
        ("min_film=2um:-0.1", "log_sd must be a positive number"),
        ("backlash=0.8mm:0.1", "not a parameter that takes a prior"),
        (
            "film_half_length=8.5e-5:0.2",
            r"is in mm and must say so, e.g\. "
            r"film_half_length=0\.085mm:0\.2 if 8\.5e-05 was in m",
        ),
        ("drag_torque=0.025mm:0.3", "drag_torque's centre is in N m"),
    ):
        with pytest.raises(RattlefitError, match=problem):
            parse_prior(text)


def test_a_prior_on_the_viscosity_in_pa_s_is_the_factors_at_the_first_recordings_oil():
    import rattlefit as rf
    from rattlefit import rig

    rigs = [rig.setup(rf.read_recording("data/pairII_boundary_65.6_20pct_16Hz.h5"))]
    _, spec = parse_prior("viscosity=0.3:0.2")
    options = rf.FitOptions(priors={"viscosity": spec})  # accepted under its own name
    (scale,) = (s for s in default_specs(rigs, options.priors) if s.name == "viscosity_scale")
    assert scale.center == pytest.approx(0.3 / rigs[0].viscosity, rel=1e-12)
    assert (scale.log_sd, scale.role) == (0.2, "nuisance")
    assert "viscosity" not in [s.name for s in default_specs(rigs, options.priors)]


def test_a_role_is_derived_from_the_prior_only_when_not_given():
    assert ParameterSpec("x", "m", 1.0, 2.0).role == "physical"
    assert ParameterSpec("x", "m", 1.0, 2.0, center=1.5, log_sd=0.1).role == "nuisance"
    assert ParameterSpec("x", "m", 1.0, 2.0, center=1.5, log_sd=0.1, role="physical").role == (
        "physical"
    )
    with pytest.raises(RattlefitError, match="role 'free' is not one of"):
        ParameterSpec("x", "m", 1.0, 2.0, role="free")


def _two_lubrication_space():
    """A space as a fit of a boundary and an oil-jet recording has it, by hand: its films,
    the shared parameters and one backlash per recording."""
    from rattlefit.problem.space import ParameterSpace

    films = ("film_half_length[boundary]", "film_half_length[oil_jet]")
    shared = [s for s in default_specs([], {}) if s.name != "film_half_length"]
    own = [ParameterSpec(f, "m", 1e-6, 5e-3, role="physical") for f in films]
    backlash = [
        ParameterSpec(f"backlash[{k}]", "m", 1e-4, 4e-4, center=2e-4, log_sd=0.01) for k in range(2)
    ]
    return ParameterSpace((*own, *shared, *backlash), films)


def test_the_space_maps_named_values_onto_each_recordings_model_parameters():
    space = _two_lubrication_space()
    values = dict(zip(space.names, [8e-5, 1e-3, 0.02, 1.3, 0.9, 3e-6, 2.1e-4, 2.2e-4], strict=True))
    viscosities = np.array([0.49, 0.40])  # each recording's catalogue μ, Pa s
    for r, film in enumerate(space.films):
        p = space.rattle_params(values, r, viscosities)
        assert float(p.film_half_length) == values[film]
        assert float(p.backlash) == values[f"backlash[{r}]"]
        # the viscosity factor scales the recording's own catalogue viscosity
        assert float(p.viscosity) == pytest.approx(1.3 * viscosities[r], rel=1e-15)
        assert (float(p.drag_torque), float(p.min_film)) == (0.02, 3e-6)
        assert float(p.stiffness_scale) == 0.9
    # traced: the recording's index may be a tracer
    at = jax.jit(lambda r: space.rattle_params(values, r, viscosities).film_half_length)
    assert float(at(jnp.asarray(1))) == values["film_half_length[oil_jet]"]


def test_a_parameter_added_to_the_space_alone_reaches_the_model_and_the_documents():
    """A toy parameter, a factor on the drag torque with a prior, added through the space and
    nothing else: the model's drag is the product, its coordinate round-trips, the space's
    document reads back, and the roles list it among the nuisances."""
    from rattlefit.problem.space import ParameterSpace

    space = _two_lubrication_space()
    toy = ParameterSpec("drag_factor", "1", 0.5, 2.0, center=1.0, log_sd=0.1, scales="drag_torque")
    bigger = space.extended(toy)
    assert bigger.names[-1] == "drag_factor" and "drag_factor" in bigger.of_role("nuisance")
    z = np.linspace(-1.0, 1.0, len(bigger.specs))
    values = bigger.values(z)
    p = bigger.rattle_params(values, 0, np.array([0.49, 0.40]))
    assert float(p.drag_torque) == pytest.approx(
        values["drag_torque"] * values["drag_factor"], rel=1e-15
    )
    np.testing.assert_allclose(bigger.z_of(values), z, rtol=0, atol=1e-9)
    again = ParameterSpace.from_dict(json.loads(json.dumps(bigger.to_dict())))
    assert again == bigger
    # a spec is checked against the one registry of units, and a factor against the model
    with pytest.raises(RattlefitError, match="drag_torque is in 'N m'"):
        ParameterSpec("drag_torque", "N", 1e-3, 1.0)
    with pytest.raises(RattlefitError, match="scales 'drag'"):
        ParameterSpec("x", "1", 0.5, 2.0, scales="drag")
    with pytest.raises(RattlefitError, match="drag_factor named twice"):
        bigger.extended(toy)


def test_an_effects_fitted_fields_are_specs_of_the_effect_role():
    """A diagnosis candidate's fields are neither physical parameters (the starts, the free
    parameters of its screening) nor nuisances (the priors' block)."""
    from rattlefit.diagnosis.trial import effect_specs
    from rattlefit.physics.effects import EFFECTS

    for name in EFFECTS:
        specs = effect_specs(name)
        assert specs and {s.role for s in specs} == {"effect"}, name
