"""What the module needs outside Slicer and where it finds it: the `baffle` Python package
(in Slicer's Python), the `baffle` command line program (prepare, volume mesh, simulate)
and, for the module's own tests, the patient data. The first-run check turns what is
missing into one message that says how to get it. No Qt, no MRML."""

import importlib
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Dict, List, Optional, Tuple

from BaffleDesignerLib import process

# The subcommands of the `baffle` program the module runs, and what each is for.
SUBCOMMANDS = {
    "prepare": "Segmentation input (baffle prepare)",
    "mesh": "Volume mesh (baffle mesh)",
    "simulate": "Simulate (baffle simulate)",
}


# The scripted module's folder: the extension's package installs the `baffle` package
# (with libbaffle and the program in its bin/) beside BaffleDesigner.py, where Slicer's
# Python finds it (the scripted modules' folder is on sys.path).
MODULE_DIR = Path(__file__).resolve().parents[1]


def packaged_package_dir(module_dir: Path = MODULE_DIR) -> Optional[Path]:
    """The `baffle` package the extension installed beside the module, or None (a
    developer build or a source tree, where it comes from pip or PYTHONPATH)."""
    candidate = module_dir / "baffle"
    return candidate if (candidate / "__init__.py").is_file() else None


def executable_name(os_name: str = os.name) -> str:
    return "baffle.exe" if os_name == "nt" else "baffle"


def packaged_executable(module_dir: Path = MODULE_DIR) -> Optional[Path]:
    """The `baffle` program the extension installed (baffle/bin/), or None."""
    package = packaged_package_dir(module_dir)
    candidate = package / "bin" / executable_name() if package else None
    return candidate if candidate is not None and candidate.is_file() else None


def source_python_package() -> Optional[Path]:
    """The repository's python/ folder when the module runs from a source tree
    (slicer_module/BaffleDesigner/BaffleDesignerLib -> ../../../python), else None."""
    candidate = Path(__file__).resolve().parents[3] / "python"
    return candidate if (candidate / "pyproject.toml").exists() else None


def install_hint() -> str:
    """How to put the `baffle` package into Slicer's Python (slicer_module/README.md)."""
    source = source_python_package()
    where = repr(str(source)) if source else "'/path/to/baffle-repository/python'"
    return (
        "Install it into Slicer's Python: in the Python console (View > Python Console) run "
        "import os; os.environ['BAFFLE_LIBRARY'] = '/path/to/libbaffle.so' (built by "
        "cargo build --release -p baffle-capi; without it pip runs cargo), then "
        f"slicer.util.pip_install({where}), and restart Slicer."
    )


def package_problem() -> str:
    """'' when `import baffle` works in this Python, else what is wrong and how to fix it."""
    try:
        importlib.import_module("baffle")
        importlib.import_module("baffle.vtk_adapters")
    except ImportError as error:
        return f"The baffle Python package cannot be imported ({error}). {install_hint()}"
    return ""


def python_interpreter(env: Optional[dict] = None, executable: Optional[str] = None, os_name: str = os.name) -> str:
    """The Python that `baffle mesh` runs the gmsh wheel with (it reads $BAFFLE_PYTHON),
    found the way Slicer runs Python: $BAFFLE_PYTHON; else Slicer's PythonSlicer (beside
    this interpreter, or on PATH), which is Slicer's own Python with its packages, so
    slicer.util.pip_install("gmsh") is enough; else this interpreter when it is a plain
    Python (not the Slicer application binary); else python3 (python on Windows, where
    python3 is the Store's stub)."""
    env = dict(os.environ if env is None else env)
    if env.get("BAFFLE_PYTHON"):
        return env["BAFFLE_PYTHON"]
    executable = sys.executable if executable is None else executable
    suffix = ".exe" if os_name == "nt" else ""
    if executable:
        beside = Path(executable).parent / f"PythonSlicer{suffix}"
        if beside.is_file():
            return str(beside)
    on_path = shutil.which("PythonSlicer", path=env.get("PATH", os.defpath))
    if on_path:
        return on_path
    if executable and Path(executable).name.lower().startswith("python"):
        return executable
    return "python" if os_name == "nt" else "python3"


