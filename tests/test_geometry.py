import math

import pytest

from rattlefit.errors import ParameterError
from rattlefit.physics.geometry import table2_pair


def test_table2_pitch_diameters_give_design_centre_distance():
    for pair in ("I", "II"):
        g = table2_pair(pair)
        assert g.reference_center_distance == pytest.approx(65.0e-3, abs=0.02e-3)
        # d = z mn / cos β with mn = 2 mm
        assert 2 * g.pitch_radius_driving == pytest.approx(
            g.teeth_driving * g.normal_module / math.cos(g.helix_angle), rel=1e-12
        )


def test_mesh_mode_near_paper_estimate():
    # Section 4: "the natural frequency has been estimated in about 3400 Hz".
    g = table2_pair("II", center_distance_mm=65.0)
    assert 2700 < g.mesh_frequency_hz < 4100


def test_backlash_matches_paper_values():
    # Section 5: 0.092 rad (pair I at 66.0 mm) and 0.038 rad (pair II at 65.6 mm).
    assert table2_pair("I", center_distance_mm=66.0).angular_backlash == pytest.approx(
        0.092, rel=0.03
    )
    assert table2_pair("II", center_distance_mm=65.6).angular_backlash == pytest.approx(
        0.038, rel=0.03
    )


def test_backlash_matches_recordings(shared_recordings):
    import h5py

    for path in sorted(shared_recordings.glob("*.h5")):
        with h5py.File(path) as f:
            a = f["gear_pair"].attrs
            pair = "I" if int(a["teeth_driving"]) == 11 else "II"
            g = table2_pair(pair, center_distance_mm=float(a["center_distance_mm"]))
            # recorded backlashes carry a measurement error of ~2e-4 rad
            assert g.angular_backlash == pytest.approx(float(a["angular_backlash_rad"]), abs=2e-3)


def test_contact_ratios_by_hand_pair2():
    # Standard addendum, reference centre distance:
    # εα = (√(ra1²−rb1²) + √(ra2²−rb2²) − a sin αt) / pbt
    g = table2_pair("II", center_distance_mm=65.01)
    at = math.atan(math.tan(math.radians(20)) / math.cos(g.helix_angle))
    r1, r2 = g.pitch_radius_driving, g.pitch_radius_driven
    rb1, rb2 = r1 * math.cos(at), r2 * math.cos(at)
    path = (
        math.sqrt((r1 + 2e-3) ** 2 - rb1**2)
        + math.sqrt((r2 + 2e-3) ** 2 - rb2**2)
        - (r1 + r2) * math.sin(at)
    )
    pbt = math.pi * 2e-3 * math.cos(at) / math.cos(g.helix_angle)
    assert g.transverse_contact_ratio == pytest.approx(path / pbt, rel=2e-3)
    assert g.overlap_contact_ratio == pytest.approx(
        12.8e-3 * math.sin(g.helix_angle) / (math.pi * 2e-3)
    )


def test_curvature_radius_by_hand():
    g = table2_pair("II", center_distance_mm=65.6)
    s = math.sin(g.operating_pressure_angle)
    rho1 = 65.6e-3 * 19 / 60 * s
    rho2 = 65.6e-3 * 41 / 60 * s
    assert g.curvature_radius == pytest.approx(rho1 * rho2 / (rho1 + rho2), rel=1e-9)


def test_unphysical_geometry_refused():
    g = table2_pair("II")
    with pytest.raises(ParameterError, match="driven_inertia"):
        g.replace(driven_inertia=-1.0)
    with pytest.raises(ParameterError, match="centre distance"):
        g.replace(center_distance=0.05)
    with pytest.raises(ParameterError, match="unknown gear pair"):
        table2_pair("III")
