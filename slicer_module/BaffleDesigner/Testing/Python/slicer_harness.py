"""A headless stand-in for the parts of the 3D Slicer application that BaffleDesigner's
Widget, Logic and Test touch, so that the real module file runs outside Slicer.

What is real and what stands in:
- MRML, the module logics (plots, models, markups, segmentations, application and
  layout logic) and `slicer.util` come from the slicer-core wheel: Slicer's own classes.
- Qt is PySide6 on the offscreen platform, made to behave as PythonQt does in Slicer
  (`qt` module): Qt properties are attributes (`button.enabled = False`, `label.text`),
  shadowing methods of the same name; `obj.connect("signal(args)", slot)` and
  `disconnect(...)`, with the signature checked against the sender's signals; `name` is
  the object name.
- The .ui's custom widgets (ctkCollapsibleButton, qMRMLNodeComboBox, qMRMLWidget) are
  written here after their documentation; the .ui's <connections> are made as Qt's
  loader makes them in Slicer.
- `slicer.ScriptedLoadableModule` is scripted_loadable_module.py beside this file,
  written to behave as Slicer's (cooperative __init__, parameter node, reload).
- `slicer.app` gives what the module asks of the application: temporary path, event
  processing, application / layout logic, layout manager, module manager, I/O manager
  (models and markups through the real logics' readers), startup environment, testing
  mode (message boxes are logged, as `slicer.util` does in Slicer's testing mode).

It does not draw: views, rendering, mouse interaction in 3D views and the look of the
panel are Slicer's alone. See slicer_module/README.md.
"""

import importlib.util
import os
import re
import sys
import tempfile
import types
import xml.etree.ElementTree as ElementTree
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6 import QtCore, QtGui, QtUiTools, QtWidgets  # noqa: E402

import slicer  # noqa: E402  (slicer-core)
import slicer.util  # noqa: E402

HERE = Path(__file__).resolve().parent

# ---- PythonQt behaviour on PySide6 objects ----------------------------------------------


def _qt_property_names(cls):
    """Names of the Qt properties of a PythonQt-style class (cached per class)."""
    names = cls.__dict__.get("_qt_property_names")
    if names is None:
        meta = cls.staticMetaObject
        names = frozenset(meta.property(i).name() for i in range(meta.propertyCount()))
        cls._qt_property_names = names
    return names


def _normalized(signature):
    return bytes(QtCore.QMetaObject.normalizedSignature(signature)).decode()


class PythonQtObject:
    """Mixed into every QObject class the `qt` module hands out."""

    # Signatures of signals declared in Python (Signal(object) stands for a vtk pointer).
    pythonqt_signals = {}

    def __getattribute__(self, name):
        if name[:1] != "_" and name in _qt_property_names(type(self)):
            return QtCore.QObject.property(self, name)
        if name == "name":
            return QtCore.QObject.objectName(self)
        if name in ("connect", "disconnect"):  # PySide resolves these to QObject's own
            return types.MethodType(getattr(PythonQtObject, name), self)
        return super().__getattribute__(name)

    def __setattr__(self, name, value):
        if name[:1] != "_" and name in _qt_property_names(type(self)):
            if not QtCore.QObject.setProperty(self, name, value):
                raise AttributeError(f"{type(self).__name__}.{name} cannot be set to {value!r}")
            return
        if name == "name":
            QtCore.QObject.setObjectName(self, value)
            return
        super().__setattr__(name, value)

    def _python_signal(self, signature):
        for klass in type(self).__mro__:
            attribute = klass.__dict__.get("pythonqt_signals", {}).get(_normalized(signature))
            if attribute:
                return getattr(self, attribute)
        return None

    def connect(self, signature, slot):
        """PythonQt's connect: an unknown signal is an error here (PythonQt prints one)."""
        signal = self._python_signal(signature)
        if signal is not None:
            signal.connect(slot)
            return True
        if self.metaObject().indexOfSignal(_normalized(signature)) < 0:
            raise AttributeError(f"{type(self).__name__} has no signal {signature}")
        QtCore.QObject.connect(self, QtCore.SIGNAL(signature), slot)
        return True

    def disconnect(self, signature, slot):
        signal = self._python_signal(signature)
        if signal is not None:
            signal.disconnect(slot)
            return True
        return QtCore.QObject.disconnect(self, QtCore.SIGNAL(signature), slot)


_wrapped = {}


