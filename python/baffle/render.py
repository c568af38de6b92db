"""Pictures of a `baffle plan` folder, rendered offscreen with VTK (no X server: EGL or
OSMesa), for its report.html and the Slicer module:

    python3 -m baffle.render out/plan [--frame lps|ras]

writes out/plan/pictures/*.png and pictures.json (each picture's file, title and caption,
and notes on what could not be drawn). The views are named in the patient's terms from
the input's frame (LPS unless --frame ras), with orientation letters at the edges and a
scale bar: the CFD domain in context (LV, RV and aorta translucent, the baffle
highlighted), the aortic cap face-on, the peak speed on a cut plane along the
flow-domain centerline (in context and face-on) and that centerline coloured by the
pressure relative to the aortic plane.

Needs only vtk and numpy, not the baffle library: `baffle plan` runs this file as a
script (`python3 -c`), so the report gets its pictures without the package installed.
Exit status 0 when every picture was written, 2 when the folder lacks a file, 3 when vtk
is not importable, 4 when the offscreen renderer gave a blank image.
"""

import argparse
import json
import math
import os
import sys
from pathlib import Path

WIDTH_PX, HEIGHT_PX = 800, 600
# The 3D scene's share of the width; the legend and the colour bar take the rest.
SCENE_WIDTH = 0.72

# ModelFaceID of the plan's surfaces (the design's defaults; --*-label override them).
DEFAULT_LABELS = {"wall": 2, "baffle": 10, "vsd": 11, "aortic": 16, "inflow": 20, "outflow": 21}

# Text sizes (px of the 800 x 600 picture, which the report shows at 480 px wide).
TITLE_PX, LETTER_PX, LABEL_PX = 25, 30, 22
# One colour per part in every picture (RGB 0-1).
COLORS = {
    "wall": (0.80, 0.55, 0.51),
    "baffle": (0.10, 0.42, 0.92),
    "vsd": (0.30, 0.72, 0.30),
    "aortic": (0.92, 0.76, 0.18),
    "inflow": (0.60, 0.35, 0.80),
    "outflow": (0.20, 0.75, 0.75),
    "LV": (0.86, 0.30, 0.30),
    "RV": (0.55, 0.45, 0.80),
    "aorta": (0.93, 0.55, 0.20),
    "centerline": (0.10, 0.10, 0.10),
    "domain": (0.55, 0.58, 0.62),
}
# Segment surfaces the prepare stage reads, as `baffle_prepare::input` looks them up.
STRUCTURE_STEMS = {"LV": ("LV", "lv"), "RV": ("RV", "rv"), "aorta": ("aorta", "Aorta", "AO", "Ao")}
EXTENSIONS = ("vtp", "vtk", "stl")


class RenderError(Exception):
    """A picture could not be made; `status` is the script's exit status."""

    def __init__(self, message, status=2):
        super().__init__(message)
        self.status = status


def _import_vtk():
    # Without a display VTK's default X window fails; EGL renders offscreen (VTK >= 9.4 wheels).
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    try:
        import numpy  # noqa: F401
        import vtkmodules.vtkRenderingOpenGL2  # noqa: F401  (registers the OpenGL render window)
        import vtkmodules.vtkRenderingFreeType  # noqa: F401  (text)
        import vtkmodules.vtkInteractionStyle  # noqa: F401
    except ImportError as error:
        raise RenderError(f"the vtk and numpy modules are needed (pip install vtk numpy): {error}", status=3)


# ---------------------------------------------------------------- anatomical frame


def anatomical_views(ras):
    """(key, name, look, right, up) of the anterior, left lateral and inferior views in the
    file's frame: defined in LPS (x left, y posterior, z superior), negated x, y for RAS."""
    f = (lambda x, y, z: (-x, -y, z)) if ras else (lambda x, y, z: (x, y, z))
    return [
        ("anterior", "Anterior view", f(0, 1, 0), f(1, 0, 0), f(0, 0, 1)),
        ("left_lateral", "Left lateral view", f(-1, 0, 0), f(0, 1, 0), f(0, 0, 1)),
        ("inferior", "Inferior view", f(0, 0, 1), f(1, 0, 0), f(0, -1, 0)),
    ]


def orientation_letter(direction, ras):
    """The patient direction (R/L, A/P, S/I) closest to `direction` (file frame)."""
    x, y, z = direction
    if ras:
        x, y = -x, -y
    axis = max(range(3), key=lambda k: abs((x, y, z)[k]))
    value = (x, y, z)[axis]
    return ("L", "P", "S")[axis] if value > 0 else ("R", "A", "I")[axis]


