"""baffle.template() over the C ABI: the flattened baffle keeps the seam length, the page
is a 1:1 A4 PDF/SVG with the patient label, and bad input raises with the library's
message."""

import re
import struct

import numpy as np
import pytest

import baffle


@pytest.fixture(scope="module")
def phantom_design():
    surface, points, bsa_m2 = baffle.phantom()
    return baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=bsa_m2), points


def flat_area_mm2(mesh: baffle.Mesh) -> float:
    p = mesh.points[mesh.triangles]
    u, v = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    return float(0.5 * np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]).sum())


def seam_length_mm(result: baffle.DesignResult) -> float:
    seam = result.seam_points_mm
    return float(np.linalg.norm(np.roll(seam, -1, axis=0) - seam, axis=1).sum())


def check_template(t: baffle.Template, result: baffle.DesignResult, points, tmp_path):
    f = t.report["flattening"]
    # The perimeter is the 3D seam's length (the bar: within 1 %).
    assert f["perimeter_error"] <= 0.01
    assert f["seam_length_3d_mm"] == pytest.approx(seam_length_mm(result), rel=1e-9)
    assert f["area_3d_mm2"] == pytest.approx(result.report["baffle_area_mm2"], rel=1e-9)
    # The flat mesh is the baffle's triangles in the plane, and its area the report's.
    assert len(t.flat.triangles) == len(result.baffle.triangles) == len(t.area_ratio)
    assert np.all(t.flat.points[:, 2] == 0.0)
    assert flat_area_mm2(t.flat) == pytest.approx(f["area_flat_mm2"], rel=1e-9)
    ratio = t.area_ratio
    assert np.all(ratio > 0)
    assert np.median(np.abs(ratio - 1)) == pytest.approx(f["area_distortion_median"], rel=1e-9)
    assert len(t.report["suture_point_to_seam_mm"]) == len(points)

    pdf = t.save(tmp_path / "template.pdf").read_bytes()
    assert pdf.startswith(b"%PDF") and pdf.rstrip().endswith(b"%%EOF")
    # A4 portrait in points (72 per inch): 595.28 x 841.89.
    box = re.search(rb"/MediaBox\s*\[\s*0\s+0\s+([\d.]+)\s+([\d.]+)\s*\]", pdf)
    assert box and float(box[1]) == pytest.approx(210 * 72 / 25.4, abs=0.01) and float(box[2]) == pytest.approx(297 * 72 / 25.4, abs=0.01)
    svg = t.save(tmp_path / "template.svg").read_text()
    assert 'width="210mm"' in svg and 'height="297mm"' in svg and 'viewBox="0 0 210 297"' in svg
    png = t.save(tmp_path / "template.png").read_bytes()
    # IHDR: A4 at 300 dpi is 2480 x 3508 px; pHYs: 11811 px per metre, unit metre.
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    assert struct.unpack(">II", png[16:24]) == (2480, 3508)
    phys = png.index(b"pHYs")
    assert struct.unpack(">IIB", png[phys + 4 : phys + 13]) == (11811, 11811, 1)


def test_phantom_template(phantom_design, tmp_path):
    result, points = phantom_design
    names = [f"S{k + 1}" for k in range(len(points))]
    t = baffle.template(result.domain, points, point_labels=names, patient_label="phantom", date="2026-12-02")
    check_template(t, result, points, tmp_path)
    svg = t.svg.decode()
    assert "phantom" in svg and "2026-12-02" in svg and ">S1<" in svg and f">S{len(points)}<" in svg


def test_arap_keeps_the_seam_length_and_lowers_the_largest_area_change(phantom_design, tmp_path):
    result, points = phantom_design
    lscm = baffle.template(result.domain, points)
    arap = baffle.template(result.domain, points, method="arap")
    check_template(arap, result, points, tmp_path)
    assert arap.report["flattening"]["arap_iterations"] > 0
    assert arap.report["flattening"]["area_distortion_max"] <= lscm.report["flattening"]["area_distortion_max"]


def test_patient_template(patient_input, tmp_path):
    vtk_io = pytest.importorskip("vtkmodules.vtkIOXML")  # noqa: F841 - read_surface needs vtk
    folder, bsa_m2 = patient_input("p2")
    surface = baffle.read_surface(folder / "capped_ventricle.vtp")
    markups = baffle.read_markups(folder / "suture_points.mrk.json", frame="LPS")
    result = baffle.design(surface.points, surface.triangles, surface.labels, markups, bsa_m2=bsa_m2)
    t = baffle.template(result.domain, markups, patient_label="p2")
    check_template(t, result, markups, tmp_path)


def test_bad_template_input_is_named(phantom_design):
    result, points = phantom_design
    wall_only = baffle.Mesh(result.domain.points, result.domain.triangles, np.where(result.domain.labels == 10, 2, result.domain.labels))
    with pytest.raises(baffle.BaffleError, match="no baffle triangles") as error:
        baffle.template(wall_only, points)
    assert error.value.status == 5
    with pytest.raises(ValueError, match="method"):
        baffle.template(result.domain, points, method="tutte")
    with pytest.raises(ValueError, match="2 point labels for"):
        baffle.template(result.domain, points, point_labels=["a", "b"])
    with pytest.raises(ValueError, match=r"\.pdf, \.svg or \.png"):
        baffle.template(result.domain, points).save("template.jpg")
    with pytest.raises(baffle.BaffleError, match="dpi = 5"):
        baffle.template(result.domain, points, dpi=5)


def test_other_face_labels(phantom_design):
    result, points = phantom_design
    relabelled = baffle.Mesh(result.domain.points, result.domain.triangles, np.where(result.domain.labels == 10, 20, result.domain.labels))
    t = baffle.template(relabelled, points, baffle_label=20)
    assert len(t.flat.triangles) == len(result.baffle.triangles)
    with pytest.raises(baffle.BaffleError, match="ModelFaceID 10"):
        baffle.template(relabelled, points)
