"""Fixtures for the BaffleDesigner logic tests on real MRML classes (PyPI slicer-core):
a headless scene, the p2 patient inputs loaded through Slicer's own storage nodes, and
the built-in phantom. Patient data: $BAFFLE_DATA_DIR, else ../shared/data beside the
repository; tests that need it skip with a note when it is absent
(and fail under CI=true)."""

import os
import sys
from pathlib import Path

import numpy as np
import pytest

MODULE_DIR = Path(__file__).resolve().parents[2]  # slicer_module/BaffleDesigner
REPO = MODULE_DIR.parents[1]
sys.path.insert(0, str(MODULE_DIR))

slicer = pytest.importorskip("slicer", reason="slicer-core is not installed (pip install slicer-core)")
if not hasattr(slicer, "vtkMRMLScene"):
    pytest.skip("`slicer` is not slicer-core's MRML package", allow_module_level=True)

import vtk  # noqa: E402  (slicer-core's pinned vtk)
from vtkmodules.util import numpy_support  # noqa: E402

from BaffleDesignerLib import logic as bdlogic  # noqa: E402


def data_dir() -> Path:
    return Path(os.environ.get("BAFFLE_DATA_DIR") or REPO.parent / "shared" / "data")


def missing_data(folder: Path) -> None:
    """Skip a real-data test, with a note; under CI=true fail it instead, so a broken
    path cannot turn the real-data checks into silent passes."""
    if os.environ.get("CI", "").lower() in ("true", "1"):
        pytest.fail(f"patient data not found at {folder} (CI=true: the real-data checks must run; set BAFFLE_DATA_DIR)")
    pytest.skip(f"patient data not found at {folder} (set BAFFLE_DATA_DIR)")


def p2_inputs():
    folder = data_dir() / "p2" / "design_input"
    surface, points = folder / "capped_ventricle.vtp", folder / "suture_points.mrk.json"
    if not (surface.exists() and points.exists()):
        missing_data(folder)
    return surface, points


@pytest.fixture(scope="session")
def executable():
    """The built `baffle` command line program (BAFFLE_EXECUTABLE, PATH or target/release)."""
    from BaffleDesignerLib import environment

    found = environment.find_baffle_executable()
    if not found:
        pytest.skip("baffle executable not found: cargo build --release -p baffle-cli, or set BAFFLE_EXECUTABLE")
    return found


def has_subcommand(executable, name):
    from BaffleDesignerLib import process

    return process.subcommand_availability(executable, name)[0]


def column(table_node, name):
    """A table node's column: a list of str for string columns, else a numpy array."""
    array = table_node.GetTable().GetColumnByName(name)
    assert array is not None, f"table has no column {name!r}"
    if isinstance(array, vtk.vtkStringArray):
        return [array.GetValue(i) for i in range(array.GetNumberOfValues())]
    return numpy_support.vtk_to_numpy(array).copy()


@pytest.fixture
def scene():
    s = slicer.vtkMRMLScene()
    yield s
    s.Clear(1)


def load_model(scene, path, name="ventricle"):
    """As Slicer loads a model file: vtkMRMLModelStorageNode, LPS on disk -> RAS node."""
    node = scene.AddNewNodeByClass("vtkMRMLModelNode", name)
    storage = scene.AddNewNodeByClass("vtkMRMLModelStorageNode")
    storage.SetFileName(str(path))
    node.SetAndObserveStorageNodeID(storage.GetID())
    assert storage.ReadData(node) == 1, f"could not read {path}"
    return node


def load_closed_curve(scene, path, name="BC"):
    """As BafflePlanner's curve is loaded: vtkMRMLMarkupsJsonStorageNode -> RAS world points."""
    curve = scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", name)
    storage = slicer.vtkMRMLMarkupsJsonStorageNode()
    scene.AddNode(storage)
    storage.SetFileName(str(path))
    curve.SetAndObserveStorageNodeID(storage.GetID())
    assert storage.ReadData(curve) == 1, f"could not read {path}"
    return curve


def translation_node(scene, shift):
    """A linear transform node that moves its children by `shift` (mm, RAS)."""
    transform = scene.AddNewNodeByClass("vtkMRMLLinearTransformNode")
    matrix = vtk.vtkMatrix4x4()
    for axis in range(3):
        matrix.SetElement(axis, 3, float(shift[axis]))
    transform.SetMatrixTransformToParent(matrix)
    return transform


def curve_from_points(scene, points, name):
    curve = scene.AddNewNodeByClass("vtkMRMLMarkupsClosedCurveNode", name)
    for p in np.asarray(points, dtype=float):
        curve.AddControlPointWorld(float(p[0]), float(p[1]), float(p[2]))
    return curve


@pytest.fixture
def p2_scene(scene):
    """(scene, logic, model node, curve node) of patient p2 with BSA 0.37 m2."""
    surface_path, points_path = p2_inputs()
    model = load_model(scene, surface_path)
    curve = load_closed_curve(scene, points_path)
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.setSurfaceNode(curve, model)
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=0.37, z_score=0.0))
    return scene, logic, model, curve


@pytest.fixture
def phantom_scene(scene):
    """(scene, logic, model node, curve node) of the library's synthetic phantom."""
    return phantom_candidate(scene)


def phantom_candidate(scene, suture_half_angle_deg=None):
    """(scene, logic, model node, curve node) of the library's synthetic phantom in `scene`
    (its suture loop wrapped `suture_half_angle_deg` round the tunnel; None: the default)."""
    import baffle
    from baffle import vtk_adapters

    mesh, points, bsa_m2 = baffle.phantom(suture_half_angle_deg)
    model = scene.AddNewNodeByClass("vtkMRMLModelNode", "phantom")
    model.SetAndObservePolyData(vtk_adapters.mesh_to_polydata(mesh))
    curve = curve_from_points(scene, points, "phantom BC")
    logic = bdlogic.BaffleDesignerLogic(scene)
    logic.setSurfaceNode(curve, model)
    logic.setParameters(curve, bdlogic.DesignParameters(target_mode="bsa", bsa_m2=bsa_m2))
    return scene, logic, model, curve
