"""Builds the C ABI (cargo build --release -p baffle-capi) and ships the shared
library inside the package, so `pip install ./python` gives a working `import baffle`.

The cargo target directory is $CARGO_TARGET_DIR or the repository's ./target (shared
with `cargo test` and CMake, so nothing is compiled twice). Set BAFFLE_LIBRARY to an
existing libbaffle to skip the cargo build (it is then copied instead). pip hides a build's
output unless -v, so cargo's progress is written to the user's terminal (/dev/tty) when
there is one; BAFFLE_BUILD_QUIET=1 keeps it quiet."""

import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.dist import Distribution

HERE = Path(__file__).resolve().parent
REPO = HERE.parent


def library_name() -> str:
    """baffle/_library_file.py's, read from the file: importing the package would load the
    library this build is about to make."""
    spec = importlib.util.spec_from_file_location("baffle_library_file", HERE / "baffle" / "_library_file.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.library_name()


def cargo_built_library() -> Path:
    if not (REPO / "Cargo.toml").exists():
        sys.exit(f"baffle: no Cargo workspace at {REPO}; build from the repository or set BAFFLE_LIBRARY")
    target_dir = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    command = ["cargo", "build", "--release", "-p", "baffle-capi", "--target-dir", str(target_dir)]
    print("baffle:", " ".join(command), flush=True)
    terminal = user_terminal()
    if terminal is not None:
        terminal.write(f"baffle: building the native library (a first build takes minutes): {' '.join(command)}\n")
        terminal.flush()
    try:
        # Cargo's progress goes to the terminal: pip shows a build's own output only with -v.
        subprocess.run(command, cwd=REPO, check=True, stdout=terminal, stderr=terminal)
    finally:
        if terminal is not None:
            terminal.close()
    return target_dir / "release" / library_name()


def user_terminal():
    """The user's terminal, which pip does not capture, or None (CI, no terminal)."""
    if os.environ.get("BAFFLE_BUILD_QUIET"):
        return None
    try:
        return open("/dev/tty", "w")
    except OSError:
        return None


class BuildWithLibrary(build_py):
    """build_py that also puts the shared library next to the Python modules."""

    def run(self):
        super().run()
        given = os.environ.get("BAFFLE_LIBRARY")
        library = Path(given) if given else cargo_built_library()
        destination = Path(self.build_lib) / "baffle" / library_name()
        destination.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(library, destination)


try:  # setuptools >= 70.1 has its own; before that it is the wheel package's
    from setuptools.command.bdist_wheel import bdist_wheel
except ImportError:
    from wheel.bdist_wheel import bdist_wheel


class BinaryDistribution(Distribution):
    """The wheel holds a native library, so it goes to the platform's site-packages."""

    def has_ext_modules(self):
        return True


class PlatformWheel(bdist_wheel):
    """Tagged py3-none-<platform>: the library is platform code, but it is loaded with
    ctypes, so any CPython 3 takes the wheel (has_ext_modules alone tags it cp3X-cp3X)."""

    def get_tag(self):
        _, _, platform = super().get_tag()
        return "py3", "none", platform


# Build outside the source tree (pip builds in place): the repository ignores /target.
BUILD_BASE = REPO / "target" / "python-build" if (REPO / "Cargo.toml").exists() else HERE / "build"

setup(
    cmdclass={"build_py": BuildWithLibrary, "bdist_wheel": PlatformWheel},
    distclass=BinaryDistribution,
    options={"build": {"build_base": str(BUILD_BASE)}, "bdist_wheel": {"bdist_dir": str(BUILD_BASE / "bdist")}},
)
