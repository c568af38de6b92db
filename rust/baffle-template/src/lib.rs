//! The patch template: the designed baffle flattened to the plane at true scale, as the
//! surgeon cuts it from the patch material (issue 17; SlicerHeart's BafflePlanner does
//! the same for its baffles).
//!
//! Method: least-squares conformal maps (LSCM, Lévy et al. 2002) with two pinned
//! boundary vertices, the boundary free. Why LSCM: the baffle is a gently curved disk
//! that is close to developable, so a conformal map keeps its angles (the shape of the
//! suture line) and its area distortion stays small; the free boundary does not force
//! the seam onto a circle as a boundary-fixed (Tutte, mean-value) map would; and it is
//! one sparse, symmetric positive-definite linear solve, with no iterations to tune as
//! ARAP needs. The two pins sit at the farthest pair of seam vertices, their 3D distance
//! apart. The map is then scaled so that the template's perimeter equals the 3D seam
//! length: a conformal map is free in scale, and the seam length is what the surgeon
//! sews. The remaining error is local: the per-edge length error along the seam, the
//! per-triangle area ratio and the angle error, all reported.

pub mod drawing;
pub mod pdf;
pub mod raster;
pub mod sparse_cg;
pub mod svg;

use crate::sparse_cg::{conjugate_gradient, SparseSym};
use baffle_core::geometry::mesh::{FaceLabels, TriMesh, Vec3};
use nalgebra::Vector2;

pub type Vec2 = Vector2<f64>;

/// How the baffle is flattened (see the module's header for why LSCM is the default).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum FlattenMethod {
    #[default]
    Lscm,
    /// LSCM, then as-rigid-as-possible local/global iterations (Liu et al. 2008).
    LscmArap,
}

impl FlattenMethod {
    pub fn describe(self) -> &'static str {
        match self {
            FlattenMethod::Lscm => "LSCM (least-squares conformal map), two pinned seam vertices, scaled to the seam length",
            FlattenMethod::LscmArap => "LSCM then ARAP (as-rigid-as-possible) iterations, scaled to the seam length",
        }
    }
}

/// The baffle flattened to the plane (mm), with its distortion.
#[derive(Clone, Debug)]
pub struct FlatPatch {
    /// One 2D point per baffle vertex (mm), after scaling to the seam length.
    pub uv_mm: Vec<Vec2>,
    pub triangles: Vec<[u32; 3]>,
    /// The baffle's boundary (the seam) as vertex indices, in loop order.
    pub boundary: Vec<u32>,
    pub report: FlattenReport,
    /// Per triangle: flat area / 3D area (1 = no area change).
    pub area_ratio: Vec<f64>,
    /// Per triangle: largest corner-angle change (degrees).
    pub angle_error_deg: Vec<f64>,
}

/// The numbers a surgeon or a test checks on a template.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FlattenReport {
    pub method: &'static str,
    pub seam_length_3d_mm: f64,
    pub perimeter_mm: f64,
    /// |perimeter - seam length| / seam length after the scaling (round-off only).
    pub perimeter_error: f64,
    /// The uniform scale applied to the LSCM map. The pins sit at their 3D (chord)
    /// distance, shorter than along a curved surface, so it is above 1 on curved baffles.
    pub scale: f64,
    /// |flat seam edge / 3D seam edge - 1|: median and maximum.
    pub seam_edge_error_median: f64,
    pub seam_edge_error_max: f64,
    /// |flat area / 3D area - 1| per triangle: median and maximum.
    pub area_distortion_median: f64,
    pub area_distortion_max: f64,
    /// Largest corner-angle change per triangle (degrees): median and maximum.
    pub angle_distortion_median_deg: f64,
    pub angle_distortion_max_deg: f64,
    pub area_3d_mm2: f64,
    pub area_flat_mm2: f64,
    pub triangles: usize,
    pub cg_iterations: usize,
    pub arap_iterations: usize,
}

/// ARAP stops when an iteration lowers its energy by less than this fraction.
const ARAP_REL_TOL: f64 = 1e-5;
const ARAP_MAX_ITERATIONS: usize = 200;

