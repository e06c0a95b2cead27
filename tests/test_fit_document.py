"""The fit's JSON document read back (rattlefit.inference.fit_document): the same state to the
last bit, so that a diagnosis started from the saved fit is the one started from the fit in
memory; and every document that is not such a fit, or recordings it was not fitted to, refused
naming the file and the field."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import rattlefit as rf
from rattlefit.diagnosis.diagnose import DiagnoseOptions, diagnose
from rattlefit.documents import FIT
from rattlefit.errors import RattlefitError
from rattlefit.inference.fit_document import read_fit
from rattlefit.io.recording import OperatingPoint
from rattlefit.problem.parameters import ParameterSpec
from rattlefit.report import diagnosis_document

#: A cheap fit of a short recording: the property is the document's, not the fit's.
CHEAP = dict(seed=3, n_starts=4, max_iterations=1, n_noise_realisations=4)


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    g = rf.table2_pair("II", center_distance_mm=65.0)
    op = OperatingPoint("boundary", 20.0, 52.36, 10.472, 16.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
    rec, _ = rf.synthesize(g, op, p, seed=5, duration=1.0)
    rec = rf.read_recording(rf.write_recording(rec, tmp_path_factory.mktemp("fit") / "r.h5"))
    result = rf.identify([rec], rf.FitOptions.quick(**CHEAP))
    path = rec.path.replace("r.h5", "fit.json")
    with open(path, "w") as f:
        json.dump(result.to_json(), f)
    return rec, result, path


def test_a_saved_fit_holds_the_state_to_the_last_bit(fitted):
    rec, result, path = fitted
    back = read_fit(path, [rec])
    st, bk = result.state, back.state
    np.testing.assert_array_equal(bk.z, st.z)
    np.testing.assert_array_equal(bk.covariance_z, st.covariance_z)
    noise_back, noise = bk.likelihood.noise, st.likelihood.noise
    for field in ("sigma", "whiten", "row_scale", "chi2_recordings"):
        np.testing.assert_array_equal(getattr(noise_back, field), getattr(noise, field))
    assert noise_back.sigma_dof == noise.sigma_dof and bk.options == st.options
    assert back.estimates.parameters == result.estimates.parameters
    assert back.estimates.map_params == result.estimates.map_params
    # the problem rebuilt from the recordings and the options is the fit's
    mine, theirs = back.problem_for([rec]), result.problem_for([rec])
    for field in ("data", "sigma", "y0", "dither", "encoder_phase"):
        np.testing.assert_array_equal(getattr(mine, field), getattr(theirs, field))


def test_a_diagnosis_from_the_saved_fit_is_the_one_from_the_fit_in_memory(fitted):
    rec, result, path = fitted
    options = DiagnoseOptions(
        effects=("flank_friction",), iterations=1, base_iterations=2, n_final=8,
        null_realisations=0,
    )  # fmt: skip
    docs = [
        diagnosis_document(diagnose([rec], options, baseline=baseline))
        for baseline in (result, read_fit(path, [rec]))
    ]
    assert json.dumps(untimed(docs[0]), sort_keys=True) == json.dumps(
        untimed(docs[1]), sort_keys=True
    )


def untimed(doc):
    """``doc`` without its wall-clock times (every key naming a time or a wall)."""
    if isinstance(doc, dict):
        return {k: untimed(v) for k, v in doc.items() if "time" not in k and "wall" not in k}
    if isinstance(doc, list):
        return [untimed(v) for v in doc]
    return doc


def test_a_document_that_is_not_a_saved_fit_or_of_other_recordings_is_refused(fitted, tmp_path):
    rec, result, path = fitted
    doc = result.to_json()
    for change, words in (
        ({"format": None}, f"format: expected 'rattlefit.fit' version {FIT.version}"),
        ({"state": None}, "state: not an object"),
    ):
        bad = tmp_path / "bad.json"
        bad.write_text(json.dumps({**doc, **change}))
        with pytest.raises(RattlefitError, match=words) as err:
            read_fit(bad)
        assert str(bad) in str(err.value)
    other = dataclasses.replace(rec, primary=rec.primary + 1, path="other.h5")
    with pytest.raises(RattlefitError, match=r"fit/recordings/0: other\.h5 is not the recording"):
        read_fit(path, [other])


def test_diagnose_and_sample_refuse_a_saved_fit_of_other_recordings_in_one_line(fitted):
    from click.testing import CliRunner

    from rattlefit.cli import main

    _, _, path = fitted
    other = "data/pairII_boundary_65.6_20pct_16Hz.h5"
    for command in ("diagnose", "sample"):
        result = CliRunner().invoke(main, [command, other, "--fit", path])
        lines = [x for x in result.output.splitlines() if x.startswith("rattlefit: error")]
        assert result.exit_code == 2 and len(lines) == 1, result.output
        assert "fit/recordings/0" in lines[0] and "is not the recording fitted there" in lines[0]


def test_a_parameter_added_through_the_options_alone_is_fitted_and_read_back(fitted, tmp_path):
    # a factor on the drag torque with a prior, given as FitOptions.extra_parameters and
    # nothing else: the model sees the product, the data cannot tell the factor from T_b (its
    # interval is its prior's), and the saved fit reads back with it
    rec, _, _ = fitted
    factor = ParameterSpec(
        "drag_factor", "1", 0.5, 2.0, center=1.0, log_sd=0.1, scales="drag_torque"
    )
    options = rf.FitOptions.quick(**CHEAP, profile_group=False, extra_parameters=(factor,))
    result = rf.identify([rec], options)
    est = result.estimates.parameters
    assert result.estimates.names[-1] == "drag_factor"
    assert est["drag_factor"].bound == "prior" and not est["drag_factor"].identified
    assert est["drag_factor"].lower < 1.0 < est["drag_factor"].upper
    drag = result.estimates.map_params[0]["drag_torque"]
    assert drag == pytest.approx(est["drag_torque"].estimate * est["drag_factor"].estimate)
    path = tmp_path / "fit.json"
    path.write_text(json.dumps(result.to_json()))
    back = read_fit(path, [rec])
    assert back.state.options.extra_parameters == (factor,)
    assert back.estimates.parameters["drag_factor"] == est["drag_factor"]
    with pytest.raises(RattlefitError, match=r"extra_parameters\[0\]: 'drag_torque' is a"):
        rf.FitOptions(extra_parameters=(ParameterSpec("drag_torque", "N m", 1e-3, 1.0),))
    with pytest.raises(RattlefitError, match="must declare the model field it scales"):
        rf.FitOptions(extra_parameters=(ParameterSpec("x", "1", 0.5, 2.0),))
