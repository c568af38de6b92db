"""Readers of inputs and results: report.json's three-state verdict, a simulate result
(.vtu in mm, m/s, mmHg), suture points through the library's reader, and a labelled
surface read back into a design."""

import json

import numpy as np
import pytest

import baffle


def plan_report(verdict="inconclusive", reason="the steady solve did not reach its residual target"):
    return {
        "status": "completed",
        "verdict": {
            "verdict": verdict, "reason": reason, "passes": verdict == "passes", "threshold_mmhg": 10.0,
            "dp_peak_mmhg": 1.72, "converged": verdict != "inconclusive", "warnings": ["poor mesh"],
        },
        "quantities": {"dp_peak_mmhg": 1.72, "tetrahedra": 37031},
        "centerline": {"s_mm": [0.0, 0.5, 1.0], "pressure_rel_aortic_plane_mmhg": [None, 1.2, 0.0], "speed_m_s": [1.0, 1.5, None]},
    }


def test_a_report_gives_its_three_state_verdict_and_arrays(tmp_path):
    (tmp_path / "report.json").write_text(json.dumps(plan_report()))
    report = baffle.read_report(tmp_path)  # the plan's folder
    assert report.verdict == "inconclusive" and not report.passes
    assert "residual target" in report.reason and report.warnings == ["poor mesh"]
    assert report.dp_peak_mmhg == 1.72 and report.quantities["tetrahedra"] == 37031
    pressure = report.centerline["pressure_rel_aortic_plane_mmhg"]
    assert np.isnan(pressure[0]) and pressure[1] == 1.2
    (tmp_path / "report.json").write_text(json.dumps(plan_report("passes", None)))
    assert baffle.read_report(tmp_path / "report.json").passes


def test_a_failed_or_unknown_report_is_refused_with_the_reason(tmp_path):
    path = tmp_path / "report.json"
    path.write_text(json.dumps({"status": "failed", "failed_stage": "mesh-nominal", "error": "gmsh not found"}))
    with pytest.raises(ValueError, match="stage mesh-nominal failed: gmsh not found"):
        baffle.read_report(path)
    old = plan_report()
    old["verdict"] = {"passes": True, "dp_peak_mmhg": 1.0, "threshold_mmhg": 10.0}
    path.write_text(json.dumps(old))
    with pytest.raises(ValueError, match="no three-state verdict"):
        baffle.read_report(path)
    with pytest.raises(ValueError, match="nothing.json"):
        baffle.read_report(tmp_path / "nothing.json")


# One tetrahedron as `baffle simulate` writes a result (baffle_cfd::vtu::write_solution_vtu).
RESULT_VTU = """<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">
<UnstructuredGrid>
<Piece NumberOfPoints="4" NumberOfCells="1">
<PointData Vectors="velocity_m_s" Scalars="speed_m_s">
<DataArray type="Float64" Name="velocity_m_s" NumberOfComponents="3" format="ascii">
0e0 0e0 1e0
3e-1 4e-1 0e0
0e0 0e0 0e0
1e0 0e0 0e0
</DataArray>
<DataArray type="Float64" Name="speed_m_s" format="ascii">
1e0
5e-1
0e0
1e0
</DataArray>
<DataArray type="Float64" Name="pressure_mmhg" format="ascii">
2.5e0
2e0
1e0
0e0
</DataArray>
</PointData>
<Points><DataArray type="Float64" NumberOfComponents="3" format="ascii">
0e0 0e0 0e0
1e1 0e0 0e0
0e0 1e1 0e0
0e0 0e0 1e1
</DataArray></Points>
<Cells>
<DataArray type="Int64" Name="connectivity" format="ascii">
0 1 2 3
</DataArray>
<DataArray type="Int64" Name="offsets" format="ascii">
4
</DataArray>
<DataArray type="UInt8" Name="types" format="ascii">
10
</DataArray>
</Cells>
</Piece>
</UnstructuredGrid>
</VTKFile>
"""


def test_a_simulate_result_reads_in_mm_m_s_and_mmhg(tmp_path):
    pytest.importorskip("vtkmodules.vtkIOXML")
    path = tmp_path / "peak.vtu"
    path.write_text(RESULT_VTU)
    fields = baffle.read_fields(path)
    assert fields["points_mm"].shape == (4, 3) and fields["points_mm"].max() == 10.0
    assert fields["tetrahedra"].tolist() == [[0, 1, 2, 3]]
    np.testing.assert_allclose(np.linalg.norm(fields["velocity_m_s"], axis=1), fields["speed_m_s"])
    assert fields["pressure_mmhg"].tolist() == [2.5, 2.0, 1.0, 0.0]
    path.write_text(RESULT_VTU.replace("pressure_mmhg", "pressure"))
    with pytest.raises(ValueError, match="missing point arrays pressure_mmhg"):
        baffle.read_fields(path)


def test_points_are_read_by_the_librarys_reader_in_either_frame(tmp_path):
    csv = tmp_path / "points.csv"
    csv.write_text("1,2,3\n4,5,6\n7,8,9.5\n")
    lps = baffle.read_points(csv)
    assert lps.tolist() == [[1, 2, 3], [4, 5, 6], [7, 8, 9.5]]
    np.testing.assert_array_equal(baffle.read_points(csv, "ras"), lps * [-1, -1, 1])
    with pytest.raises(baffle.BaffleError, match="missing.fcsv"):
        baffle.read_points(tmp_path / "missing.fcsv")
    with pytest.raises(ValueError, match="LPS or RAS"):
        baffle.read_points(csv, "XYZ")


def test_a_surface_written_and_read_back_designs_as_the_original(tmp_path):
    pytest.importorskip("vtkmodules.vtkIOXML")
    from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter

    from baffle.vtk_adapters import mesh_to_polydata

    surface, points, bsa_m2 = baffle.phantom()
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(tmp_path / "capped.vtp"))
    writer.SetInputData(mesh_to_polydata(surface))
    assert writer.Write() == 1
    back = baffle.read_surface(tmp_path / "capped.vtp")
    np.testing.assert_array_equal(back.triangles, surface.triangles)
    np.testing.assert_array_equal(back.labels, surface.labels)
    np.testing.assert_allclose(back.points, surface.points)
    a = baffle.design(back.points, back.triangles, back.labels, points, bsa_m2=bsa_m2)
    b = baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2)
    assert a.report["baffle_area_mm2"] == pytest.approx(b.report["baffle_area_mm2"], rel=1e-12)
    stl = tmp_path / "capped.stl"
    stl.write_text("solid x\nendsolid x\n")
    with pytest.raises(ValueError, match="labelled surface"):
        baffle.read_surface(stl)