/// Flatten a disk-topology surface (mm). Errors name what is wrong with the input.
pub fn flatten(mesh: &TriMesh, method: FlattenMethod) -> Result<FlatPatch, String> {
    let boundary = single_boundary(mesh)?;
    let (pin_a, pin_b) = farthest_pair(mesh, &boundary);
    let d_mm = (mesh.points[pin_b as usize] - mesh.points[pin_a as usize]).norm();
    let pins = [(pin_a, Vec2::zeros()), (pin_b, Vec2::new(d_mm, 0.0))];
    let (conformal, cg_iterations) = lscm(mesh, &pins)?;
    let (uv, arap_iterations) = match method {
        FlattenMethod::Lscm => (conformal, 0),
        FlattenMethod::LscmArap => arap(mesh, conformal, pin_a, ARAP_MAX_ITERATIONS, ARAP_REL_TOL)?,
    };
    let seam_3d = loop_length(&boundary, |i| mesh.points[i as usize].into());
    let perimeter_unscaled = loop_length(&boundary, |i| lift(uv[i as usize]));
    if !(perimeter_unscaled > 0.0) {
        return Err("flattening collapsed the boundary to a point".into());
    }
    let scale = seam_3d / perimeter_unscaled;
    let uv_mm: Vec<Vec2> = uv.iter().map(|p| p * scale).collect();
    let perimeter_mm = loop_length(&boundary, |i| lift(uv_mm[i as usize]));
    let area_ratio: Vec<f64> = (0..mesh.triangles.len()).map(|t| flat_area(&uv_mm, mesh.triangles[t]) / mesh.triangle_area_mm2(t)).collect();
    let angle_error_deg: Vec<f64> = mesh.triangles.iter().map(|&tri| angle_error(mesh, &uv_mm, tri)).collect();
    let edge_errors = seam_edge_errors(mesh, &uv_mm, &boundary);
    let area_err: Vec<f64> = area_ratio.iter().map(|r| (r - 1.0).abs()).collect();
    let report = FlattenReport {
        method: method.describe(),
        seam_length_3d_mm: seam_3d,
        perimeter_mm,
        perimeter_error: (perimeter_mm - seam_3d).abs() / seam_3d,
        scale,
        seam_edge_error_median: median(&edge_errors),
        seam_edge_error_max: max(&edge_errors),
        area_distortion_median: median(&area_err),
        area_distortion_max: max(&area_err),
        angle_distortion_median_deg: median(&angle_error_deg),
        angle_distortion_max_deg: max(&angle_error_deg),
        area_3d_mm2: mesh.area_mm2(),
        area_flat_mm2: mesh.triangles.iter().map(|&t| flat_area(&uv_mm, t)).sum(),
        triangles: mesh.triangles.len(),
        cg_iterations,
        arap_iterations,
    };
    if let Some(t) = area_ratio.iter().position(|r| !(*r > 0.0)) {
        return Err(format!("flattening folded triangle {t} (flat area ratio {:.3})", area_ratio[t]));
    }
    Ok(FlatPatch { uv_mm, triangles: mesh.triangles.clone(), boundary, report, area_ratio, angle_error_deg })
}

/// A file format of the printed page; all three draw the same [`drawing::layout`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PageFormat {
    Pdf,
    Svg,
    /// A raster at this many dots per inch, stored in the file.
    Png { dpi: f64 },
}

impl PageFormat {
    /// The format a file name asks for (.pdf, .svg, .png; `dpi` is the PNG's).
    pub fn from_path(path: &std::path::Path, dpi: f64) -> Result<Self, String> {
        match path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).as_deref() {
            Some("pdf") => Ok(PageFormat::Pdf),
            Some("svg") => Ok(PageFormat::Svg),
            Some("png") => Ok(PageFormat::Png { dpi }),
            _ => Err(format!("{}: a template must end in .pdf, .svg or .png", path.display())),
        }
    }

    /// The page's shapes as the file's bytes.
    pub fn render(self, shapes: &[drawing::Shape]) -> Result<Vec<u8>, String> {
        match self {
            PageFormat::Pdf => Ok(pdf::to_pdf(shapes)),
            PageFormat::Svg => Ok(svg::to_svg(shapes).into_bytes()),
            PageFormat::Png { dpi } => raster::to_png(shapes, dpi),
        }
    }
}

