//! Closed polygons in a plane's (u, v) coordinates (mm): the cap outlines (ear clipping,
//! the planar caps) and the VSD footprint of the extension.

/// Twice the signed area of (a, b, c): positive when they run counter-clockwise.
pub(crate) fn orient(a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> f64 {
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

/// Even-odd test of `p` against the closed polygon `poly`.
pub(crate) fn inside_polygon(poly: &[(f64, f64)], p: (f64, f64)) -> bool {
    let mut inside = false;
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        if (a.1 > p.1) != (b.1 > p.1) && p.0 < a.0 + (p.1 - a.1) / (b.1 - a.1) * (b.0 - a.0) {
            inside = !inside;
        }
    }
    inside
}

/// Distance (mm) from `p` to the closed polygon `poly`'s edges.
pub(crate) fn distance_to_polygon_mm(poly: &[(f64, f64)], p: (f64, f64)) -> f64 {
    let segment = |a: (f64, f64), b: (f64, f64)| {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let length2 = dx * dx + dy * dy;
        let t = if length2 > 0.0 { (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / length2).clamp(0.0, 1.0) } else { 0.0 };
        (p.0 - a.0 - t * dx).hypot(p.1 - a.1 - t * dy)
    };
    (0..poly.len()).map(|i| segment(poly[i], poly[(i + 1) % poly.len()])).fold(f64::INFINITY, f64::min)
}