def round_length_mm(target_mm):
    """The largest 1, 2 or 5 x 10^k mm not above `target_mm`."""
    magnitude = 10.0 ** math.floor(math.log10(target_mm))
    return max(m * magnitude for m in (1.0, 2.0, 5.0, 10.0) if m * magnitude <= target_mm * (1 + 1e-9))


# ---------------------------------------------------------------- reading


def read_surface(path):
    """A .vtp/.vtk/.stl surface as vtkPolyData."""
    from vtkmodules.vtkIOGeometry import vtkSTLReader
    from vtkmodules.vtkIOLegacy import vtkPolyDataReader
    from vtkmodules.vtkIOXML import vtkXMLPolyDataReader

    path = Path(path)
    if not path.is_file():
        raise RenderError(f"{path}: no such file")
    reader_class = {".vtp": vtkXMLPolyDataReader, ".vtk": vtkPolyDataReader, ".stl": vtkSTLReader}.get(path.suffix.lower())
    if reader_class is None:
        raise RenderError(f"{path}: not a .vtp, .vtk or .stl surface")
    data = read_with(reader_class, path)
    if data.GetNumberOfCells() == 0:
        raise RenderError(f"{path}: no cells")
    return data


def read_volume(path):
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader

    path = Path(path)
    if not path.is_file():
        raise RenderError(f"{path}: no such file")
    grid = read_with(vtkXMLUnstructuredGridReader, path)
    if grid.GetPointData().GetArray("speed_m_s") is None:
        raise RenderError(f"{path}: no point array speed_m_s")
    return grid


def read_with(reader_class, path):
    """What a new VTK file reader of `reader_class` reads from `path`."""
    reader = reader_class()
    reader.SetFileName(str(path))
    reader.Update()
    return reader.GetOutput()


def with_labels(surface, labels):
    """The cells of `surface` whose ModelFaceID is in `labels`, as vtkPolyData (None if none)."""
    import numpy as np
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkIdTypeArray
    from vtkmodules.vtkCommonDataModel import vtkSelection, vtkSelectionNode
    from vtkmodules.vtkFiltersExtraction import vtkExtractSelection
    from vtkmodules.vtkFiltersGeometry import vtkGeometryFilter

    ids = surface.GetCellData().GetArray("ModelFaceID")
    if ids is None:
        return None
    keep = np.nonzero(np.isin(vtk_to_numpy(ids), list(labels)))[0]
    if keep.size == 0:
        return None
    indices = vtkIdTypeArray()
    for k in keep:
        indices.InsertNextValue(int(k))
    node = vtkSelectionNode()
    node.SetFieldType(vtkSelectionNode.CELL)
    node.SetContentType(vtkSelectionNode.INDICES)
    node.SetSelectionList(indices)
    selection = vtkSelection()
    selection.AddNode(node)
    extract = vtkExtractSelection()
    extract.SetInputData(0, surface)
    extract.SetInputData(1, selection)
    geometry = vtkGeometryFilter()
    geometry.SetInputConnection(extract.GetOutputPort())
    geometry.Update()
    return geometry.GetOutput()


def find_structure(folder, stems):
    for stem in stems:
        for extension in EXTENSIONS:
            path = Path(folder) / f"{stem}.{extension}"
            if path.is_file():
                return path
    return None


def points_of(data):
    import numpy as np
    from vtkmodules.util.numpy_support import vtk_to_numpy

    return np.asarray(vtk_to_numpy(data.GetPoints().GetData()), dtype=float)


# ---------------------------------------------------------------- scene pieces


def surface_actor(data, color, opacity=1.0):
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals
    from vtkmodules.vtkRenderingCore import vtkActor, vtkPolyDataMapper

    normals = vtkPolyDataNormals()
    normals.SetInputData(data)
    normals.SetFeatureAngle(60.0)
    normals.ConsistencyOn()
    mapper = vtkPolyDataMapper()
    mapper.SetInputConnection(normals.GetOutputPort())
    mapper.ScalarVisibilityOff()
    actor = vtkActor()
    actor.SetMapper(mapper)
    prop = actor.GetProperty()
    prop.SetColor(*color)
    prop.SetOpacity(opacity)
    prop.SetSpecular(0.15 if opacity >= 1 else 0.0)
    # Translucent shells show both sides; an opaque part is lit on its outer side.
    prop.SetBackfaceCulling(False)
    return actor


