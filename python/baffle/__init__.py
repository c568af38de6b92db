"""Area-constrained DORV baffle design (after Martinez et al.), over the C ABI.

    import baffle
    surface = baffle.read_surface("capped_ventricle.vtp")        # needs vtk
    points = baffle.read_points("suture_points.mrk.json")        # .mrk.json, .fcsv, .csv; LPS
    result = baffle.design(surface.points, surface.triangles, surface.labels, points, bsa_m2=0.37)
    result.domain.points, result.report["sections"]

    plan = baffle.plan("out/plan", phantom=True, sbp_mmhg=107, dbp_mmhg=78, mode="quick")
    plan.verdict, plan.dp_mmhg, plan.dp_threshold_mmhg, plan.reasons   # the library's verdict

    report = baffle.read_report("out/plan")                      # a `baffle plan` folder
    report.verdict, report.reason, report.dp_peak_mmhg           # "passes" / "fails" / "inconclusive"
    fields = baffle.read_fields("out/plan/simulate-nominal/peak.vtu")   # mm, m/s, mmHg; needs vtk

    t = baffle.template(result.domain, points, patient_label="p2")   # the patch template
    t.save("template.pdf"); t.report["flattening"]["area_distortion_max"]; t.flat.points

With the `vtk` module importable, `baffle.vtk_adapters` converts vtkPolyData.
"""

from ._lib import ABI_VERSION, BaffleError, Cancelled, version
from .design import DesignResult, Mesh, design, peak_flow_ml_s, phantom
from .markups import read_markups
from .plan import PlanResult, plan, write_case
from .results import PlanReport, read_fields, read_points, read_report, read_surface
from .template import Template, template

__all__ = [
    "ABI_VERSION",
    "BaffleError",
    "Cancelled",
    "DesignResult",
    "Mesh",
    "PlanReport",
    "PlanResult",
    "design",
    "peak_flow_ml_s",
    "phantom",
    "plan",
    "read_fields",
    "read_markups",
    "read_points",
    "read_report",
    "read_surface",
    "template",
    "Template",
    "version",
    "write_case",
]
__version__ = "0.1.0"
