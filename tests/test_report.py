"""The identification table: what a person reads first."""

import math

import numpy as np
import pytest

from rattlefit.fit import FitOptions, FitResult, ParameterEstimate
from rattlefit.report import format_table


def _result(chi2, dof):
    a = ParameterEstimate("a", "m", 8.5e-5, 6e-5, 1.1e-4, True)
    tb = ParameterEstimate("drag_torque", "N m", None, 0.0, 0.05, False, "upper")
    return FitResult(
        parameters={"a": a, "drag_torque": tb},
        correlation=np.eye(2),
        names=["a", "drag_torque"],
        chi2=chi2,
        dof=dof,
        n_iterations=3,
        success=True,
        message="converged",
        seed=7,
        wall_time=1.0,
        recordings=[],
        options=FitOptions(),
        z=np.zeros(2),
        covariance_z=np.eye(2),
        measured_features=[],
        fitted_features=[],
        sigma=[],
        band_centers=np.zeros(1),
        map_params=[],
    )


def test_p_value_is_the_chi2_tail():
    # with two degrees of freedom the χ² tail is exp(−χ²/2) in closed form
    assert _result(3.0, 2).p_value == pytest.approx(math.exp(-1.5), rel=1e-12)
    assert _result(20.0, 2).p_value == pytest.approx(math.exp(-10.0), rel=1e-12)


def test_table_warns_only_about_a_poor_fit():
    good = format_table(_result(30.0, 28))
    assert "warning" not in good
    assert "0.085" in good and "[0.06, 0.11]" in good  # mm
    assert "≤ 0.05" in good and "upper bound only" in good
    bad = _result(120.0, 28)
    assert bad.poor_fit and bad.to_json()["fit"]["poor_fit"] is True
    text = format_table(bad)
    assert "warning: χ² is far above its 28 degrees of freedom" in text
    assert "√(χ²/dof) = 2.1" in text
