"""The Python API without VTK: errors become exceptions with the library's
message, cancellation from the progress callback, markups reading."""

import ctypes
import json

import numpy as np
import pytest

import baffle
from baffle import _lib


@pytest.fixture(scope="module")
def phantom():
    return baffle.phantom()


def test_versions():
    assert baffle.version() == baffle.__version__
    assert _lib.lib.baffle_abi_version() == baffle.ABI_VERSION


def test_null_pointer_is_an_error_code():
    count = ctypes.c_size_t()
    assert _lib.lib.baffle_mesh_point_count(None, ctypes.byref(count)) == 1
    assert _lib.lib.baffle_last_error() == b"mesh is NULL"


def test_open_mesh_is_rejected(phantom):
    surface, points, bsa_m2 = phantom
    with pytest.raises(baffle.BaffleError, match="not a closed manifold") as error:
        baffle.design(surface.points, surface.triangles[1:], surface.labels[1:], points, bsa_m2=bsa_m2)
    assert error.value.status == 5


def test_unreachable_target_reports_the_largest_feasible_area():
    # A suture loop wrapped 100 degrees round the tunnel leaves too little baffle near the caps.
    surface, points, _ = baffle.phantom(suture_half_angle_deg=100.0)
    with pytest.raises(baffle.BaffleError, match="admits a tunnel of at most") as error:
        baffle.design(surface.points, surface.triangles, surface.labels, points, target_area_mm2=300.0)
    assert error.value.status == 6
    largest = error.value.max_feasible_area_mm2
    assert 100.0 < largest < 300.0
    assert f"at most {largest:.1f} mm2" in str(error.value)
    # The reported area designs, and every constrained or checked section holds it.
    result = baffle.design(surface.points, surface.triangles, surface.labels, points, target_area_mm2=largest)
    assert all(s["final_area_mm2"] >= largest for s in result.checked_sections)


def test_too_few_points_are_rejected(phantom):
    surface, points, bsa_m2 = phantom
    with pytest.raises(baffle.BaffleError, match="at least 4"):
        baffle.design(surface.points, surface.triangles, surface.labels, points[:2], bsa_m2=bsa_m2)


def test_bad_arrays_are_rejected(phantom):
    surface, points, bsa_m2 = phantom
    nan_points = surface.points.copy()
    nan_points[3, 1] = np.nan
    with pytest.raises(baffle.BaffleError, match="point 3 has a non-finite coordinate"):
        baffle.design(nan_points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2)
    far = surface.triangles.copy()
    far[7, 2] = len(surface.points)
    with pytest.raises(baffle.BaffleError, match="triangle 7 refers to point"):
        baffle.design(surface.points, far, surface.labels, points, bsa_m2=bsa_m2)
    with pytest.raises(ValueError, match="exactly one target"):
        baffle.design(surface.points, surface.triangles, surface.labels, points)
    with pytest.raises(TypeError, match="unknown design option"):
        baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, seam_sample=3)


def test_options_are_range_checked_by_the_library(phantom):
    # The same DesignOptions::validate as the CLI: a NaN distance must not switch the check off.
    surface, points, bsa_m2 = phantom
    with pytest.raises(baffle.BaffleError, match=r"max_point_distance_mm = NaN is outside \[0, 100\]"):
        baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, max_point_distance_mm=float("nan"))
    with pytest.raises(baffle.BaffleError, match="remesh_edge_mm = 0.000001 is outside"):
        baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, remesh_edge_mm=1e-6)


def test_progress_false_cancels(phantom):
    surface, points, bsa_m2 = phantom
    seen = []

    def stop_at_sections(fraction, stage):
        seen.append((fraction, stage))
        return stage != "sections"

    with pytest.raises(baffle.Cancelled, match="cancelled during sections"):
        baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, progress=stop_at_sections)
    assert seen[0][1] == "validate" and seen[-1][1] == "sections"
    assert [f for f, _ in seen] == sorted(f for f, _ in seen)


def test_callback_exception_reaches_the_caller(phantom):
    surface, points, bsa_m2 = phantom

    def broken(fraction, stage):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, progress=broken)


def test_phantom_design_with_progress(phantom):
    surface, points, bsa_m2 = phantom
    fractions = []
    result = baffle.design(
        surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2,
        progress=lambda fraction, stage: fractions.append(fraction),
    )
    assert fractions[0] == 0.0 and fractions[-1] == 1.0
    assert all(s["final_area_mm2"] >= result.target_area_mm2 for s in result.checked_sections)
    assert result.domain.triangles.shape == (result.report["domain_triangles"], 3)
    assert "peak_flow_ml_s" in result.report["hemodynamics_estimate"]["absent_because"]


def test_a_peak_flow_adds_the_reduced_order_estimate(phantom):
    surface, points, bsa_m2 = phantom
    result = baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, peak_flow_ml_s=70.0)
    estimate = result.report["hemodynamics_estimate"]
    assert estimate["peak_flow_ml_s"] == 70.0
    assert estimate["v_max_estimate_m_s"] > 0 and np.isfinite(estimate["dp_estimate_mmhg"])
    assert "mmHg below" in estimate["dp_uncertainty"]
    with pytest.raises(baffle.BaffleError, match="peak_flow_ml_s"):
        baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2, peak_flow_ml_s=-1.0)


def test_the_peak_flow_for_the_estimate_is_the_papers():
    # patients.json's p2: BSA 0.37 m2 at CI 3.48 -> 70.0 ml/s (Table 4).
    assert baffle.peak_flow_ml_s(0.37, 3.48) == pytest.approx(3.26 * 0.37 * 3.48 * 1000 / 60, rel=1e-12)
    assert baffle.peak_flow_ml_s(0.37) == pytest.approx(69.96, abs=0.01)
    with pytest.raises(baffle.BaffleError, match="BSA"):
        baffle.peak_flow_ml_s(0.0)
    with pytest.raises(baffle.BaffleError, match="cardiac index"):
        baffle.peak_flow_ml_s(0.37, float("nan"))


def write_markups(path, frame, points):
    document = {
        "markups": [
            {
                "type": "ClosedCurve",
                "coordinateSystem": frame,
                "controlPoints": [{"position": list(p), "positionStatus": "defined"} for p in points]
                + [{"position": [0, 0, 0], "positionStatus": "undefined"}],
            }
        ]
    }
    path.write_text(json.dumps(document))


def test_markups_ras_points_are_converted_like_the_library(tmp_path):
    ras = np.array([[1.0, 2.0, 3.0], [-4.0, 5.5, 6.0]])
    path = tmp_path / "points.mrk.json"
    write_markups(path, "RAS", ras)
    lps = baffle.read_markups(path, frame="LPS")
    np.testing.assert_array_equal(lps, ras * [-1, -1, 1])
    np.testing.assert_array_equal(baffle.read_markups(path, frame="RAS"), ras)
    np.testing.assert_array_equal(lps, baffle.read_points(path, "LPS"))
