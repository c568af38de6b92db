"""Area-constrained DORV baffle design (after Martinez et al.), over the C ABI.

    import baffle
    points = baffle.read_markups("suture_points.mrk.json", frame="LPS")
    result = baffle.design(surface_points, triangles, labels, points, bsa_m2=0.37)
    result.domain.points, result.report["sections"]

With the `vtk` module importable, `baffle.vtk_adapters` converts vtkPolyData.
"""

from ._lib import ABI_VERSION, BaffleError, Cancelled, version
from .design import DesignResult, Mesh, design, phantom
from .markups import read_markups

__all__ = [
    "ABI_VERSION",
    "BaffleError",
    "Cancelled",
    "DesignResult",
    "Mesh",
    "design",
    "phantom",
    "read_markups",
    "version",
]
__version__ = "0.1.0"
