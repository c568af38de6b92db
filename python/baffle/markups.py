"""Suture points from 3D Slicer markups files (.mrk.json), in pure Python."""

import json
from pathlib import Path

import numpy as np

_POINT_TYPES = ("ClosedCurve", "Curve", "Fiducial")


def read_markups(path, frame: str = "LPS") -> np.ndarray:
    """Control points (n, 3) in mm of the first closed curve, curve or fiducial list
    with defined points, converted into `frame` ("LPS", as Slicer writes models, or
    "RAS"). Points whose positionStatus is "undefined" are skipped."""
    frame = frame.upper()
    if frame not in ("LPS", "RAS"):
        raise ValueError(f"frame must be LPS or RAS, not {frame!r}")
    document = json.loads(Path(path).read_text(encoding="utf-8"))
    for markup in document.get("markups", []):
        if markup.get("type") not in _POINT_TYPES:
            continue
        points = [
            cp["position"] for cp in markup.get("controlPoints", []) if cp.get("positionStatus", "defined") != "undefined"
        ]
        if not points:
            continue
        xyz = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        stored = str(markup.get("coordinateSystem", "LPS")).upper()
        if stored != frame:  # LPS <-> RAS negates x and y
            xyz = xyz * np.array([-1.0, -1.0, 1.0])
        return xyz
    raise ValueError(f"{path}: no curve or fiducial markup with defined control points")
