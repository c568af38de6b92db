"""Roache's grid convergence index with the observed order (Celik et al. 2008,
"Procedure for Estimation and Reporting of Uncertainty Due to Discretization in CFD
Applications", J. Fluids Eng. 130: 078001), for three meshes.

h is a representative cell size, h = (V / N)^(1/3) for N tetrahedra filling V; level 1
is the finest. The refinement ratios need not be equal: the observed order p solves
p = |ln|e32/e21| + q(p)| / ln r21, q(p) = ln((r21^p - s) / (r32^p - s)), s = sign(e32/e21),
by fixed-point iteration. Oscillatory convergence (s < 0) is reported as such.
"""
import math

SAFETY_FACTOR = 1.25
# Roache's conservative choice when the observed order cannot be trusted: the scheme's
# formal order (P1-P1 stabilized elements: 2 for velocity) with safety factor 3.
FORMAL_ORDER = 2.0
CONSERVATIVE_SAFETY_FACTOR = 3.0
# An observed order outside this range says the levels are not in the asymptotic range.
CREDIBLE_ORDER = (0.5, 3.0)


def representative_h(volume_mm3, cells):
    return (volume_mm3 / cells) ** (1.0 / 3.0)


def observed_order(h, f, iterations=200, tol=1e-10):
    """Observed order of accuracy from three (h, f) levels, finest first."""
    (h1, h2, h3), (f1, f2, f3) = h, f
    if not h1 < h2 < h3:
        raise ValueError(f"mesh sizes must grow from level 1 to 3, got {h}")
    e21, e32 = f2 - f1, f3 - f2
    if e21 == 0 or e32 == 0:
        raise ValueError(f"two levels give the same value ({f}): the order is undefined")
    r21, r32 = h2 / h1, h3 / h2
    s = math.copysign(1.0, e32 / e21)
    p = abs(math.log(abs(e32 / e21))) / math.log(r21)
    for _ in range(iterations):
        q = math.log((r21 ** p - s) / (r32 ** p - s))
        p_new = abs(math.log(abs(e32 / e21)) + q) / math.log(r21)
        if abs(p_new - p) < tol:
            return p_new
        p = p_new
    return p


def gci(h, f):
    """Observed order, extrapolated value and the fine-grid GCI (a fraction of f1)."""
    (h1, h2, _), (f1, f2, f3) = h, f
    p = observed_order(h, f)
    r21 = h2 / h1
    extrapolated = (r21 ** p * f1 - f2) / (r21 ** p - 1.0)
    e_a21 = abs((f1 - f2) / f1)
    oscillatory = (f3 - f2) * (f2 - f1) < 0
    asymptotic = CREDIBLE_ORDER[0] <= p <= CREDIBLE_ORDER[1] and not oscillatory
    gci_fine = SAFETY_FACTOR * e_a21 / (r21 ** p - 1.0)
    conservative = CONSERVATIVE_SAFETY_FACTOR * e_a21 / (r21 ** FORMAL_ORDER - 1.0)
    return {
        "observed_order": p,
        "extrapolated": extrapolated,
        "relative_change_21": e_a21,
        "gci_fine": gci_fine,
        "oscillatory": oscillatory,
        "asymptotic": asymptotic,
        # The band to report: the GCI when the order is credible, else the conservative one.
        "gci_reported": gci_fine if asymptotic else conservative,
        "band_abs": abs(f1) * (gci_fine if asymptotic else conservative),
    }