def pythonqt_class(cls):
    """`cls` (a PySide6 QObject class) as PythonQt presents it."""
    if not (isinstance(cls, type) and issubclass(cls, QtCore.QObject)) or issubclass(cls, PythonQtObject):
        return cls
    if cls not in _wrapped:
        _wrapped[cls] = type(cls.__name__, (PythonQtObject, cls), {"__module__": "qt"})
    return _wrapped[cls]


class UiLoader(QtUiTools.QUiLoader):
    """QUiLoader making PythonQt-style widgets, the custom widgets below, and the .ui's
    <connections> (by signature, as Qt's loader does in Slicer)."""

    def createWidget(self, class_name, parent=None, name=""):
        cls = CUSTOM_WIDGETS.get(class_name) or pythonqt_class(getattr(QtWidgets, class_name, None))
        if cls is None:
            raise RuntimeError(f"the .ui uses {class_name}, which neither Qt nor this harness provides")
        widget = cls(parent)
        widget.setObjectName(name)
        return widget

    def createLayout(self, class_name, parent=None, name=""):
        layout = pythonqt_class(getattr(QtWidgets, class_name))(parent)
        layout.setObjectName(name)
        return layout

    def load(self, device, parent=None):
        text = bytes(device.readAll()).decode("utf-8")
        root = ElementTree.fromstring(text)
        connections = root.find("connections")
        wanted = []
        if connections is not None:
            wanted = [(c.findtext("sender"), c.findtext("signal"), c.findtext("receiver"), c.findtext("slot"))
                      for c in connections.findall("connection")]
            root.remove(connections)
        buffer = QtCore.QBuffer()
        buffer.setData(ElementTree.tostring(root))
        buffer.open(QtCore.QIODevice.ReadOnly)
        widget = super().load(buffer, parent)
        if widget is None:
            return None
        for sender, signal, receiver, slot in wanted:
            objects = [self._named(widget, sender), self._named(widget, receiver)]
            objects[0].connect(signal, getattr(objects[1], slot.split("(")[0]))
        return widget

    @staticmethod
    def _named(top, name):
        found = top if QtCore.QObject.objectName(top) == name else top.findChild(QtCore.QObject, name)
        if found is None:
            raise RuntimeError(f".ui connection names {name}, which the form does not have")
        return found


def make_qt_module():
    """The `qt` module of PythonQt: Qt classes by name, QObjects PythonQt-style."""
    module = types.ModuleType("qt")
    sources = (QtCore, QtGui, QtWidgets, QtUiTools)

    def lookup(name):
        if name == "QUiLoader":
            return UiLoader
        for source in sources:
            if hasattr(source, name):
                value = pythonqt_class(getattr(source, name))
                setattr(module, name, value)
                return value
        raise AttributeError(f"module 'qt' has no attribute {name!r}")

    module.__getattr__ = lookup
    return module


# ---- the .ui's custom widgets, after their documentation ---------------------------------


class qMRMLWidget(pythonqt_class(QtWidgets.QWidget)):
    """qMRMLWidget: a QWidget holding a MRML scene; setMRMLScene emits mrmlSceneChanged."""

    mrmlSceneChanged = QtCore.Signal(object)
    pythonqt_signals = {"mrmlSceneChanged(vtkMRMLScene*)": "mrmlSceneChanged"}

    def __init__(self, parent=None):
        super().__init__(parent)
        self._scene = None

    def setMRMLScene(self, scene):
        if scene is self._scene:
            return
        self._scene = scene
        self.mrmlSceneChanged.emit(scene)

    def mrmlScene(self):
        return self._scene


class ctkCollapsibleButton(pythonqt_class(QtWidgets.QWidget)):
    """ctkCollapsibleButton: a titled container whose contents hide when collapsed."""

    contentsCollapsed = QtCore.Signal(bool)
    pythonqt_signals = {"contentsCollapsed(bool)": "contentsCollapsed"}

    def __init__(self, parent=None):
        super().__init__(parent)
        self._text = ""
        self._collapsed = False

    def _get_text(self):
        return self._text

    def _set_text(self, text):
        self._text = text

    def _get_collapsed(self):
        return self._collapsed

    def _set_collapsed(self, collapsed):
        self._collapsed = bool(collapsed)
        for child in self.findChildren(QtWidgets.QWidget, options=QtCore.Qt.FindDirectChildrenOnly):
            child.setVisible(not self._collapsed)
        self.contentsCollapsed.emit(self._collapsed)

    text = QtCore.Property(str, _get_text, _set_text)
    collapsed = QtCore.Property(bool, _get_collapsed, _set_collapsed)


