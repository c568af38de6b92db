"""The parts of the module that only run inside the Slicer application, checked here:
the scripted module compiles, every widget it uses is in the .ui file, the CMake lists
name every Python file, and the icon is a real 128x128 drawing."""

import py_compile
import re
import struct
import xml.etree.ElementTree as ElementTree
import zlib

from conftest import MODULE_DIR


def test_module_script_compiles(tmp_path):
    py_compile.compile(str(MODULE_DIR / "BaffleDesigner.py"), cfile=str(tmp_path / "m.pyc"), doraise=True)


def test_widget_names_mirror_the_ui_file():
    ui = ElementTree.parse(MODULE_DIR / "Resources" / "UI" / "BaffleDesigner.ui")
    names = {w.get("name") for w in ui.iter("widget")}
    used = set(re.findall(r"self\.ui\.([A-Za-z_][A-Za-z0-9_]*)", (MODULE_DIR / "BaffleDesigner.py").read_text()))
    assert len(used) >= 15
    assert used <= names, f"used in BaffleDesigner.py but missing from the .ui: {sorted(used - names)}"
    combo = next(w for w in ui.iter("widget") if w.get("name") == "targetModeComboBox")
    assert len(combo.findall("item")) == 4  # = TARGET_MODES


def test_cmake_lists_every_module_file():
    cmake = (MODULE_DIR / "CMakeLists.txt").read_text()
    assert "slicerMacroBuildScriptedModule" in cmake and "WITH_GENERIC_TESTS" in cmake
    assert "slicer_add_python_unittest" in cmake and "baffle_designer_add_native(" in cmake
    files = (MODULE_DIR / "CMake" / "BaffleDesignerFiles.cmake").read_text()
    for path in sorted((MODULE_DIR / "BaffleDesignerLib").glob("*.py")):
        assert "BaffleDesignerLib/" + path.name in files, path.name
    extension = (MODULE_DIR.parent / "CMakeLists.txt").read_text()
    assert "add_subdirectory(BaffleDesigner)" in extension and 'EXTENSION_CATEGORY "Cardiac"' in extension
    assert 'EXTENSION_DEPENDS "SlicerHeart"' in extension


def test_icon_is_a_128_pixel_drawing():
    data = (MODULE_DIR / "Resources" / "Icons" / "BaffleDesigner.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height, depth, color_type = struct.unpack(">IIBB", data[16:26])
    assert (width, height, depth, color_type) == (128, 128, 8, 6)  # RGBA
    chunks, offset = [], 8
    while offset < len(data):
        length, kind = struct.unpack(">I4s", data[offset:offset + 8])
        chunks.append((kind, data[offset + 8:offset + 8 + length]))
        offset += 12 + length
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    assert len(raw) == 128 * (1 + 128 * 4)
    # Filtered bytes, but a drawing (not a flat placeholder) still has many distinct values.
    assert len(set(raw)) > 50


def test_no_case_writer_or_verdict_of_its_own():
    """The CFD case and the verdict are the library's (baffle.write_case, baffle.plan, the
    summary's and report's verdict): the module writes no JSON, holds no threshold and
    compares no dp with a number."""
    sources = {path.name: path.read_text() for path in [MODULE_DIR / "BaffleDesigner.py", *sorted((MODULE_DIR / "BaffleDesignerLib").glob("*.py"))]}
    for name, text in sources.items():
        code = "\n".join(line.split("#")[0] for line in text.splitlines())
        assert "json.dump" not in code, f"{name} writes JSON"
        assert not re.search(r"dp\w*\s*[<>]=?\s*[\d(]", code), f"{name} judges a dp"
        assert not re.search(r"threshold\w*\s*=\s*\d", code, re.IGNORECASE), f"{name} holds a threshold"
        assert "10 mmHg" not in text, f"{name} names a threshold the library owns"
