"""The shared library's file name on this platform. Its own module, with nothing to import,
because setup.py reads it before the library exists (importing the package loads it)."""

import sys


def library_name() -> str:
    if sys.platform == "win32":
        return "baffle.dll"
    if sys.platform == "darwin":
        return "libbaffle.dylib"
    return "libbaffle.so"
