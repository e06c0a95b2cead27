"""Model-free evidence (rattlefit.features.orders, .drift; rattlefit.diagnosis.evidence).

References the code did not produce: the injected run-out of a simulated recording (its
size and wheel), the independent shared recordings with their truth, and the second rig
model of validation/second_rig with its stated effects.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import rattlefit as rf
from rattlefit import synthesize
from rattlefit.diagnosis.evidence import findings
from rattlefit.features.drift import ar1_factor, drift_evidence, trend_t, window_length
from rattlefit.features.orders import (
    contact_events,
    drive_order_evidence,
    local_inflation,
    order_projections,
    primary_residual,
    quantisation_inflation,
    ripple_orders,
    runout_evidence,
)
from rattlefit.io.recording import OperatingPoint
from rattlefit.physics import effects as fx
from rattlefit.testing.shared import recordings_dir

SHARED = recordings_dir(Path(__file__).resolve().parents[1])
FAMILY = 0.01  # the diagnosis' default family-wise level
RECORDING_SEED = 5
#: the fitted amplitude must hold the injected one within this many standard errors, plus
#: a quantisation allowance (the encoders resolve 2π/40000 rad: 3.2 µm on pair II's r1)
Z_TOLERANCE = 4.0
QUANTISATION_ALLOWANCE_M = 1.0e-6


@pytest.fixture(scope="module")
def boundary_pair2():
    """Pair II, 65.6 mm, boundary, 20 % at 16 Hz (the paper's headline point) with run-out of
    the driven wheel, and the same without it."""
    g = rf.table2_pair("II", center_distance_mm=65.6)
    op = OperatingPoint("boundary", 20.0, 52.36, 10.472, 16.0)
    p = rf.RattleParams(0.085e-3, 0.025, 0.4942, g.backlash)
    runout = fx.Runout(driven_amplitude=10e-6, driven_phase=0.7)
    with_runout, _ = synthesize(g, op, p, seed=RECORDING_SEED, effects=[runout])
    clean, _ = synthesize(g, op, p, seed=RECORDING_SEED)
    return with_runout, clean


def test_runout_of_the_driven_wheel_is_found_on_that_wheel_with_its_size(boundary_pair2):
    # the catalogue's run-out moves both flanks alike by e2 sin(θ2 + φ2) on the pitch circle:
    # each flank's swing against the driven wheel's angle must give e2
    rec, _ = boundary_pair2
    primary, secondary = runout_evidence(rec)
    assert secondary.p_value < 1e-6, secondary
    for flank in ("upper", "lower"):
        if f"{flank}_m" in secondary.detail:  # a flank met too rarely is left out
            swing, sd = secondary.detail[f"{flank}_m"], secondary.detail[f"{flank}_sd_m"]
            assert abs(swing - 10e-6) < Z_TOLERANCE * sd + QUANTISATION_ALLOWANCE_M, (
                flank,
                swing,
                sd,
            )
    assert primary.p_value > 1e-3, primary


def test_a_clean_recording_gives_no_significant_finding(boundary_pair2):
    # at the diagnosis' family-wise 1 % a calibrated set of tests names one clean realisation
    # in a hundred, and another CPU makes another realisation: one recording is held to a
    # tenth of that level, which a miscalibrated test (p ≈ 1e-10 on clean data) still fails
    _, clean = boundary_pair2
    found = findings([clean], FAMILY / 10)
    assert not any(f.significant for f in found), [f.as_dict() for f in found]
    assert len(found) == 7  # run-out ×2, mesh order, tooth ×2, drift, drive order
    assert {f.effect for f in found} == {
        "runout",
        "tooth_errors",
        "tooth_defect",
        "viscosity_drift",
        "drive_ripple",
    }


def test_contact_events_lie_on_the_flanks_of_a_clean_recording(boundary_pair2):
    # without geometric errors both flanks sit at ±backlash/2 of the median-centred Δθ*:
    # the envelope of the contact positions spans the recorded backlash
    _, clean = boundary_pair2
    ev = contact_events(clean)
    b = clean.gear_pair.angular_backlash_rad
    upper = np.percentile(ev.position[ev.flank == 1], 95)
    lower = np.percentile(ev.position[ev.flank == -1], 5)
    assert upper - lower == pytest.approx(b, rel=0.03)
    assert np.all(np.diff(ev.time) >= 0)


def test_drift_windows_hold_whole_driven_wheel_revolutions(boundary_pair2):
    rec, _ = boundary_pair2
    n = window_length(rec)
    f_driven = rec.operating.drive_mean_speed_rad_s / (2 * math.pi) / rec.gear_ratio
    revolutions = n / rec.sample_rate_hz * f_driven
    assert abs(revolutions - round(revolutions)) < 0.01 and round(revolutions) >= 1


def test_drift_is_found_when_the_oil_warms(boundary_pair2):
    # the viscosity falls fourfold over a 6 s recording of a 1 mm film: the film's damping
    # falls and the rattle grows (over seeds p = 2e-10 … 8e-6, against the diagnosis' level
    # 1.7e-3; over 3 s, or with a 0.3 mm film, p spreads across that level); the clean twin
    # shows no drift
    g = rf.table2_pair("II", center_distance_mm=65.6)
    op = OperatingPoint("boundary", 20.0, 52.36, 10.472, 16.0)
    p = rf.RattleParams(1e-3, 0.025, 0.4942, g.backlash)
    warm = fx.ViscosityDrift(rate=math.log(4.0) / 6.0)
    rec, _ = synthesize(g, op, p, seed=RECORDING_SEED, effects=[warm], duration=6.0)
    assert drift_evidence(rec).p_value < FAMILY / 6
    _, clean = boundary_pair2
    assert drift_evidence(clean).p_value > FAMILY / 6


def test_a_drift_trend_without_the_drive_is_the_least_squares_slope():
    # closed form: with a constant drive the trend is scipy's straight-line fit, its standard
    # error widened by the residuals' autocorrelation
    rng = np.random.default_rng(3)
    values = rng.standard_normal((9, 2)) + 0.1 * np.arange(9)[:, None]
    slope, slope_sd, _, dof = trend_t(values, np.full(9, 52.36))
    for j in range(2):
        fit = stats.linregress(np.arange(9), values[:, j])
        residuals = values[:, j] - fit.intercept - fit.slope * np.arange(9)
        assert slope[j] == pytest.approx(fit.slope, rel=1e-10)
        assert slope_sd[j] == pytest.approx(fit.stderr * math.sqrt(ar1_factor(residuals)))
    assert dof == 7


def test_a_beat_the_drive_shows_too_is_no_drift_and_a_trend_it_does_not_show_is():
    # Windows 0.045 drive cycles longer than whole ones: over 11 windows the drive's window
    # means go through half a beat, like a trend, and a drive-locked statistic follows them.
    # On time alone that beat is a trend; beyond the drive it is not, and a real trend beside
    # it stays one.
    windows = 11
    drive = 52.36 + 0.2 * np.cos(2 * np.pi * 0.045 * np.arange(windows))
    level = 0.01 / 2
    flagged = {"time only": 0, "beyond the drive": 0, "trend": 0}
    seeds = range(40)
    for seed in seeds:
        noise = 0.002 * np.random.default_rng(seed).standard_normal((windows, 2))
        locked = 0.5 * (drive - drive.mean())
        values = np.column_stack([locked, locked + 0.02 * np.arange(windows)]) + noise
        _, _, t_time, dof_time = trend_t(values, np.full(windows, drive.mean()))
        _, _, t, dof = trend_t(values, drive)
        assert dof == dof_time - 1
        flagged["time only"] += 2 * stats.t.sf(abs(t_time[0]), dof_time) < level
        flagged["beyond the drive"] += 2 * stats.t.sf(abs(t[0]), dof) < level
        flagged["trend"] += 2 * stats.t.sf(abs(t[1]), dof) < level
    assert flagged["time only"] >= 0.9 * len(seeds)
    assert flagged["beyond the drive"] <= 0.1 * len(seeds)
    assert flagged["trend"] >= 0.9 * len(seeds)


def _shared_truth():
    path = SHARED / "truth.json"
    return json.loads(path.read_text()) if path.is_file() else {}


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"needs the independent recordings at {SHARED}")
@pytest.mark.parametrize("name", sorted(_shared_truth()))
def test_shared_recordings_run_out_is_found_and_nothing_else(name):
    # independent data: each run-out file gets run-out, every other file no finding at all
    truth = _shared_truth()[name]
    path = next(SHARED.glob(f"**/{name}.h5"), None)
    if path is None:
        pytest.skip(f"needs {name}.h5, not under {SHARED}")
    found = findings([rf.read_recording(path)], FAMILY)
    named = {f.effect for f in found if f.significant}
    expected = {"runout"} if "runout" in truth["unmodelled_effects"] else set()
    assert named == expected, [f.as_dict() for f in found if f.significant]


@pytest.mark.parametrize(("order", "ripple"), [(2, 2e-3), (24, 5e-4), (37, 3e-4)])
def test_a_ripple_of_the_primary_shaft_is_found_at_its_order_with_its_size(
    boundary_pair2, order, ripple
):
    # the clean recording's primary encoder with an angle ripple A at an order added (counts
    # rounded, so A spans a few counts): the acceleration amplitude is (order · Ω)² A, an
    # engine's firing order or an electric motor's slot order, and the clean encoder has none
    import dataclasses

    _, clean = boundary_pair2
    assert not drive_order_evidence(clean).p_value < FAMILY / 7
    theta = clean.theta_primary
    counts = clean.primary + np.round(
        ripple * np.sin(order * theta) * clean.counts_per_rev / (2 * np.pi)
    )
    rec = dataclasses.replace(clean, primary=counts.astype(clean.primary.dtype))
    test = drive_order_evidence(rec)
    assert test.p_value < 1e-6 and test.detail["order"] == order
    omega = rec.operating.drive_mean_speed_rad_s
    # a ripple of a few counts, rounded, is sized to within 10 %
    assert test.amplitude == pytest.approx((order * omega) ** 2 * ripple, rel=0.1)


def test_the_encoder_quantisation_of_a_smooth_drive_is_no_ripple(boundary_pair2):
    # counting a smoothly turning shaft leaves lines at orders set by the speed law (here,
    # 20 % at 16 Hz, order 126, χ² ≈ 40 where white noise gives 2): the quantisation null
    # holds them, where the neighbours' level alone would call them a ripple
    _, clean = boundary_pair2
    residual = primary_residual(clean, 6)
    orders = ripple_orders(clean)
    chi2 = order_projections(residual, clean.theta_primary, orders)[0]
    local = local_inflation(order_projections(residual, clean.theta_primary, orders + 0.5)[0])
    by_neighbours = stats.chi2.sf(chi2 / local, 2).min() * orders.size
    assert by_neighbours < 1e-10
    null = quantisation_inflation(clean, orders, 6)
    assert np.all(chi2 / np.maximum(local, null) < 30)
    assert drive_order_evidence(clean).p_value > 0.01


@pytest.mark.parametrize("teeth", [11, 43])
def test_the_smooth_part_of_the_tooth_offsets_is_projected_out(teeth):
    from rattlefit.features.orders import RUNOUT_ORDERS, smooth_part_removed

    angle = 2 * math.pi * (np.arange(teeth) + 0.5) / teeth
    proj = smooth_part_removed(teeth, np.ones(teeth, bool))
    # a constant, an eccentric and an oval swing across the teeth leave nothing
    for order in RUNOUT_ORDERS:
        swing = 3.0 + np.cos(order * angle + 0.4)
        assert np.allclose(proj @ swing, 0.0, atol=1e-12)
    # one tooth of depth d keeps d (1 − 5/T) on that tooth: the mean and two orders take 5 of
    # the T dimensions, and equally spaced teeth spread them evenly (closed form)
    notch = np.zeros(teeth)
    notch[3] = 1.0
    assert (proj @ notch)[3] == pytest.approx(1 - (1 + 2 * len(RUNOUT_ORDERS)) / teeth)
    # an untested tooth takes no part
    tested = np.ones(teeth, bool)
    tested[5] = False
    assert np.all(smooth_part_removed(teeth, tested)[5] == 0.0)


def test_the_drive_ripple_candidate_takes_the_order_its_test_found(boundary_pair2):
    # a ripple found at order 24 is fitted to the bands as a ripple at order 24, not at the
    # candidate's default order
    import dataclasses

    from rattlefit.diagnosis.evidence import candidate_static
    from rattlefit.diagnosis.trial import candidate_problem
    from rattlefit.problem.options import FitOptions
    from rattlefit.problem.problem import problem_from

    _, clean = boundary_pair2
    counts = clean.primary + np.round(
        5e-4 * np.sin(24 * clean.theta_primary) * clean.counts_per_rev / (2 * np.pi)
    )
    rec = dataclasses.replace(clean, primary=counts.astype(clean.primary.dtype))
    static = candidate_static(findings([rec], FAMILY))
    assert static == {"drive_ripple": {"order": 24}}
    assert candidate_static(findings([clean], FAMILY)) == {}
    base, _, _ = problem_from([rec], FitOptions.quick())
    problem, _ = candidate_problem(base, ("drive_ripple",), static)
    assert problem.effects[0].order == 24


def test_motor_cogging_at_order_24_from_the_second_rig_is_found_and_named():
    # The second rig (validation/second_rig, another simulator) with its servo's cogging torque
    # at order 24 of the motor's rotation inside the speed loop, at 14 Hz (where order 24 is
    # no drive harmonic): the drive-order test finds order 24 at about the acceleration the
    # rig states, the verdict names a drive ripple and its candidate is fitted at order 24
    # (clean recordings' silence is the shared recordings' and the smooth drive's tests).

    from rattlefit.diagnosis.evidence import candidate_static
    from rattlefit.diagnosis.verdict import Evidence, decide
    from validation.second_rig import validation_set

    drawn = validation_set.draw(next(c for c in validation_set.plan() if c.kinds == ("ripple",)))
    at = 14.0
    cogging = validation_set.at_drive_frequency(drawn, at)
    (with_it,), _ = validation_set.simulate_cases([cogging], duration=1.5, burn_in=0.5)
    found = findings([with_it], FAMILY)
    (ripple,) = [f for f in found if f.significant]
    assert ripple.effect == "drive_ripple" and ripple.test.detail["order"] == 24
    stated = validation_set.truth_of(cogging)["effects"][0]["acceleration_order24_rad_s2"]
    assert stated / 1.5 < ripple.test.amplitude < 1.5 * stated
    assert decide([], Evidence(tuple(found))).label == "drive_ripple"
    assert candidate_static(found) == {"drive_ripple": {"order": 24}}