class qMRMLNodeComboBox(pythonqt_class(QtWidgets.QWidget)):
    """qMRMLNodeComboBox: lists the scene's nodes of `nodeTypes` (subclasses too), not the
    hidden ones; with noneEnabled false it selects the first node that appears while
    none is current, and another one when the current node leaves the scene."""

    currentNodeChanged = QtCore.Signal(object)
    currentNodeIDChanged = QtCore.Signal(str)
    pythonqt_signals = {
        "currentNodeChanged(vtkMRMLNode*)": "currentNodeChanged",
        "currentNodeIDChanged(QString)": "currentNodeIDChanged",
    }

    def __init__(self, parent=None):
        super().__init__(parent)
        self._scene = None
        self._tags = []
        self._current = None
        self._nodeTypes = []
        self._flags = {"noneEnabled": False, "addEnabled": True, "removeEnabled": True,
                       "renameEnabled": False, "showHidden": False}

    def _flag(name):
        return QtCore.Property(bool, lambda self: self._flags[name],
                               lambda self, value: self._flags.__setitem__(name, bool(value)))

    noneEnabled = _flag("noneEnabled")
    addEnabled = _flag("addEnabled")
    removeEnabled = _flag("removeEnabled")
    renameEnabled = _flag("renameEnabled")
    showHidden = _flag("showHidden")
    del _flag

    def _get_node_types(self):
        return list(self._nodeTypes)

    def _set_node_types(self, types_):
        self._nodeTypes = list(types_)

    nodeTypes = QtCore.Property("QStringList", _get_node_types, _set_node_types)

    def _get_current_id(self):
        return self._current.GetID() if self._current is not None else ""

    currentNodeID = QtCore.Property(str, _get_current_id)

    def accepts(self, node):
        if node is None or not any(node.IsA(t) for t in self._nodeTypes):
            return False
        return self._flags["showHidden"] or not node.GetHideFromEditors()

    def nodes(self):
        if self._scene is None:
            return []
        found = []
        for i in range(self._scene.GetNumberOfNodes()):
            node = self._scene.GetNthNode(i)
            if self.accepts(node):
                found.append(node)
        return found

    def nodeCount(self):
        return len(self.nodes())

    def setMRMLScene(self, scene):
        for tag in self._tags:
            self._scene.RemoveObserver(tag)
        self._tags = []
        self._scene = scene
        if scene is not None:
            self._tags = [scene.AddObserver(scene.NodeAddedEvent, self._onNodeAdded),
                          scene.AddObserver(scene.NodeRemovedEvent, self._onNodeRemoved)]
        nodes = self.nodes()
        self._select(self._current if self._current in nodes else (None if self._flags["noneEnabled"] or not nodes else nodes[0]))

    def mrmlScene(self):
        return self._scene

    def currentNode(self):
        return self._current

    def setCurrentNode(self, node):
        if node is not None and not self.accepts(node):
            raise ValueError(f"{self.name}: {node.GetClassName()} is not one of {self._nodeTypes}")
        self._select(node)

    def setCurrentNodeID(self, node_id):
        self.setCurrentNode(self._scene.GetNodeByID(node_id) if node_id else None)

    def _select(self, node):
        if node is self._current:
            return
        self._current = node
        self.currentNodeChanged.emit(node)
        self.currentNodeIDChanged.emit(node.GetID() if node is not None else "")

    # vtk calls these with (caller, event); the node comes as call data in C++, which
    # Python observers only see with a CallDataType; read the scene instead.
    def _onNodeAdded(self, scene, _event):
        nodes = self.nodes()
        if self._current is None and not self._flags["noneEnabled"] and nodes:
            self._select(nodes[0])

    def _onNodeRemoved(self, scene, _event):
        nodes = self.nodes()
        if self._current is not None and self._current not in nodes:
            self._select(None if self._flags["noneEnabled"] or not nodes else nodes[0])


CUSTOM_WIDGETS = {
    "qMRMLWidget": qMRMLWidget,
    "ctkCollapsibleButton": ctkCollapsibleButton,
    "qMRMLNodeComboBox": qMRMLNodeComboBox,
}

# ---- the application ----------------------------------------------------------------------