def lookup_table(kind, low, high):
    """Blue-cyan-green-yellow-red for speed; blue-white-red (0 white) for a gauge pressure."""
    from vtkmodules.vtkCommonCore import vtkLookupTable
    from vtkmodules.vtkRenderingCore import vtkColorTransferFunction

    stops = {
        "speed": [(0.0, (0.16, 0.24, 0.75)), (0.25, (0.16, 0.67, 0.86)), (0.5, (0.31, 0.75, 0.31)), (0.75, (0.94, 0.82, 0.2)), (1.0, (0.82, 0.16, 0.16))],
        "pressure": [(0.0, (0.15, 0.30, 0.75)), (0.5, (0.97, 0.97, 0.97)), (1.0, (0.75, 0.12, 0.12))],
    }[kind]
    function = vtkColorTransferFunction()
    for x, rgb in stops:
        function.AddRGBPoint(x, *rgb)
    table = vtkLookupTable()
    table.SetNumberOfTableValues(256)
    table.Build()
    for k in range(256):
        table.SetTableValue(k, *function.GetColor(k / 255.0), 1.0)
    table.SetRange(low, high)
    table.SetNanColor(0.6, 0.6, 0.6, 1.0)
    return table


def colored_actor(data, array, table):
    from vtkmodules.vtkRenderingCore import vtkActor, vtkDataSetMapper

    mapper = vtkDataSetMapper()
    mapper.SetInputData(data)
    mapper.SetScalarModeToUsePointFieldData()
    mapper.SelectColorArray(array)
    mapper.SetLookupTable(table)
    mapper.UseLookupTableScalarRangeOn()
    mapper.ScalarVisibilityOn()
    actor = vtkActor()
    actor.SetMapper(mapper)
    actor.GetProperty().SetAmbient(0.35)
    actor.GetProperty().SetDiffuse(0.65)
    return actor


def text_actor(text, x, y, size=20, color=(0.1, 0.1, 0.1), bold=False, justify="left", vertical="bottom", backdrop=False):
    from vtkmodules.vtkRenderingCore import vtkTextActor

    actor = vtkTextActor()
    actor.SetInput(text)
    prop = actor.GetTextProperty()
    prop.SetFontSize(size)
    prop.SetColor(*color)
    prop.SetBold(bold)
    if backdrop:
        # Readable over the 3D scene: a half-white box behind the text.
        prop.SetBackgroundColor(1.0, 1.0, 1.0)
        prop.SetBackgroundOpacity(0.75)
    {"left": prop.SetJustificationToLeft, "center": prop.SetJustificationToCentered, "right": prop.SetJustificationToRight}[justify]()
    {"bottom": prop.SetVerticalJustificationToBottom, "center": prop.SetVerticalJustificationToCentered, "top": prop.SetVerticalJustificationToTop}[vertical]()
    actor.SetDisplayPosition(int(x), int(y))
    return actor


def shape_2d(points_px, color, line_width=None):
    """A filled polygon (or, with line_width, a polyline) in display pixels."""
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkRenderingCore import vtkActor2D, vtkPolyDataMapper2D

    points = vtkPoints()
    for x, y in points_px:
        points.InsertNextPoint(x, y, 0.0)
    cells = vtkCellArray()
    cells.InsertNextCell(len(points_px))
    for k in range(len(points_px)):
        cells.InsertCellPoint(k)
    data = vtkPolyData()
    data.SetPoints(points)
    data.SetLines(cells) if line_width else data.SetPolys(cells)
    mapper = vtkPolyDataMapper2D()
    mapper.SetInputData(data)
    actor = vtkActor2D()
    actor.SetMapper(mapper)
    actor.GetProperty().SetColor(*color)
    if line_width:
        actor.GetProperty().SetLineWidth(line_width)
    return actor


