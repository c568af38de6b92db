"""Designs on the patient inputs and the phantom, checked with VTK's own filters
(the PyPI vtk wheel): watertight domain, positive volume, every constrained section
re-cut with vtkCutter reaches the target, labels, and a .vtp round trip."""

import numpy as np
import pytest

import baffle

vtk = pytest.importorskip("vtkmodules.vtkCommonCore")
from vtkmodules.vtkCommonCore import vtkIdList  # noqa: E402
from vtkmodules.vtkFiltersCore import vtkFeatureEdges, vtkMassProperties  # noqa: E402
from vtkmodules.vtkIOXML import vtkXMLPolyDataWriter  # noqa: E402

from conftest import plane_cut, read_vtp  # noqa: E402
from baffle.vtk_adapters import centerline_polydata, design_polydata, mesh_to_polydata, polydata_to_mesh  # noqa: E402

WALL, BAFFLE, VSD_CAP, AORTIC_CAP = 2, 10, 11, 16
# VTK re-cuts the same triangles with the same plane; only summation order differs.
RELATIVE_TOLERANCE = 1e-9


def write_vtp(polydata, path):
    writer = vtkXMLPolyDataWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(polydata)
    assert writer.Write() == 1


def open_or_nonmanifold_edges(polydata) -> int:
    edges = vtkFeatureEdges()
    edges.SetInputData(polydata)
    edges.BoundaryEdgesOn()
    edges.NonManifoldEdgesOn()
    edges.FeatureEdgesOff()
    edges.ManifoldEdgesOff()
    edges.Update()
    return edges.GetOutput().GetNumberOfCells()


def section_loops(polydata, origin, normal):
    """(centroid, area mm2) of each closed loop of the plane section."""
    lines = plane_cut(polydata, origin, normal)
    loops, ids = [], vtkIdList()
    lines.GetLines().InitTraversal()
    while lines.GetLines().GetNextCell(ids):
        index = [ids.GetId(k) for k in range(ids.GetNumberOfIds())]
        if len(index) > 1 and index[0] == index[-1]:
            index = index[:-1]  # closed loops repeat their first point
        if len(index) < 3:
            continue
        p = np.array([lines.GetPoint(i) for i in index])
        twice_area = np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)
        loops.append((p.mean(axis=0), 0.5 * abs(float(np.dot(twice_area, normal)))))
    return loops


def nearest_section_area_mm2(polydata, origin, normal) -> float:
    loops = section_loops(polydata, origin, normal)
    assert loops, f"no closed section loop at {origin}"
    return min(loops, key=lambda loop: np.linalg.norm(loop[0] - np.asarray(origin)))[1]


def check_design(result: baffle.DesignResult, tmp_path):
    report = result.report
    target_mm2 = report["target_area_mm2"]
    domain = mesh_to_polydata(result.domain)
    assert open_or_nonmanifold_edges(domain) == 0

    mass = vtkMassProperties()
    mass.SetInputData(domain)
    mass.Update()
    assert mass.GetSurfaceArea() > 0 and mass.GetVolume() > 0
    assert mass.GetVolume() == pytest.approx(report["domain_volume_mm3"], rel=1e-6)

    labels, counts = np.unique(result.domain.labels, return_counts=True)
    assert labels.tolist() == [WALL, BAFFLE, VSD_CAP, AORTIC_CAP]
    assert counts[1] == len(result.baffle.triangles) == report["baffle_triangles"]
    assert len(result.seam_points_mm) == report["seam_vertices"]

    constrained = result.constrained_sections
    assert len(constrained) == report["constrained_sections"] > 0
    checked = result.checked_sections
    assert len(checked) == report["constrained_sections"] + report["checked_only_sections"]
    for section in checked:
        area = nearest_section_area_mm2(domain, section["origin_mm"], section["normal"])
        assert area >= target_mm2 * (1 - RELATIVE_TOLERANCE), f"s = {section['s_mm']} mm: {area} < {target_mm2}"
        assert area == pytest.approx(section["final_area_mm2"], rel=RELATIVE_TOLERANCE)
    # The sections lie at the centerline samples, in order.
    s_mm = np.array([s["s_mm"] for s in report["sections"]])
    np.testing.assert_array_equal(s_mm, result.centerline_s_mm)
    np.testing.assert_allclose(np.linalg.norm(result.centerline_tangents, axis=1), 1.0, rtol=1e-12)

    centerline = centerline_polydata(result)
    assert centerline.GetNumberOfPoints() == len(result.centerline_s_mm) and centerline.GetNumberOfLines() == 1
    assert centerline.GetPointData().GetArray("s_mm").GetValue(0) == result.centerline_s_mm[0]

    path = tmp_path / "domain.vtp"
    write_vtp(domain, path)
    back = polydata_to_mesh(read_vtp(path))
    np.testing.assert_array_equal(back.points, result.domain.points)
    np.testing.assert_array_equal(back.triangles, result.domain.triangles)
    np.testing.assert_array_equal(back.labels, result.domain.labels)


@pytest.mark.parametrize("patient", ["p2", "p3"])
def test_patient_design_meets_the_target_by_vtk(patient, patient_input, tmp_path):
    folder, bsa_m2 = patient_input(patient)
    surface = read_vtp(folder / "capped_ventricle.vtp")
    points = baffle.read_markups(folder / "suture_points.mrk.json", frame="LPS")  # the .vtp files are LPS
    result = design_polydata(surface, points, bsa_m2=bsa_m2)
    check_design(result, tmp_path)


def test_phantom_design_through_vtp(tmp_path):
    surface, points, bsa_m2 = baffle.phantom()
    path = tmp_path / "phantom.vtp"
    write_vtp(mesh_to_polydata(surface), path)
    result = design_polydata(read_vtp(path), points, bsa_m2=bsa_m2)
    check_design(result, tmp_path)


def test_quads_are_refused():
    mesh = baffle.Mesh(np.eye(3), np.array([[0, 1, 2]]), np.array([WALL]))
    polydata = mesh_to_polydata(mesh)
    from vtkmodules.vtkCommonDataModel import vtkCellArray

    polys = vtkCellArray()
    polys.InsertNextCell(4)
    for i in (0, 1, 2, 0):
        polys.InsertCellPoint(i)
    polydata.SetPolys(polys)
    with pytest.raises(ValueError, match="only triangles"):
        polydata_to_mesh(polydata)