class ModuleManager(pythonqt_class(QtCore.QObject)):
    moduleAboutToBeUnloaded = QtCore.Signal(str)
    pythonqt_signals = {"moduleAboutToBeUnloaded(QString)": "moduleAboutToBeUnloaded"}


class LayoutManager:
    """qSlicerLayoutManager's model side: the layout is the scene's layout node's view
    arrangement, and the layout logic creates the view nodes of the current layout."""

    def __init__(self, layout_logic):
        self._logic = layout_logic

    def layoutLogic(self):
        return self._logic

    def setLayout(self, layout_id):
        self._logic.GetLayoutNode().SetViewArrangement(layout_id)

    @property
    def layout(self):
        return self._logic.GetLayoutNode().GetViewArrangement()

    def viewClasses(self):
        """View node classes of the current layout ('vtkMRMLTableViewNode', ...)."""
        description = self._logic.GetLayoutNode().GetCurrentLayoutDescription() or ""
        return set(re.findall(r'class="(vtkMRML\w+)"', description))


class IOManager:
    """The readers Slicer's 'ModelFile' and 'MarkupsFile' types use: the models and
    markups logics (LPS files become RAS nodes, as in Slicer)."""

    def __init__(self, application):
        self._app = application

    def fileType(self, filename):
        return "MarkupsFile" if str(filename).endswith((".mrk.json", ".fcsv")) else "ModelFile"

    def loadNodes(self, filetype, properties, loaded, messages=None):
        scene = self._app.scene
        path = properties["fileName"]
        if filetype == "ModelFile":
            node = self._app.modules.models.logic().AddModel(path)
        elif filetype == "MarkupsFile":
            node_id = self._app.modules.markups.logic().LoadMarkups(path)
            node = scene.GetNodeByID(node_id) if node_id else None
        else:
            raise ValueError(f"the harness reads ModelFile and MarkupsFile, not {filetype}")
        if node is None:
            return False
        loaded.AddItem(node)
        return True


class LoadableModule:
    """qSlicerAbstractModule as scripted modules see it: the `parent` of ScriptedLoadableModule."""

    def __init__(self, name, path=None, logic=None):
        self.name = name
        self.path = str(path) if path else ""
        self._logic = logic
        self.title = ""
        self.categories = []
        self.dependencies = []
        self.contributors = []
        self.helpText = ""
        self.acknowledgementText = ""
        self.icon = None
        self.widget = None  # the module panel (WidgetRepresentation)

    def logic(self):
        return self._logic

    def widgetRepresentation(self):
        return self.widget


class WidgetRepresentation(qMRMLWidget):
    """qSlicerScriptedLoadableModuleWidget: the module panel; reload() makes a new Python
    widget from the reloaded module script (as slicer.util.reloadScriptedModule expects)."""

    def __init__(self, module):
        super().__init__()
        self.setLayout(pythonqt_class(QtWidgets.QVBoxLayout)())
        self.module = module
        self.pythonWidget = None

    def self(self):
        return self.pythonWidget

    def reload(self):
        make_module_widget(self.module, self)


class Application:
    """slicer.app: what scripted modules ask of qSlicerApplication."""

    def __init__(self, qapp, scene, temporary_path):
        self.qapp = qapp
        self.scene = scene
        self.temporaryPath = temporary_path
        self.applicationName = "Slicer"
        self.process_events_calls = 0
        self._app_logic = slicer.vtkSlicerApplicationLogic()
        self._app_logic.SetMRMLScene(scene)
        if scene.GetFirstNodeByClass("vtkMRMLLayoutNode") is None:
            layout_node = slicer.vtkMRMLLayoutNode()
            layout_node.SetSingletonTag("vtkMRMLLayoutNode")
            scene.AddNode(layout_node)
        self._layout_logic = slicer.vtkMRMLLayoutLogic()
        self._layout_logic.SetMRMLScene(scene)
        self._layout_logic.GetLayoutNode().SetViewArrangement(slicer.vtkMRMLLayoutNode.SlicerLayoutFourUpView)
        self._layout_manager = LayoutManager(self._layout_logic)
        self._module_manager = ModuleManager()
        self._io = IOManager(self)
        self.modules = types.SimpleNamespace()

    def processEvents(self, flags=None):
        self.process_events_calls += 1
        if flags is None:
            self.qapp.processEvents()
        else:
            self.qapp.processEvents(flags)

    def applicationLogic(self):
        return self._app_logic

    def layoutManager(self):
        return self._layout_manager

    def moduleManager(self):
        return self._module_manager

    def coreIOManager(self):
        return self._io

    ioManager = coreIOManager

    def startupEnvironment(self):
        return QtCore.QProcessEnvironment.systemEnvironment()

    def testingEnabled(self):
        return True

    def topLevelWidgets(self):
        return self.qapp.topLevelWidgets()

    def userSettings(self):
        return QtCore.QSettings()

    settings = userSettings