class Picture:
    """One offscreen picture: a 3D scene (parallel projection) with its title, orientation
    letters and scale bar, and beside it a panel with the legend and the colour bar."""

    def __init__(self, title, ras, colorbar=None):
        from vtkmodules.vtkRenderingCore import vtkRenderer, vtkRenderWindow

        self.window = vtkRenderWindow()
        self.window.SetOffScreenRendering(1)
        self.window.SetSize(WIDTH_PX, HEIGHT_PX)
        self.window.SetAlphaBitPlanes(1)
        self.window.SetMultiSamples(0)
        self.scene = vtkRenderer()
        self.side = vtkRenderer()
        for renderer, viewport in ((self.scene, (0.0, 0.0, SCENE_WIDTH, 1.0)), (self.side, (SCENE_WIDTH, 0.0, 1.0, 1.0))):
            renderer.SetBackground(1.0, 1.0, 1.0)
            renderer.SetViewport(*viewport)
            self.window.AddRenderer(renderer)
        # Translucent shells drawn in depth order.
        self.scene.SetUseDepthPeeling(1)
        self.scene.SetMaximumNumberOfPeels(8)
        self.scene_px = (WIDTH_PX * SCENE_WIDTH, HEIGHT_PX)
        self.ras = ras
        self.title = title
        self.legend = []
        self.colorbar = colorbar

    def _colorbar(self, table, title):
        from vtkmodules.vtkRenderingAnnotation import vtkScalarBarActor

        bar = vtkScalarBarActor()
        bar.SetLookupTable(table)
        bar.SetNumberOfLabels(5)
        bar.SetLabelFormat("%.2f")
        bar.SetUnconstrainedFontSize(True)
        bar.SetBarRatio(0.25)
        bar.GetPositionCoordinate().SetCoordinateSystemToNormalizedViewport()
        bar.GetPositionCoordinate().SetValue(0.1, 0.05)
        bar.SetWidth(0.8)
        bar.SetHeight(0.5)
        prop = bar.GetLabelTextProperty()
        prop.SetColor(0.1, 0.1, 0.1)
        prop.SetFontSize(LABEL_PX)
        prop.ShadowOff()
        prop.ItalicOff()
        prop.BoldOff()
        self.side.AddViewProp(bar)
        # Text positions are window pixels; the panel starts at the scene's right edge.
        x = self.scene_px[0] + 14
        for k, line in enumerate(title.split("\n")):
            self.side.AddViewProp(text_actor(line, x, HEIGHT_PX * 0.57 + (LABEL_PX + 4) * (1 - k), size=LABEL_PX, bold=k == 0))

    def add(self, actor):
        self.scene.AddActor(actor)

    def add_legend(self, name, color):
        self.legend.append((name, color))

    def look(self, points, look, right, up, margin=1.25):
        """Parallel camera looking along `look` at the box of `points` (mm), `up` up; the
        box fills 1/margin of the scene's height or width."""
        import numpy as np

        look, right, up = (np.asarray(v, dtype=float) / np.linalg.norm(v) for v in (look, right, up))
        u, v, w = points @ right, points @ up, points @ look
        center = right * (u.min() + u.max()) / 2 + up * (v.min() + v.max()) / 2 + look * (w.min() + w.max()) / 2
        width_px, height_px = self.scene_px
        # Half the height shown (mm): the box with room for the title and the scale bar.
        half_height = max((v.max() - v.min()) / 2, (u.max() - u.min()) / 2 * height_px / width_px) * margin
        camera = self.scene.GetActiveCamera()
        camera.ParallelProjectionOn()
        camera.SetFocalPoint(*center)
        distance = 4.0 * float(max(np.ptp(u), np.ptp(v), np.ptp(w), 1.0))
        camera.SetPosition(*(center - look * distance))
        camera.SetViewUp(*up)
        camera.SetParallelScale(half_height)
        self.scene.ResetCameraClippingRange()
        self.px_per_mm = height_px / (2 * half_height)
        self.directions = (right, up)

    def _overlays(self):
        width_px, height_px = self.scene_px
        right, up = self.directions
        letter = lambda d: orientation_letter(d, self.ras)
        grey = (0.35, 0.35, 0.35)
        for text, x, y, h, v in (
            (letter(right), width_px - 12, height_px / 2, "right", "center"),
            (letter(-right), 12, height_px / 2, "left", "center"),
            (letter(up), width_px / 2, height_px - 40, "center", "top"),
            (letter(-up), width_px / 2, 12, "center", "bottom"),
        ):
            self.scene.AddViewProp(text_actor(text, x, y, size=LETTER_PX, color=grey, bold=True, justify=h, vertical=v, backdrop=True))
        self.scene.AddViewProp(text_actor(self.title, 12, height_px - 10, size=TITLE_PX, bold=True, vertical="top", backdrop=True))
        # Scale bar: a round length about a fifth of the scene's width, at the bottom left.
        length_mm = round_length_mm(0.2 * width_px / self.px_per_mm)
        x0, y0, bar_px = 20, 24, length_mm * self.px_per_mm
        self.scene.AddViewProp(shape_2d([(x0, y0), (x0 + bar_px, y0)], (0.1, 0.1, 0.1), line_width=4))
        for x in (x0, x0 + bar_px):
            self.scene.AddViewProp(shape_2d([(x, y0 - 5), (x, y0 + 5)], (0.1, 0.1, 0.1), line_width=2))
        self.scene.AddViewProp(text_actor(f"{length_mm:g} mm", x0 + bar_px / 2, y0 + 8, size=LABEL_PX, justify="center", backdrop=True))
        # The legend of the parts at the top of the side panel, the colour bar below it.
        x = width_px + 10
        for k, (name, color) in enumerate(self.legend):
            y = height_px - 40 - (LABEL_PX + 8) * k
            # A 2D shape's points are the panel's own pixels, a text's the window's.
            square = [(10, y), (30, y), (30, y + 20), (10, y + 20)]
            self.side.AddViewProp(shape_2d(square, color))
            self.side.AddViewProp(text_actor(name, x + 24, y, size=LABEL_PX))
        if self.colorbar:
            self._colorbar(*self.colorbar)

    def write(self, path):
        """Render, write the PNG, and return its pixel statistics (raises if blank)."""
        import numpy as np
        from vtkmodules.util.numpy_support import vtk_to_numpy
        from vtkmodules.vtkIOImage import vtkPNGWriter
        from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter

        self._overlays()
        self.window.Render()
        grab = vtkWindowToImageFilter()
        grab.SetInput(self.window)
        grab.SetInputBufferTypeToRGB()
        grab.ReadFrontBufferOff()
        grab.Update()
        image = grab.GetOutput()
        pixels = vtk_to_numpy(image.GetPointData().GetScalars()).astype(float)
        # The scene alone (the 3D part): text on white is not a rendered picture.
        width, height, _ = image.GetDimensions()
        scene = pixels.reshape(height, width, -1)[:, : int(self.scene_px[0])]
        non_white = float(np.mean(np.any(scene < 250, axis=-1)))
        if non_white < 0.02:
            raise RenderError(f"{path.name}: the offscreen renderer gave a blank picture ({non_white:.1%} of its pixels drawn); is OpenGL (EGL or OSMesa) available?", status=4)
        writer = vtkPNGWriter()
        writer.SetFileName(str(path))
        writer.SetInputData(image)
        writer.Write()
        self.window.Finalize()
        return {"drawn_fraction": round(non_white, 4), "mean": round(float(pixels.mean()), 2)}