def child_environment(base: Optional[dict] = None) -> dict:
    """`base` (default: this process's environment) with BAFFLE_PYTHON set to
    python_interpreter(), so that `baffle mesh` and the gmsh check use the same Python."""
    env = dict(os.environ if base is None else base)
    env["BAFFLE_PYTHON"] = python_interpreter(env)
    return env


def find_baffle_executable() -> Optional[str]:
    """$BAFFLE_EXECUTABLE, else the packaged extension's program (baffle/bin beside the
    module), else `baffle` on PATH, else a development tree's cargo build
    (slicer_module/BaffleDesigner/BaffleDesignerLib -> ../../../target/release/baffle)."""
    given = os.environ.get("BAFFLE_EXECUTABLE")
    if given:
        return given
    packaged = packaged_executable()
    if packaged is not None:
        return str(packaged)
    on_path = shutil.which("baffle")
    if on_path:
        return on_path
    built = Path(__file__).resolve().parents[3] / "target" / "release" / executable_name()
    return str(built) if built.exists() else None


def gmsh_availability(env: Optional[dict] = None, timeout: float = 20.0) -> Tuple[bool, str]:
    """Whether `baffle mesh`, started with `env`, finds a working gmsh, looked up in its
    order (baffle-mesh, gmsh.rs): $BAFFLE_GMSH, else `gmsh` on PATH, else the gmsh wheel
    in python_interpreter(env) ($BAFFLE_PYTHON, which baffle mesh reads too). (True, "")
    or (False, what to do)."""
    env = dict(os.environ if env is None else env)
    if env.get("BAFFLE_GMSH"):
        candidates = [[env["BAFFLE_GMSH"], "--version"]]
    else:
        on_path = shutil.which("gmsh", path=env.get("PATH", os.defpath))
        candidates = ([[on_path, "--version"]] if on_path else []) + [[python_interpreter(env), "-c", "import gmsh"]]
    tried = []
    for command in candidates:
        try:
            done = process.run_captured(command, env=env, timeout=timeout)
        except (OSError, subprocess.TimeoutExpired) as error:
            tried.append(f"{command[0]}: {error}")
            continue
        if done.returncode == 0:
            return True, ""
        detail = (done.stderr or done.stdout).strip().splitlines()
        tried.append(f"{' '.join(command)}: {detail[-1] if detail else f'exit code {done.returncode}'}")
    return False, (
        "gmsh was not found (install it with `bash scripts/install_gmsh.sh` or `python3 -m pip install gmsh`, "
        "or set BAFFLE_GMSH before starting Slicer); tried " + "; ".join(tried)
    )


def first_run_problems(executable: Optional[str], availability: Dict[str, Tuple[bool, str]]) -> List[str]:
    """Everything missing, one line each: the package (no design at all), the program,
    its subcommands and gmsh (`availability`: subcommand or "gmsh" -> (available, why
    not), from process.subcommand_availability and gmsh_availability)."""
    problems = []
    package = package_problem()
    if package:
        problems.append(package)
    if not executable:
        problems.append(
            "The baffle command line program was not found (prepare, volume mesh, simulate): "
            "build it (cargo build --release -p baffle-cli) and put it on PATH or set BAFFLE_EXECUTABLE "
            "before starting Slicer."
        )
        return problems
    for subcommand, purpose in SUBCOMMANDS.items():
        available, reason = availability.get(subcommand, (False, "not checked"))
        if not available:
            problems.append(f"{purpose} is unavailable: {reason}")
    available, reason = availability.get("gmsh", (True, ""))
    if not available:
        problems.append(f"Volume mesh and Simulate need gmsh: {reason}")
    return problems


def patient_data_dir(module_file: str) -> Tuple[Optional[Path], List[Path]]:
    """(folder holding p1/p2/p3 or None, the folders tried). $BAFFLE_DATA_DIR first; then
    shared/data beside every ancestor of the module file, the real one (a build tree's
    copy or symlink) and the source tree's, so that a build tree next to the repository
    finds the data too."""
    tried = []
    given = os.environ.get("BAFFLE_DATA_DIR")
    if given:
        tried.append(Path(given))
    for start in dict.fromkeys((Path(module_file).absolute(), Path(module_file).resolve())):
        for ancestor in start.parents:
            tried.append(ancestor / "shared" / "data")
    tried = list(dict.fromkeys(tried))
    for folder in tried:
        if (folder / "p2").is_dir():
            return folder, tried
    return None, tried