def _module_logic(cls, scene, app_logic=None):
    logic = cls()
    if app_logic is not None and hasattr(logic, "SetMRMLApplicationLogic"):
        logic.SetMRMLApplicationLogic(app_logic)
    logic.SetMRMLScene(scene)
    return logic


def install(temporary_path=None):
    """Set up `qt`, `ctk`, `slicer.app`, `slicer.mrmlScene`, `slicer.modules` and
    `slicer.ScriptedLoadableModule`; returns the Application. Once per process (one
    QApplication); later calls return the same application."""
    if getattr(slicer, "app", None) is not None and isinstance(slicer.app, Application):
        return slicer.app
    QtCore.QCoreApplication.setOrganizationName("baffle-slicer-harness")
    qapp = QtWidgets.QApplication.instance() or QtWidgets.QApplication(["slicer-harness"])
    sys.modules["qt"] = make_qt_module()
    ctk = types.ModuleType("ctk")
    ctk.ctkCollapsibleButton = ctkCollapsibleButton
    sys.modules["ctk"] = ctk
    slicer.qMRMLWidget = qMRMLWidget
    slicer.qMRMLNodeComboBox = qMRMLNodeComboBox

    scene = slicer.vtkMRMLScene()
    app = Application(qapp, scene, temporary_path or tempfile.mkdtemp(prefix="slicer-harness-"))
    slicer.app = app
    slicer.mrmlScene = scene
    slicer.modules = app.modules
    app_logic = app.applicationLogic()
    for name, cls in (("plots", slicer.vtkSlicerPlotsLogic), ("models", slicer.vtkSlicerModelsLogic),
                      ("markups", slicer.vtkSlicerMarkupsLogic), ("tables", slicer.vtkSlicerTablesLogic),
                      ("segmentations", slicer.vtkSlicerSegmentationsModuleLogic)):
        setattr(app.modules, name, LoadableModule(name.capitalize(), logic=_module_logic(cls, scene, app_logic)))

    spec = importlib.util.spec_from_file_location("slicer.ScriptedLoadableModule", HERE / "scripted_loadable_module.py")
    base = importlib.util.module_from_spec(spec)
    sys.modules["slicer.ScriptedLoadableModule"] = base
    spec.loader.exec_module(base)
    slicer.ScriptedLoadableModule = base
    return app


def load_scripted_module(path):
    """Load a scripted module as Slicer does: its folder on sys.path, the script imported
    under the module's name, the module class instantiated with its LoadableModule."""
    path = Path(path).resolve()
    name = path.stem
    if str(path.parent) not in sys.path:
        sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location(name, path)
    script = importlib.util.module_from_spec(spec)
    sys.modules[name] = script
    spec.loader.exec_module(script)
    module = LoadableModule(name, path=path)
    module.instance = getattr(script, name)(module)
    setattr(slicer.modules, name.lower(), module)
    return module


def make_module_widget(module, representation=None):
    """The module panel and its Python widget, set up (Slicer's widget representation
    does this on first show; reload does it again)."""
    script = sys.modules[module.name]
    representation = representation or WidgetRepresentation(module)
    module.widget = representation
    widget = getattr(script, module.name + "Widget")(representation)
    representation.pythonWidget = widget
    widget.setup()
    representation.show()  # the panel of the selected module is on screen
    setattr(slicer.modules, module.name + "Widget", widget)
    return widget


def unload_module(module):
    """What the module manager does before unloading a module (application exit)."""
    slicer.app.moduleManager().moduleAboutToBeUnloaded.emit(module.name)


def process_events_for(seconds, until=None):
    """Run the event loop (timers fire) for up to `seconds`, or until until() is true."""
    import time

    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        QtWidgets.QApplication.processEvents(QtCore.QEventLoop.AllEvents, 50)
        if until is not None and until():
            return True
        time.sleep(0.01)
    return until() if until is not None else True

