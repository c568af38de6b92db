"""A stand-in for SlicerHeart's BafflePlanner logic (BafflePlanner/BafflePlanner.py), written
here after its public source, for what meets BaffleDesigner in one scene:

- its parameter node is ScriptedLoadableModuleLogic's singleton vtkMRMLScriptedModuleNode
  (singleton tag and attribute ModuleName "BafflePlanner"), which references the selected
  curve as 'InputCurve';
- the input is a closed curve (its selector's base name is 'BC'); selecting it sets the
  curve's attribute AutoUpdate to "true" when it has none, creates the '<curve> surface
  points' point list (reference 'SurfacePoints'); the baffle model is the curve's
  'BaffleModel' reference, and RadiusScalingFactor / BaffleSurfaceThickness* attributes
  are read from the curve on every rebuild;
- the logic observes the curve's PointModifiedEvent (rebuild when AutoUpdate is "true")
  and vtkCommand.ModifiedEvent (onInputCurveParametersModified: it re-reads the curve's
  references, and setOutputBaffleModelNode -> updatePointPlaceMode rebuilds, then
  rebuilds again): every ModifiedEvent of the curve rebuilds the baffle;
- updatePointPlaceMode snaps points to the visible surface unless auto-updating;
- the rebuild resamples the curve to 80 points and warps a unit disk onto them with a
  thin-plate spline (the 'soap bubble'), into the BaffleModel node.

`rebuilds` counts updateOutputBaffleModel runs, `modified_reactions` the ModifiedEvents
it answered. Nothing here draws or is interactive."""

import math

import slicer
import vtk

MODULE_NAME = "BafflePlanner"
LANDMARKS = 80