# ---------------------------------------------------------------- the plan's pictures


class Plan:
    """The files of a completed `baffle plan` folder the pictures are made from."""

    def __init__(self, folder, labels):
        self.folder = Path(folder)
        report_path = self.folder / "report.json"
        try:
            self.report = json.loads(report_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as error:
            raise RenderError(f"{report_path}: {error}")
        if self.report.get("status") != "completed":
            raise RenderError(f"{report_path}: the plan did not complete (stage {self.report.get('failed_stage')} failed)")
        self.labels = labels
        self.extended = bool(self.report.get("domain", {}).get("extended"))
        self.domain = read_surface(self.folder / "design" / "domain.vtp")
        self.cfd_domain = read_surface(self.folder / "extend" / "extended.vtp") if self.extended else self.domain
        self.centerline = read_surface(self.folder / "centerline" / "centerline.vtp")
        nominal = next((r["stage"] for r in self.report.get("runs", []) if r.get("mesh") == "nominal"), "simulate-nominal")
        self.peak = read_volume(self.folder / nominal / "peak.vtu")
        self.anatomy = self._anatomy()

    def _anatomy(self):
        """The LV, RV and aorta segment surfaces the prepare stage read, when it read a
        folder (a relative one is taken from the current directory, as the plan was run);
        `self.anatomy_note` says why there are none."""
        folder = self.report.get("inputs", {}).get("segmentations")
        if not folder:
            self.anatomy_note = "no LV, RV and aorta segment surfaces (the plan did not start from --segmentations): the context views show the CFD domain alone"
            return {}
        found = {name: find_structure(Path(folder), stems) for name, stems in STRUCTURE_STEMS.items()}
        missing = [name for name, path in found.items() if path is None]
        self.anatomy_note = f"segment surfaces not found in {folder}: {', '.join(missing)}" if missing else ""
        return {name: read_surface(path) for name, path in found.items() if path is not None}

    def part(self, surface, *names):
        return with_labels(surface, [self.labels[n] for n in names])

    def cfd_wall(self, *also):
        """The CFD domain's wall, with the parts named in `also` ("baffle", ...): neither the
        VSD and aortic planes nor, for the designed domain, its end caps, which would hide
        what lies behind them."""
        return self.part(self.cfd_domain, "wall", *also)


def mid_centerline(centerline):
    """The middle point of the flow-domain centerline and its unit direction there."""
    import numpy as np

    points = points_of(centerline)
    mid = len(points) // 2
    tangent = points[min(mid + 1, len(points) - 1)] - points[max(mid - 1, 0)]
    return points[mid], tangent / np.linalg.norm(tangent)


def speed_cut(peak, origin, normal):
    """The peak speed on the plane through `origin` (normal `normal`), only the piece of it
    that holds `origin`'s flow (a plane through the whole domain also crosses other parts)."""
    cut = plane_cut(peak, origin, normal, nearest=True)
    if cut.GetNumberOfCells() == 0:
        raise RenderError("the cut plane through the middle of the flow-domain centerline misses the mesh")
    return cut


def plane_cut(data, origin, normal, nearest: bool = False):
    """The cut of `data` (a surface or a volume mesh) by the plane through `origin` with
    `normal`; with `nearest`, only its connected piece nearest `origin` (a plane through a
    curved domain also crosses it elsewhere). Also the package's (vtk_adapters.plane_cut)."""
    from vtkmodules.vtkCommonDataModel import vtkPlane
    from vtkmodules.vtkFiltersCore import vtkCutter, vtkPolyDataConnectivityFilter

    plane = vtkPlane()
    plane.SetOrigin(*origin)
    plane.SetNormal(*normal)
    cutter = vtkCutter()
    cutter.SetInputData(data)
    cutter.SetCutFunction(plane)
    if not nearest:
        cutter.Update()
        return cutter.GetOutput()
    piece = vtkPolyDataConnectivityFilter()
    piece.SetInputConnection(cutter.GetOutputPort())
    piece.SetExtractionModeToClosestPointRegion()
    piece.SetClosestPoint(*origin)
    piece.Update()
    return piece.GetOutput()


def rim_tube(cap, radius_mm):
    """The boundary loop of a cap as a tube: the cap's outline, which hides nothing behind it."""
    from vtkmodules.vtkFiltersCore import vtkFeatureEdges, vtkTubeFilter

    edges = vtkFeatureEdges()
    edges.SetInputData(cap)
    edges.BoundaryEdgesOn()
    edges.FeatureEdgesOff()
    edges.ManifoldEdgesOff()
    edges.NonManifoldEdgesOff()
    tube = vtkTubeFilter()
    tube.SetInputConnection(edges.GetOutputPort())
    tube.SetRadius(radius_mm)
    tube.SetNumberOfSides(12)
    tube.Update()
    return tube.GetOutput()


def size_mm(data):
    """The diagonal of the bounding box of `data` (mm)."""
    import numpy as np

    points = points_of(data)
    return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


def centerline_tube(centerline, radius_mm):
    from vtkmodules.vtkFiltersCore import vtkTubeFilter

    tube = vtkTubeFilter()
    tube.SetInputData(centerline)
    tube.SetRadius(radius_mm)
    tube.SetNumberOfSides(16)
    tube.CappingOn()
    tube.Update()
    return tube.GetOutput()


def array_range(data, name):
    import numpy as np
    from vtkmodules.util.numpy_support import vtk_to_numpy

    array = data.GetPointData().GetArray(name)
    if array is None:
        raise RenderError(f"no point array {name}")
    values = vtk_to_numpy(array).astype(float)
    values = values[np.isfinite(values)]
    if values.size == 0:
        raise RenderError(f"the point array {name} holds no finite value")
    return float(values.min()), float(values.max())


def context_picture(plan, view, ras):
    """The CFD domain in the anatomy: LV, RV, aorta translucent, baffle and caps opaque."""
    key, name, look, right, up = view
    picture = Picture(f"{name}, in context", ras)
    for structure, surface in plan.anatomy.items():
        picture.add(surface_actor(surface, COLORS[structure], 0.15))
        picture.add_legend(f"{structure} segment", COLORS[structure])
    # The CFD domain's own wall shows where the flow is computed (the extension's ends).
    picture.add(surface_actor(plan.part(plan.cfd_domain, "wall"), COLORS["domain"], 0.3))
    picture.add_legend("CFD wall", COLORS["domain"])
    shown = [("baffle", "baffle", 1.0), ("vsd", "VSD plane", 0.9), ("aortic", "aortic plane", 0.9)]
    if plan.extended:
        # Half see-through: the mid-LV cap is wide and would hide the LV behind it.
        shown += [("inflow", "inflow (mid-LV)", 0.55), ("outflow", "outflow (STJ)", 0.55)]
    for part, label, opacity in shown:
        data = plan.part(plan.cfd_domain, part)
        if data is not None:
            picture.add(surface_actor(data, COLORS[part], opacity))
            picture.add_legend(label, COLORS[part])
    picture.add(surface_actor(centerline_tube(plan.centerline, 0.3), COLORS["centerline"]))
    picture.add_legend("centerline", COLORS["centerline"])
    # Framed on the CFD domain: the anatomy around it may run off the edges.
    picture.look(points_of(plan.cfd_domain), look, right, up, margin=1.4)
    return picture


def aortic_face_on_picture(plan, ras):
    """The designed pathway seen straight into its aortic cap, superior kept up."""
    import numpy as np

    cap = plan.part(plan.domain, "aortic")
    if cap is None:
        raise RenderError("the designed domain has no aortic cap")
    from vtkmodules.vtkFiltersCore import vtkPolyDataNormals

    normals = vtkPolyDataNormals()
    normals.SetInputData(cap)
    normals.ComputeCellNormalsOn()
    normals.SplittingOff()
    normals.AutoOrientNormalsOff()
    normals.ConsistencyOff()
    normals.Update()
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkFiltersVerdict import vtkCellSizeFilter

    sizes = vtkCellSizeFilter()
    sizes.SetInputConnection(normals.GetOutputPort())
    sizes.Update()
    out = sizes.GetOutput()
    outward = (vtk_to_numpy(out.GetCellData().GetNormals()) * vtk_to_numpy(out.GetCellData().GetArray("Area"))[:, None]).sum(axis=0)
    look = -outward / np.linalg.norm(outward)
    superior = np.array([0.0, 0.0, 1.0])
    up = superior - look * superior.dot(look)
    up = up / np.linalg.norm(up) if np.linalg.norm(up) > 1e-6 else np.cross(look, [1.0, 0.0, 0.0])
    right = np.cross(look, up)
    picture = Picture("Aortic annulus, face-on", ras)
    for part, label, opacity in (("wall", "RV wall", 0.3), ("baffle", "baffle", 1.0), ("vsd", "VSD cap", 1.0)):
        data = plan.part(plan.domain, part)
        if data is not None:
            picture.add(surface_actor(data, COLORS[part], opacity))
            picture.add_legend(label, COLORS[part])
    # The annulus as its rim: the pathway behind it stays in sight.
    picture.add(surface_actor(rim_tube(cap, 0.006 * size_mm(plan.domain)), COLORS["aortic"]))
    picture.add_legend("aortic annulus", COLORS["aortic"])
    picture.look(points_of(plan.domain), look, right, up)
    return picture


def cut_plane(plan, anterior):
    """The plane through the centerline's middle that holds its direction there, turned as
    near to facing the anterior viewer as that allows: (origin, normal, s_mm)."""
    import numpy as np

    origin, tangent = mid_centerline(plan.centerline)
    look = np.asarray(anterior[2], dtype=float)
    normal = look - tangent * tangent.dot(look)
    if np.linalg.norm(normal) < 1e-6:
        normal = np.cross(tangent, anterior[3])
    normal = normal / np.linalg.norm(normal)
    return origin, normal if normal.dot(look) >= 0 else -normal


def speed_pictures(plan, anterior, ras):
    """The peak speed on the cut, inside the translucent pathway (anterior) and face-on."""
    import numpy as np

    origin, normal = cut_plane(plan, anterior)
    cut = speed_cut(plan.peak, origin, normal)
    low, high = 0.0, max(array_range(cut, "speed_m_s")[1], 1e-6)
    table = lookup_table("speed", low, high)
    bar = (table, "speed\nat peak (m/s)")

    in_context = Picture(f"{anterior[1]}: peak speed on a cut", ras, colorbar=bar)
    in_context.add(surface_actor(plan.cfd_wall("inflow", "outflow"), COLORS["domain"], 0.2))
    baffle = plan.part(plan.cfd_domain, "baffle")
    if baffle is not None:
        in_context.add(surface_actor(baffle, COLORS["baffle"], 0.35))
        in_context.add_legend("baffle", COLORS["baffle"])
    in_context.add_legend("CFD wall", COLORS["domain"])
    in_context.add(colored_actor(cut, "speed_m_s", table))
    in_context.look(points_of(plan.cfd_domain), *anterior[2:])

    face_on = Picture("Peak speed on the cut, face-on", ras, colorbar=bar)
    face_on.add(colored_actor(cut, "speed_m_s", table))
    look = np.asarray(normal)
    up = np.asarray(anterior[4], dtype=float)
    up = up - look * up.dot(look)
    up = up / np.linalg.norm(up) if np.linalg.norm(up) > 1e-6 else np.cross(look, anterior[3])
    face_on.look(points_of(cut), look, np.cross(look, up), up)
    return in_context, face_on, high


def pressure_picture(plan, anterior, ras):
    """The flow-domain centerline coloured by the pressure relative to the aortic plane."""
    name = "pressure_rel_aortic_plane_mmhg"
    low, high = array_range(plan.centerline, name)
    # Symmetric about 0 so white is the aortic plane's mean pressure.
    extent = max(abs(low), abs(high), 1e-3)
    table = lookup_table("pressure", -extent, extent)
    picture = Picture(f"{anterior[1]}: centerline pressure", ras, colorbar=(table, "p - aortic\nplane (mmHg)"))
    picture.add(surface_actor(plan.cfd_wall("baffle", "inflow", "outflow"), COLORS["domain"], 0.2))
    picture.add_legend("CFD wall", COLORS["domain"])
    pathway = size_mm(plan.domain)
    for part, label in (("vsd", "VSD plane"), ("aortic", "aortic plane")):
        data = plan.part(plan.cfd_domain, part)
        if data is not None:
            picture.add(surface_actor(rim_tube(data, 0.005 * pathway), COLORS[part]))
            picture.add_legend(label, COLORS[part])
    picture.add(colored_actor(centerline_tube(plan.centerline, 0.025 * pathway), name, table))
    # Framed on the designed pathway (VSD to aortic plane), where the centerline runs.
    picture.look(points_of(plan.domain), *anterior[2:], margin=1.5)
    return picture, (low, high)


def render_plan(folder, ras=False, labels=None):
    """Write the pictures of the plan in `folder` to folder/pictures; returns the manifest."""
    _import_vtk()
    labels = {**DEFAULT_LABELS, **(labels or {})}
    plan = Plan(folder, labels)
    out = plan.folder / "pictures"
    out.mkdir(exist_ok=True)
    frame = "RAS" if ras else "LPS"
    views = anatomical_views(ras)
    anterior = views[0]
    notes = [plan.anatomy_note] if plan.anatomy_note else []
    pictures = []

    def add(file, picture, caption, section):
        stats = picture.write(out / file)
        pictures.append({"file": file, "title": picture.title, "caption": caption, "section": section, "pixels": stats})

    where = "the extended CFD domain (LV to the mid-LV inflow cap, aorta to the STJ outflow cap)" if plan.extended else "the designed CFD domain"
    for view in views[:2]:
        add(
            f"context_{view[0]}.png",
            context_picture(plan, view, ras),
            f"{view[1]} ({frame} frame): {where} in the segmented anatomy (translucent), the baffle highlighted, the VSD and aortic planes and the flow-domain centerline.",
            "anatomy",
        )
    add(
        "aortic_cap_face_on.png",
        aortic_face_on_picture(plan, ras),
        "The designed pathway seen straight into the aortic annulus (its rim in yellow) from the aorta: the baffle and, beside it, the VSD cap, through the translucent RV wall; the letters give the patient's directions.",
        "anatomy",
    )
    in_context, face_on, v_max = speed_pictures(plan, anterior, ras)
    plane = "a plane through the middle of the flow-domain centerline that holds its direction there, turned to face the anterior viewer as far as that allows"
    add(
        "speed_cut_anterior.png",
        in_context,
        f"Speed at peak flow (m/s, peak.vtu) on {plane}, inside the translucent CFD domain; the largest speed on the cut is {v_max:.2f} m/s. "
        "The wall itself is not coloured: the flow is zero there (no slip).",
        "flow",
    )
    add("speed_cut_face_on.png", face_on, "The same cut seen face-on, with its scale bar.", "flow")
    picture, (low, high) = pressure_picture(plan, anterior, ras)
    add(
        "pressure_centerline.png",
        picture,
        f"The flow-domain centerline coloured by the pressure at peak flow relative to the aortic plane's mean ({low:.2f} to {high:.2f} mmHg; grey where not sampled).",
        "flow",
    )
    manifest = {"frame": frame, "pictures": pictures, "notes": notes}
    (out / "pictures.json").write_text(json.dumps(manifest, indent=2), encoding="utf-8")
    return manifest


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python3 -m baffle.render", description=__doc__.split("\n\n")[0])
    parser.add_argument("plan", help="a completed `baffle plan` --out folder")
    parser.add_argument("--frame", choices=("lps", "ras"), default="lps", help="the surfaces' frame (default LPS, as Slicer writes models)")
    for part, label in DEFAULT_LABELS.items():
        parser.add_argument(f"--{part}-label", type=int, default=label, help=f"ModelFaceID of the {part} (default {label})")
    args = parser.parse_args(argv)
    labels = {part: getattr(args, f"{part}_label") for part in DEFAULT_LABELS}
    try:
        manifest = render_plan(args.plan, ras=args.frame == "ras", labels=labels)
    except RenderError as error:
        print(f"baffle.render: {error}", file=sys.stderr)
        return error.status
    for picture in manifest["pictures"]:
        print(Path(args.plan) / "pictures" / picture["file"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