/// A finished template: the flattened baffle and the page's shapes.
pub struct Template {
    pub flat: FlatPatch,
    pub shapes: Vec<drawing::Shape>,
    /// Per suture point: distance (mm) from the point to the seam vertex it is drawn at.
    pub suture_offsets_mm: Vec<f64>,
    /// Seam vertices marked as VSD and aortic rims.
    pub vsd_rim_vertices: usize,
    pub aortic_rim_vertices: usize,
    /// The seam's closest approach to each cap (mm, to the cap's nearest vertex).
    pub seam_to_vsd_cap_mm: f64,
    pub seam_to_aortic_cap_mm: f64,
}

/// The seam part beside one cap (see [`RIM_BAND_MM`]), from each seam vertex's distance
/// to this cap and to the other one.
fn rim(name: &'static str, colour: drawing::Rgb, to_this: &[f64], to_other: &[f64]) -> drawing::Rim {
    let closest = min(to_this);
    let boundary_positions = (0..to_this.len()).filter(|&k| to_this[k] <= closest + RIM_BAND_MM && to_this[k] < to_other[k]).collect();
    drawing::Rim { name, colour, boundary_positions }
}

fn min(values: &[f64]) -> f64 {
    values.iter().copied().fold(f64::INFINITY, f64::min)
}

/// A cap's rim on the template: the seam vertices within this much of the seam's
/// closest approach to the cap (and closer to it than to the other cap), in mm. The
/// seam seldom touches a cap, so "touching" would mark nothing on most patients.
pub const RIM_BAND_MM: f64 = 2.0;

/// The template of a designed domain (`ModelFaceID` baffle, VSD and aortic caps): the
/// baffle flattened, the suture points at their nearest seam vertex (numbered by
/// `point_labels`, or 1, 2, ... where a label is empty), the seam next to each cap marked.
pub fn template_from_domain(
    domain: &TriMesh,
    labels: &FaceLabels,
    suture_points_mm: &[Vec3],
    point_labels: &[String],
    text: &drawing::TemplateText,
    method: FlattenMethod,
) -> Result<Template, String> {
    let baffle = domain.with_labels(|l| l == labels.baffle);
    if baffle.triangles.is_empty() {
        return Err(format!("the domain has no baffle triangles (ModelFaceID {})", labels.baffle));
    }
    let flat = flatten(&baffle, method)?;
    let seam: Vec<Vec3> = flat.boundary.iter().map(|&i| baffle.points[i as usize]).collect();
    let mut markers = Vec::new();
    let mut suture_offsets_mm = Vec::new();
    for (k, p) in suture_points_mm.iter().enumerate() {
        let (pos, d) = nearest(&seam, p);
        suture_offsets_mm.push(d);
        let label = point_labels.get(k).filter(|l| !l.is_empty()).cloned().unwrap_or_else(|| (k + 1).to_string());
        markers.push(drawing::Marker { label, uv_mm: flat.uv_mm[flat.boundary[pos] as usize] });
    }
    let distances = |label: i32, name: &str| -> Result<Vec<f64>, String> {
        let cap = domain.with_labels(|l| l == label);
        if cap.triangles.is_empty() {
            return Err(format!("the domain has no {name} cap triangles (ModelFaceID {label})"));
        }
        Ok(seam.iter().map(|p| nearest(&cap.points, p).1).collect())
    };
    let (to_vsd, to_aorta) = (distances(labels.vsd_cap, "VSD")?, distances(labels.aortic_cap, "aortic")?);
    let rims = [rim("VSD", drawing::Rgb(0.0, 0.45, 0.0), &to_vsd, &to_aorta), rim("Ao", drawing::Rgb(0.55, 0.0, 0.55), &to_aorta, &to_vsd)];
    let shapes = drawing::layout(&flat, &markers, &rims, text)?;
    Ok(Template {
        seam_to_vsd_cap_mm: min(&to_vsd),
        seam_to_aortic_cap_mm: min(&to_aorta),
        vsd_rim_vertices: rims[0].boundary_positions.len(),
        aortic_rim_vertices: rims[1].boundary_positions.len(),
        flat,
        shapes,
        suture_offsets_mm,
    })
}

