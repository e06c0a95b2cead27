import itertools
import math

import pytest

from rattlefit.errors import ParameterError
from rattlefit.physics.oil import dynamic_viscosity, kinematic_viscosity_cst

# The seed paper's oil, Table 3: SAE 80W/90, 156.5 cSt at 40 °C, 15.7 cSt at 100 °C, 890 kg/m³.
OIL = (156.5, 15.7, 890.0)


def test_catalogue_points_are_reproduced():
    assert kinematic_viscosity_cst(40.0, *OIL[:2]) == pytest.approx(156.5, rel=1e-9)
    assert kinematic_viscosity_cst(100.0, *OIL[:2]) == pytest.approx(15.7, rel=1e-9)


def test_paper_value_at_20c():
    # "for an oil temperature of approximately 20 °C, a viscosity value (μ) of 0.5 Pa s"
    assert dynamic_viscosity(20.0, *OIL) == pytest.approx(0.5, rel=0.03)


def test_walther_form_against_hand_computation():
    # ASTM D341 by hand at 60 °C: log10 log10(ν+0.7) is linear in log10 T.
    def ll(nu):
        return math.log10(math.log10(nu + 0.7))

    x40, x100, x60 = (math.log10(t + 273.15) for t in (40, 100, 60))
    y60 = ll(156.5) + (ll(15.7) - ll(156.5)) * (x60 - x40) / (x100 - x40)
    expected = 10 ** (10**y60) - 0.7
    assert kinematic_viscosity_cst(60.0, 156.5, 15.7) == pytest.approx(expected, rel=1e-12)


def test_viscosity_decreases_with_temperature():
    values = [dynamic_viscosity(t, *OIL) for t in (0, 20, 40, 80)]
    assert all(a > b for a, b in itertools.pairwise(values))


@pytest.mark.parametrize(
    "args", [(20.0, 15.0, 150.0, 890.0), (20.0, 150.0, 15.0, -1.0), (400.0, *OIL)]
)
def test_bad_input_is_refused(args):
    with pytest.raises(ParameterError):
        dynamic_viscosity(*args)
