"""diagnose's policy (rattlefit.diagnosis.policy) against what the evidence tests and the
effects' own declarations say."""

from pathlib import Path

import rattlefit as rf
from rattlefit.diagnosis import policy
from rattlefit.diagnosis.evidence import kind_of, recording_tests
from rattlefit.physics.effects import EFFECTS

DATA = Path(__file__).resolve().parents[1] / "data"


def test_every_model_free_test_points_to_an_effect_that_declares_it():
    # the tests a boundary recording gets (run-out, mesh order, tooth, drift, drive order) are
    # exactly the families the effects declare; each effect named only when found has one
    rec = rf.read_recording(DATA / "pairII_boundary_65.6_20pct_16Hz.h5")
    assert {kind_of(t) for t in recording_tests(rec)} == set(policy.POINTS_TO)
    assert all(EFFECTS[n].evidence in policy.POINTS_TO for n in policy.FOUND_ONLY)
    assert policy.ENCODER_VISIBLE < policy.FOUND_ONLY
    # a flank pattern's null is simulated only for tests that measure a size on the pitch circle
    assert all(policy.RELEVANT_SIZE_M[f] > 0 for f in policy.FLANK_PATTERN_TESTS)
    assert "drift" not in policy.FLANK_PATTERN_TESTS


def test_an_effect_the_encoders_see_is_fitted_only_when_found():
    effects = tuple(EFFECTS)
    seen = frozenset({"runout"})
    program = policy.in_program(effects, seen)
    assert "runout" in program and "tooth_errors" not in program
    assert "viscosity_drift" in program  # named only when found, but its absent end is free
    tried, skipped = policy.effects_to_try(effects, seen, band_gap=False)
    assert tried == ["runout"]
    assert skipped["tooth_errors"] is policy.Skipped.NOT_SEEN
    assert skipped["viscosity_drift"] is policy.Skipped.NOT_FOUND
    assert skipped["flank_friction"] is policy.Skipped.NO_BAND_GAP
    tried, _ = policy.effects_to_try(effects, seen, band_gap=False, every_effect=True)
    assert tried == list(effects)


def test_a_pair_of_effects_is_one_name_that_splits_back():
    name = policy.pair_name("runout", "flank_friction")
    assert policy.is_pair(name) and not policy.is_pair("runout")
    assert policy.effects_of(name) == ("runout", "flank_friction")