class BafflePlannerLogic:
    def __init__(self, scene=None):
        self.scene = scene if scene is not None else slicer.mrmlScene
        self.inputCurveNode = None
        self._curve_tags = []
        self.surfacePointsNode = None
        self._points_tags = []
        self.rebuilds = 0
        self.modified_reactions = 0

    # ---- parameter node (ScriptedLoadableModuleLogic.getParameterNode) -------------------

    def getParameterNode(self):
        from BaffleDesignerLib.logic import singleton_parameter_node  # Slicer's base does the same

        return singleton_parameter_node(self.scene, MODULE_NAME)

    # ---- inputs ----------------------------------------------------------------------------

    def getAutoUpdateEnabled(self):
        return bool(self.inputCurveNode) and self.inputCurveNode.GetAttribute("AutoUpdate") == "true"

    def setAutoUpdateEnabled(self, enabled):
        if self.inputCurveNode:
            self.inputCurveNode.SetAttribute("AutoUpdate", "true" if enabled else "false")
            self.updatePointPlaceMode()

    def setInputCurveNode(self, curve):
        if self.inputCurveNode:
            for tag in self._curve_tags:
                self.inputCurveNode.RemoveObserver(tag)
            self._curve_tags = []
            self.inputCurveNode = None
            self.setSurfacePointsNode(None)
        self.inputCurveNode = curve
        if curve:
            if not curve.GetAttribute("AutoUpdate"):
                curve.SetAttribute("AutoUpdate", "true")
            self._curve_tags = [
                curve.AddObserver(slicer.vtkMRMLMarkupsNode.PointModifiedEvent, self.onInputPointsModified),
                curve.AddObserver(vtk.vtkCommand.ModifiedEvent, self.onInputCurveModified),
            ]
            self.onInputCurveParametersModified()
            if self.surfacePointsNode is None:
                points = self.scene.AddNewNodeByClass("vtkMRMLMarkupsFiducialNode", curve.GetName() + " surface points")
                self.setSurfacePointsNode(points)
            self.onInputPointsModified()
        self.getParameterNode().SetAndObserveNodeReferenceID("InputCurve", curve.GetID() if curve else None)

    def setSurfacePointsNode(self, points):
        if self.surfacePointsNode is not None and self.surfacePointsNode is not points:
            for tag in self._points_tags:
                self.surfacePointsNode.RemoveObserver(tag)
            self._points_tags = []
            self.surfacePointsNode = None
        if self.surfacePointsNode is points:
            return
        self.surfacePointsNode = points
        if points is not None:
            self._points_tags = [points.AddObserver(slicer.vtkMRMLMarkupsNode.PointModifiedEvent, self.onInputPointsModified)]
            if self.inputCurveNode:
                self.inputCurveNode.SetAndObserveNodeReferenceID("SurfacePoints", points.GetID())
            self.onInputCurveParametersModified()
            self.onInputPointsModified()

    def getOutputBaffleModelNode(self):
        return self.inputCurveNode.GetNodeReference("BaffleModel") if self.inputCurveNode else None

    def setOutputBaffleModelNode(self, model):
        if not self.inputCurveNode:
            return
        self.inputCurveNode.SetAndObserveNodeReferenceID("BaffleModel", model.GetID() if model else None)
        self.updatePointPlaceMode()
        self.onInputPointsModified()

    def updatePointPlaceMode(self):
        unconstrained = self.getAutoUpdateEnabled() and self.getOutputBaffleModelNode()
        mode = slicer.vtkMRMLMarkupsDisplayNode.SnapModeUnconstrained if unconstrained else slicer.vtkMRMLMarkupsDisplayNode.SnapModeToVisibleSurface
        for points in (self.inputCurveNode, self.surfacePointsNode):
            if points is not None and points.GetDisplayNode() is not None:
                points.GetDisplayNode().SetSnapMode(mode)
        self.onInputPointsModified()

    # ---- observers ----------------------------------------------------------------------------

    def onInputPointsModified(self, *_):
        if self.getAutoUpdateEnabled():
            self.updateOutputBaffleModel()

    def onInputCurveModified(self, *_):
        self.modified_reactions += 1
        self.onInputCurveParametersModified()

    def onInputCurveParametersModified(self, *_):
        if self.inputCurveNode:
            self.setSurfacePointsNode(self.inputCurveNode.GetNodeReference("SurfacePoints"))
            self.setOutputBaffleModelNode(self.inputCurveNode.GetNodeReference("BaffleModel"))
        else:
            self.setSurfacePointsNode(None)

    # ---- the soap-bubble baffle ----------------------------------------------------------------

    def updateOutputBaffleModel(self):
        model = self.getOutputBaffleModelNode()
        if not self.inputCurveNode or model is None:
            return
        self.rebuilds += 1
        curve_points = self.inputCurveNode.GetCurvePointsWorld()
        length = self.inputCurveNode.GetCurveLengthWorld()
        targets = vtk.vtkPoints()
        if curve_points is None or curve_points.GetNumberOfPoints() < 2 or length <= 0:
            model.SetAndObservePolyData(vtk.vtkPolyData())
            return
        slicer.vtkMRMLMarkupsCurveNode.ResamplePoints(curve_points, targets, length / (LANDMARKS - 0.1), True)
        sources = vtk.vtkPoints()
        for i in range(targets.GetNumberOfPoints()):
            angle = 2.0 * math.pi * i / targets.GetNumberOfPoints()
            sources.InsertNextPoint(math.cos(angle), math.sin(angle), 0.0)
        scale = float(self.inputCurveNode.GetAttribute("RadiusScalingFactor") or 1.0)
        disk = vtk.vtkDiskSource()
        disk.SetInnerRadius(0.0)
        disk.SetOuterRadius(scale)
        disk.SetCircumferentialResolution(LANDMARKS)
        disk.SetRadialResolution(20)
        triangulate = vtk.vtkTriangleFilter()
        triangulate.SetInputConnection(disk.GetOutputPort())
        spline = vtk.vtkThinPlateSplineTransform()
        spline.SetBasisToR()
        spline.SetSourceLandmarks(sources)
        spline.SetTargetLandmarks(targets)
        warp = vtk.vtkTransformPolyDataFilter()
        warp.SetTransform(spline)
        warp.SetInputConnection(triangulate.GetOutputPort())
        warp.Update()
        model.SetAndObservePolyData(warp.GetOutput())
