"""The identification table: what a person reads first."""

import math

import numpy as np
import pytest

from rattlefit import FitOptions, FitResult
from rattlefit.inference.profile import profile_threshold
from rattlefit.inference.result import ParameterEstimate
from rattlefit.report import format_table


def _result(chi2, dof, chi2_recordings=(), recordings=(), regime_share=(), profile=None):
    a = ParameterEstimate("a", "m", 8.5e-5, 6e-5, 1.1e-4, True)
    tb = ParameterEstimate("drag_torque", "N m", None, 0.0, 0.05, False, "upper")
    mu = ParameterEstimate("viscosity", "Pa s", None, 0.3, 0.6, False, "interval")
    return FitResult(
        parameters={"a": a, "drag_torque": tb, "viscosity": mu},
        correlation=np.eye(3),
        names=["a", "drag_torque", "viscosity"],
        chi2=chi2,
        dof=dof,
        n_iterations=3,
        success=True,
        message="converged",
        seed=7,
        wall_time=1.0,
        recordings=list(recordings),
        options=FitOptions(),
        z=np.zeros(3),
        covariance_z=np.eye(3),
        measured_features=[],
        fitted_features=[],
        sigma=[],
        band_centers=np.zeros(1),
        map_params=[],
        chi2_recordings=list(chi2_recordings),
        regime_share=list(regime_share),
        profile=profile or {},
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
    # two-sided but wider than an identified interval: how much wider is said
    assert "[0.3, 0.6]" in good and "interval too wide (×2.00 > ×1.5)" in good
    bad = _result(120.0, 28)
    assert bad.poor_fit and bad.to_json()["fit"]["poor_fit"] is True
    text = format_table(bad)
    assert "warning: χ² is far above its 28 degrees of freedom" in text
    assert "√(χ²/dof) = 2.1" in text


def test_a_joint_fit_names_the_recording_the_model_does_not_explain():
    # 57 dof over two recordings: 28.5 each. 30 is an ordinary χ² on 28.5 (p ≈ 0.4), 400 is not
    files = ["/data/pairII_boundary_65.6.h5", "/data/pairII_oiljet_65.6.h5"]
    bad = _result(430.0, 57, chi2_recordings=[30.0, 400.0], recordings=files)
    assert bad.poorly_fitted == [1]
    assert bad.to_json()["fit"]["poorly_fitted_recordings"] == [files[1]]
    text = format_table(bad)
    assert "does not explain pairII_oiljet_65.6.h5 within" in text
    assert "each recording's own √(χ²/dof)" in text and "boundary" not in text
    # both merely mediocre, poor only together: no single file is blamed
    both = _result(100.0, 57, chi2_recordings=[50.0, 50.0], recordings=files)
    assert both.poor_fit and both.poorly_fitted == []
    assert "does not explain these recordings together" in format_table(both)


def test_a_recording_in_a_minority_regime_is_named():
    # the fit compares each recording with its own regime; where that is a minority of the
    # model's releases at the optimum, the reader must learn it (and which file, when several)
    assert "note" not in format_table(_result(30.0, 28, regime_share=[0.9]))
    one = format_table(_result(30.0, 28, recordings=["x/r.h5"], regime_share=[0.25]))
    assert "note: the recording is in a regime that 25% of the model's releases reach" in one
    two = format_table(
        _result(60.0, 57, [30.0, 30.0], ["x/a.h5", "x/b.h5"], regime_share=[1.0, 0.2])
    )
    assert "note: b.h5 is in a regime that 20%" in two and "a.h5 is in" not in two


def _allowance(line):
    # "… (χ²₁ 3.84 + 1.645 × X, <source>)": the sd the line says the allowance is made of
    return float(line.split("1.645 × ")[1].split(",")[0])


@pytest.mark.parametrize(
    ("mc", "jitter", "source"),
    [
        (4.0, np.array([[1.0, -2.0, 1.5, -1.0]]), "Monte Carlo"),  # below the analytic
        (4.0, np.array([[14.1, 10.0, -7.4, 13.7]]), "roughness"),  # one set: its rms
        (4.9, np.array([[55.7, 10.9, -11.0, 24.5], [51.6, 17.4, -8.1, 42.7]]), "spread"),
    ],
)
def test_the_table_says_what_set_the_profile_threshold(mc, jitter, source):
    # the line must name the allowance profile_threshold used, with the sd that reproduces it
    threshold = profile_threshold(mc, jitter)
    profile = {"threshold": threshold, "monte_carlo_sd": mc, "realisation_sets": len(jitter)}
    profile["roughness_rms"] = float(np.sqrt(np.mean(jitter[0] ** 2)))
    if len(jitter) > 1:
        profile["roughness_sd"] = float(np.sqrt(np.mean(np.var(jitter, axis=0, ddof=1))))
    res = _result(30.0, 28, profile=profile)
    (line,) = [x for x in format_table(res).splitlines() if x.startswith("95 % intervals")]
    assert source in line and f"within {threshold:.1f} " in line
    assert 3.84 + 1.645 * _allowance(line) == pytest.approx(threshold, abs=0.1)
    assert res.to_json()["fit"]["profile"]["threshold"] == threshold
    assert "95 % intervals" not in format_table(_result(30.0, 28))  # nothing to say
