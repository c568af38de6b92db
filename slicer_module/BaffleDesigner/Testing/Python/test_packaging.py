"""The packaged extension's layout, built without Slicer: CMake/PackageLayout installs the
scripted module's files where slicerMacroBuildScriptedModule puts them and the native part
(BaffleDesignerNative.cmake: cargo's libbaffle and `baffle`, and the Python package)
beside them; then a fresh Python with none of the developer settings (no PYTHONPATH to
./python, no BAFFLE_LIBRARY or BAFFLE_EXECUTABLE) runs the installed module's own checks."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import MODULE_DIR, REPO

SCRIPTED = "lib/Slicer-5.8/qt-scripted-modules"

FROM_THE_PACKAGE = """
import sys, unittest
import slicer_harness as harness
harness.install()
import slicer
module = harness.load_scripted_module(sys.argv[1])
import baffle
from baffle import _lib
from BaffleDesignerLib import environment, process
print("PACKAGE", baffle.__file__)
print("LIBRARY", _lib._library_path())
print("PROGRAM", environment.find_baffle_executable())
print("PACKAGED", environment.packaged_package_dir())
print("PROBLEM", environment.package_problem() or "none")
test = sys.modules["BaffleDesigner"].BaffleDesignerTest("runTest")
test.messageDelay = 0
test.setUp()
test.test_phantom_design_and_drag()
print("SELFTEST phantom passed")
"""


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    cmake = shutil.which("cmake")
    if cmake is None:
        if os.environ.get("CI", "").lower() in ("true", "1"):
            pytest.fail("cmake not found (CI=true: the package layout must be checked)")
        pytest.skip("cmake not found")
    root = tmp_path_factory.mktemp("package")
    build, prefix = root / "build", root / "install"
    source = MODULE_DIR / "CMake" / "PackageLayout"
    target_dir = os.environ.get("CARGO_TARGET_DIR", str(REPO / "target"))
    for command in (
        [cmake, "-S", str(source), "-B", str(build), f"-DBAFFLE_CARGO_TARGET_DIR={target_dir}", f"-DBAFFLE_SCRIPTED_MODULES_DIR={SCRIPTED}"],
        [cmake, "--build", str(build)],
        [cmake, "--install", str(build), "--prefix", str(prefix)],
    ):
        done = subprocess.run(command, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"{' '.join(command)}:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return prefix / SCRIPTED


def test_the_package_holds_the_module_the_library_the_program_and_the_python_package(installed):
    library = {"win32": "baffle.dll", "darwin": "libbaffle.dylib"}.get(sys.platform, "libbaffle.so")
    for relative in ("BaffleDesigner.py", "BaffleDesignerLib/logic.py", "BaffleDesignerLib/process.py",
                     "Resources/UI/BaffleDesigner.ui", "Resources/Icons/BaffleDesigner.png",
                     "baffle/__init__.py", "baffle/_lib.py", "baffle/vtk_adapters.py", f"baffle/{library}"):
        assert (installed / relative).is_file(), relative
    program = installed / "baffle" / "bin" / ("baffle.exe" if os.name == "nt" else "baffle")
    assert program.is_file() and os.access(program, os.X_OK)
    assert not list(installed.rglob("__pycache__"))
    python_files = {p.name for p in (REPO / "python" / "baffle").glob("*.py")}
    assert python_files == {p.name for p in (installed / "baffle").glob("*.py")}


def test_the_installed_module_finds_them_and_its_self_test_designs(installed):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "BAFFLE_LIBRARY", "BAFFLE_EXECUTABLE")}
    env.update(QT_QPA_PLATFORM="offscreen", PYTHONPATH=str(Path(__file__).parent))  # the harness only
    done = subprocess.run([sys.executable, "-c", FROM_THE_PACKAGE, str(installed / "BaffleDesigner.py")],
                          cwd=str(installed), env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    out = dict(line.split(" ", 1) for line in done.stdout.splitlines() if " " in line)
    assert Path(out["PACKAGE"]).parent == installed / "baffle"
    assert Path(out["LIBRARY"]).parent == installed / "baffle"
    assert Path(out["PROGRAM"]).parent == installed / "baffle" / "bin"
    assert Path(out["PACKAGED"]) == installed / "baffle" and out["PROBLEM"] == "none"
    assert out["SELFTEST"] == "phantom passed"


def test_a_packaged_module_without_a_working_package_fails_its_self_test(installed, tmp_path):
    """A package whose library is missing is a broken install, not a developer build: the
    self-test must fail and say where, not skip."""
    broken = tmp_path / "qt-scripted-modules"
    shutil.copytree(installed, broken)
    for library in (broken / "baffle").glob("*baffle.*"):
        if library.suffix in (".so", ".dll", ".dylib"):
            library.unlink()
    code = ("import sys, unittest\nimport slicer_harness as harness\nharness.install()\n"
            "harness.load_scripted_module(sys.argv[1])\n"
            "r = unittest.TextTestRunner().run(unittest.TestSuite([sys.modules['BaffleDesigner'].BaffleDesignerTest('runTest')]))\n"
            "print('SKIPPED', len(r.skipped), 'FAILED', len(r.failures))\n")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "BAFFLE_LIBRARY", "BAFFLE_EXECUTABLE")}
    env.update(QT_QPA_PLATFORM="offscreen", PYTHONPATH=str(Path(__file__).parent))
    done = subprocess.run([sys.executable, "-c", code, str(broken / "BaffleDesigner.py")], cwd=str(broken), env=env,
                          capture_output=True, text=True, timeout=120)
    assert "SKIPPED 0 FAILED 1" in done.stdout, done.stdout + done.stderr[-3000:]
    assert "packaged extension" in done.stderr and str(broken / "baffle") in done.stderr


def test_the_python_wheel_is_tagged_for_any_python_3_on_this_platform(tmp_path):
    """The package loads libbaffle with ctypes: no CPython ABI, so py3-none-<platform>
    (marking it as having extension modules alone gave cp3X-cp3X)."""
    import zipfile

    library = os.environ.get("BAFFLE_LIBRARY") or str(REPO / "target" / "release" / "libbaffle.so")
    env = dict(os.environ, BAFFLE_LIBRARY=library, BAFFLE_BUILD_QUIET="1")
    done = subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
                           "-w", str(tmp_path), str(REPO / "python")], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    (wheel,) = tmp_path.glob("baffle-*.whl")
    name, version, python_tag, abi_tag, platform_tag = wheel.stem.split("-")
    assert (python_tag, abi_tag) == ("py3", "none") and platform_tag != "any", wheel.name
    assert "baffle/" + Path(library).name in zipfile.ZipFile(wheel).namelist()