/// Index of the point of `points` nearest to `p`, and its distance (mm).
fn nearest(points: &[Vec3], p: &Vec3) -> (usize, f64) {
    points.iter().enumerate().map(|(k, q)| (k, (q - p).norm())).min_by(|a, b| a.1.total_cmp(&b.1)).unwrap_or((0, f64::INFINITY))
}

fn single_boundary(mesh: &TriMesh) -> Result<Vec<u32>, String> {
    if mesh.triangles.is_empty() {
        return Err("the baffle has no triangles".into());
    }
    let loops = mesh.boundary_loops().map_err(|e| format!("baffle boundary: {e}"))?;
    match loops.len() {
        1 => Ok(loops.into_iter().next().unwrap()),
        n => Err(format!("the baffle must be a disk with one boundary loop (the seam), it has {n}")),
    }
}

/// The two boundary vertices farthest apart: pinning them fixes the similarity freedom
/// of LSCM with the least leverage on the rest.
fn farthest_pair(mesh: &TriMesh, boundary: &[u32]) -> (u32, u32) {
    let mut best = (boundary[0], boundary[boundary.len() / 2], -1.0);
    for (k, &a) in boundary.iter().enumerate() {
        for &b in &boundary[k + 1..] {
            let d = (mesh.points[a as usize] - mesh.points[b as usize]).norm_squared();
            if d > best.2 {
                best = (a, b, d);
            }
        }
    }
    (best.0, best.1)
}

/// The unknowns of a flattening: two per vertex (u, v), except at pinned vertices.
struct Unknowns {
    pinned: Vec<Option<Vec2>>,
    /// Column of (vertex, coordinate), `usize::MAX` when pinned.
    col: Vec<usize>,
    count: usize,
}

impl Unknowns {
    fn new(vertices: usize, pins: &[(u32, Vec2)]) -> Self {
        let mut pinned: Vec<Option<Vec2>> = vec![None; vertices];
        for &(v, p) in pins {
            pinned[v as usize] = Some(p);
        }
        let mut col = vec![usize::MAX; 2 * vertices];
        let mut count = 0;
        for v in (0..vertices).filter(|&v| pinned[v].is_none()) {
            col[2 * v] = count;
            col[2 * v + 1] = count + 1;
            count += 2;
        }
        Unknowns { pinned, col, count }
    }

    fn positions(&self, x: &[f64]) -> Vec<Vec2> {
        (0..self.pinned.len()).map(|v| self.pinned[v].unwrap_or_else(|| Vec2::new(x[self.col[2 * v]], x[self.col[2 * v + 1]]))).collect()
    }

    /// Add the least-squares row (sum of coefficient x variable = target) to the normal
    /// equations: row^T row into `system` (when given), row^T (target - pinned part) into
    /// `rhs`. Variables are 2 * vertex + coordinate.
    fn add_row(&self, row: &[(usize, f64)], target: f64, system: Option<&mut SparseSym>, rhs: &mut [f64]) {
        let known: f64 = row.iter().filter_map(|&(var, a)| self.pinned[var / 2].map(|p| a * p[var % 2])).sum();
        for &(vi, ai) in row.iter().filter(|&&(v, _)| self.col[v] != usize::MAX) {
            rhs[self.col[vi]] += ai * (target - known);
        }
        if let Some(system) = system {
            for &(vi, ai) in row.iter().filter(|&&(v, _)| self.col[v] != usize::MAX) {
                for &(vj, aj) in row.iter().filter(|&&(v, _)| self.col[v] != usize::MAX) {
                    system.add(self.col[vi], self.col[vj], ai * aj);
                }
            }
        }
    }
}

/// Every triangle's barycentric gradients in its own frame, and sqrt(area) as row weight.
fn triangle_frames(mesh: &TriMesh) -> Result<Vec<([Vec2; 3], f64)>, String> {
    (0..mesh.triangles.len())
        .map(|t| {
            let grads = local_gradients(mesh, mesh.triangles[t]).ok_or_else(|| format!("baffle triangle {t} is degenerate (zero area)"))?;
            Ok((grads, mesh.triangle_area_mm2(t).sqrt()))
        })
        .collect()
}

/// LSCM: per triangle, in its own orthonormal frame, the Cauchy-Riemann residuals
/// u_x - v_y and u_y + v_x of the linear map, weighted by the triangle's area; their
/// sum of squares is minimized with the pinned vertices fixed (normal equations, CG).
fn lscm(mesh: &TriMesh, pins: &[(u32, Vec2)]) -> Result<(Vec<Vec2>, usize), String> {
    let unknowns = Unknowns::new(mesh.points.len(), pins);
    let mut system = SparseSym::new(unknowns.count);
    let mut rhs = vec![0.0; unknowns.count];
    for (tri, (grads, w)) in mesh.triangles.iter().zip(triangle_frames(mesh)?) {
        let var = |k: usize, c: usize| 2 * tri[k] as usize + c;
        let r1: Vec<(usize, f64)> = (0..3).flat_map(|k| [(var(k, 0), w * grads[k].x), (var(k, 1), -w * grads[k].y)]).collect();
        let r2: Vec<(usize, f64)> = (0..3).flat_map(|k| [(var(k, 0), w * grads[k].y), (var(k, 1), w * grads[k].x)]).collect();
        unknowns.add_row(&r1, 0.0, Some(&mut system), &mut rhs);
        unknowns.add_row(&r2, 0.0, Some(&mut system), &mut rhs);
    }
    let (x, iterations) = conjugate_gradient(&system.finish(), &rhs, 1e-12, 20 * unknowns.count + 100).map_err(|e| format!("LSCM solve: {e}"))?;
    Ok((unknowns.positions(&x), iterations))
}

/// ARAP refinement (Liu et al. 2008), local/global: each triangle's Jacobian is fitted
/// to its closest rotation (local), then all vertices to those rotations in least
/// squares (global, the same matrix every time), until the energy
/// sum A_t |J_t - R_t|^2 stops falling by more than `rel_tol`.
fn arap(mesh: &TriMesh, start: Vec<Vec2>, pin: u32, max_iterations: usize, rel_tol: f64) -> Result<(Vec<Vec2>, usize), String> {
    let frames = triangle_frames(mesh)?;
    let unknowns = Unknowns::new(mesh.points.len(), &[(pin, start[pin as usize])]);
    let rows = |tri: [u32; 3], grads: &[Vec2; 3], w: f64, a: usize, b: usize| -> [(usize, f64); 3] {
        std::array::from_fn(|k| (2 * tri[k] as usize + a, w * grads[k][b]))
    };
    let mut system = SparseSym::new(unknowns.count);
    let mut scratch = vec![0.0; unknowns.count];
    for (tri, (grads, w)) in mesh.triangles.iter().zip(&frames) {
        for (a, b) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            unknowns.add_row(&rows(*tri, grads, *w, a, b), 0.0, Some(&mut system), &mut scratch);
        }
    }
    let system = system.finish();
    let mut uv = start;
    let mut last_energy = f64::INFINITY;
    for iteration in 1..=max_iterations {
        let mut rhs = vec![0.0; unknowns.count];
        let mut energy = 0.0;
        for (tri, (grads, w)) in mesh.triangles.iter().zip(&frames) {
            let j = jacobian(&uv, *tri, grads);
            let r = closest_rotation(&j);
            energy += w * w * (j - r).norm_squared();
            for (a, b) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                unknowns.add_row(&rows(*tri, grads, *w, a, b), w * r[(a, b)], None, &mut rhs);
            }
        }
        if last_energy.is_finite() && last_energy - energy <= rel_tol * last_energy {
            return Ok((uv, iteration - 1));
        }
        last_energy = energy;
        let (x, _) = conjugate_gradient(&system, &rhs, 1e-10, 20 * unknowns.count + 100).map_err(|e| format!("ARAP solve: {e}"))?;
        uv = unknowns.positions(&x);
    }
    Ok((uv, max_iterations))
}

/// The flat map's Jacobian on a triangle (rows u, v; columns the triangle's x, y).
fn jacobian(uv: &[Vec2], tri: [u32; 3], grads: &[Vec2; 3]) -> nalgebra::Matrix2<f64> {
    (0..3).map(|k| uv[tri[k] as usize] * grads[k].transpose()).sum()
}

/// The rotation nearest to a 2x2 matrix (Frobenius norm).
fn closest_rotation(j: &nalgebra::Matrix2<f64>) -> nalgebra::Matrix2<f64> {
    let angle = (j[(1, 0)] - j[(0, 1)]).atan2(j[(0, 0)] + j[(1, 1)]);
    let (s, c) = angle.sin_cos();
    nalgebra::Matrix2::new(c, -s, s, c)
}

/// Gradients of the three barycentric coordinates in the triangle's own frame
/// (x along the first edge, counter-clockwise as wound).
fn local_gradients(mesh: &TriMesh, tri: [u32; 3]) -> Option<[Vec2; 3]> {
    let [a, b, c] = tri.map(|i| mesh.points[i as usize]);
    let e1 = b - a;
    let normal = e1.cross(&(c - a));
    let area2 = normal.norm();
    if !(area2 > 0.0) || e1.norm() == 0.0 {
        return None;
    }
    let x = e1.normalize();
    let y = normal.normalize().cross(&x);
    let p = [Vec2::zeros(), Vec2::new(e1.dot(&x), 0.0), Vec2::new((c - a).dot(&x), (c - a).dot(&y))];
    // grad(lambda_k) = perp(p_{k+2} - p_{k+1}) / (2A), perp rotating by +90 degrees.
    Some(std::array::from_fn(|k| {
        let e = p[(k + 2) % 3] - p[(k + 1) % 3];
        Vec2::new(-e.y, e.x) / area2
    }))
}

fn lift(p: Vec2) -> Vec3 {
    Vec3::new(p.x, p.y, 0.0)
}

fn loop_length(boundary: &[u32], at: impl Fn(u32) -> Vec3) -> f64 {
    (0..boundary.len()).map(|k| (at(boundary[(k + 1) % boundary.len()]) - at(boundary[k])).norm()).sum()
}

/// Signed area (positive when the flat triangle keeps the 3D winding).
fn flat_area(uv: &[Vec2], tri: [u32; 3]) -> f64 {
    let [a, b, c] = tri.map(|i| uv[i as usize]);
    0.5 * ((b - a).x * (c - a).y - (b - a).y * (c - a).x)
}

fn corner_angles<P: Copy>(pts: [P; 3], sub: impl Fn(P, P) -> (f64, f64, f64)) -> [f64; 3] {
    std::array::from_fn(|k| {
        let u = sub(pts[(k + 1) % 3], pts[k]);
        let v = sub(pts[(k + 2) % 3], pts[k]);
        let dot = u.0 * v.0 + u.1 * v.1 + u.2 * v.2;
        let nu = (u.0 * u.0 + u.1 * u.1 + u.2 * u.2).sqrt();
        let nv = (v.0 * v.0 + v.1 * v.1 + v.2 * v.2).sqrt();
        (dot / (nu * nv)).clamp(-1.0, 1.0).acos()
    })
}

fn angle_error(mesh: &TriMesh, uv: &[Vec2], tri: [u32; 3]) -> f64 {
    let a3 = corner_angles(tri.map(|i| mesh.points[i as usize]), |p, q| {
        let d = p - q;
        (d.x, d.y, d.z)
    });
    let a2 = corner_angles(tri.map(|i| uv[i as usize]), |p, q| {
        let d = p - q;
        (d.x, d.y, 0.0)
    });
    (0..3).map(|k| (a2[k] - a3[k]).abs().to_degrees()).fold(0.0, f64::max)
}

fn seam_edge_errors(mesh: &TriMesh, uv: &[Vec2], boundary: &[u32]) -> Vec<f64> {
    (0..boundary.len())
        .map(|k| {
            let (a, b) = (boundary[k] as usize, boundary[(k + 1) % boundary.len()] as usize);
            ((uv[b] - uv[a]).norm() / (mesh.points[b] - mesh.points[a]).norm() - 1.0).abs()
        })
        .collect()
}

fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

fn max(values: &[f64]) -> f64 {
    values.iter().copied().fold(f64::NAN, f64::max)
}

#[cfg(test)]
mod tests;
