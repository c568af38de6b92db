//! Sampling a tetrahedral point field at arbitrary points: find the containing tet
//! through a uniform grid of tet bounding boxes, then interpolate barycentrically
//! (exact for fields linear in space, as P1 finite-element fields are per tet).
//! [`PeakFields`] samples a `baffle simulate` result (peak.vtu) along a centerline,
//! for `baffle centerline` and the plan's report.

use baffle_cfd::vtu::{PRESSURE_ARRAY, VELOCITY_ARRAY};
use baffle_core::Vec3;
use std::path::Path;

/// Barycentric coordinates below this count as inside (points on a face or a cap).
const INSIDE_TOLERANCE: f64 = 1e-9;
/// A point this little outside every tet (relative barycentric) is taken from the
/// nearest one: centerline ends lie on the caps, which remeshing may move slightly.
const OUTSIDE_TOLERANCE: f64 = 0.05;

pub struct TetLocator<'a> {
    points: &'a [[f64; 3]],
    tets: &'a [[u32; 4]],
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    cells: Vec<Vec<u32>>,
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn det3(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> f64 {
    a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
}

/// Barycentric coordinates of `p` in the tet `v` (None for a flat tet).
pub fn barycentric(v: [[f64; 3]; 4], p: [f64; 3]) -> Option<[f64; 4]> {
    let (a, b, c) = (sub(v[1], v[0]), sub(v[2], v[0]), sub(v[3], v[0]));
    let volume = det3(a, b, c);
    if volume.abs() < 1e-300 {
        return None;
    }
    let q = sub(p, v[0]);
    let l1 = det3(q, b, c) / volume;
    let l2 = det3(a, q, c) / volume;
    let l3 = det3(a, b, q) / volume;
    Some([1.0 - l1 - l2 - l3, l1, l2, l3])
}

impl<'a> TetLocator<'a> {
    pub fn new(points: &'a [[f64; 3]], tets: &'a [[u32; 4]]) -> TetLocator<'a> {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let extent = sub(hi, lo).map(|e| e.max(1e-12));
        // About one tet per cell on average.
        let cell = (extent[0] * extent[1] * extent[2] / tets.len().max(1) as f64).cbrt().max(1e-12);
        let dims = extent.map(|e| ((e / cell).ceil() as usize).clamp(1, 512));
        let mut locator = TetLocator { points, tets, origin: lo, cell, dims, cells: vec![Vec::new(); dims[0] * dims[1] * dims[2]] };
        for (t, tet) in tets.iter().enumerate() {
            let (mut a, mut b) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
            for &i in tet {
                let p = points[i as usize];
                for k in 0..3 {
                    a[k] = a[k].min(p[k]);
                    b[k] = b[k].max(p[k]);
                }
            }
            let (ia, ib) = (locator.cell_of(a), locator.cell_of(b));
            for i in ia[0]..=ib[0] {
                for j in ia[1]..=ib[1] {
                    for k in ia[2]..=ib[2] {
                        let index = locator.index([i, j, k]);
                        locator.cells[index].push(t as u32);
                    }
                }
            }
        }
        locator
    }

    fn cell_of(&self, p: [f64; 3]) -> [usize; 3] {
        std::array::from_fn(|k| (((p[k] - self.origin[k]) / self.cell).floor().max(0.0) as usize).min(self.dims[k] - 1))
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    fn corners(&self, t: usize) -> [[f64; 3]; 4] {
        self.tets[t].map(|i| self.points[i as usize])
    }

    /// The tet holding `p` and its barycentric coordinates; None when `p` is outside.
    pub fn locate(&self, p: [f64; 3]) -> Option<(usize, [f64; 4])> {
        if (0..3).any(|k| p[k] < self.origin[k] - self.cell || p[k] > self.origin[k] + (self.dims[k] as f64 + 1.0) * self.cell) {
            return None;
        }
        let mut best: Option<(usize, [f64; 4], f64)> = None;
        for &t in &self.cells[self.index(self.cell_of(p))] {
            let Some(l) = barycentric(self.corners(t as usize), p) else { continue };
            let worst = l.iter().cloned().fold(f64::INFINITY, f64::min);
            if worst >= -INSIDE_TOLERANCE {
                return Some((t as usize, l));
            }
            if best.as_ref().is_none_or(|b| worst > b.2) {
                best = Some((t as usize, l, worst));
            }
        }
        best.filter(|b| b.2 >= -OUTSIDE_TOLERANCE).map(|(t, l, _)| (t, l))
    }

    /// `values` (one per point) interpolated at `p`.
    #[cfg(test)]
    pub fn interpolate(&self, values: &[f64], p: [f64; 3]) -> Option<f64> {
        self.locate(p).map(|located| self.interpolate_at(values, located))
    }

    /// `values` interpolated at a point [`TetLocator::locate`] found (one search for many fields).
    pub fn interpolate_at(&self, values: &[f64], (t, l): (usize, [f64; 4])) -> f64 {
        (0..4).map(|k| l[k] * values[self.tets[t][k] as usize]).sum()
    }
}

/// Pressure (mmHg) and velocity (m/s) per point of a tet mesh in mm, as `baffle
/// simulate` writes them.
pub struct PeakFields {
    points_mm: Vec<[f64; 3]>,
    tets: Vec<[u32; 4]>,
    pressure_mmhg: Vec<f64>,
    velocity_m_s: [Vec<f64>; 3],
}

/// Pressure (mmHg) and speed (m/s) at each centerline point; None outside the mesh.
pub struct Profile {
    pub pressure_mmhg: Vec<Option<f64>>,
    pub speed_m_s: Vec<Option<f64>>,
}

impl Profile {
    /// Largest sampled speed (m/s); NaN when no point was sampled.
    pub fn v_max_m_s(&self) -> f64 {
        self.speed_m_s.iter().flatten().cloned().fold(f64::NAN, f64::max)
    }
}

impl PeakFields {
    pub fn read(path: &Path) -> Result<PeakFields, String> {
        let peak = baffle_mesh::read_vtu(path).map_err(|e| e.to_string())?;
        let field = |name: &str, components: usize| {
            peak.point_data
                .iter()
                .find(|a| a.name == name)
                .and_then(|a| a.as_f64())
                .filter(|(c, _)| *c == components)
                .map(|(_, v)| v.to_vec())
                .ok_or_else(|| format!("{}: no point array {name} with {components} components", path.display()))
        };
        let pressure_mmhg = field(PRESSURE_ARRAY, 1)?;
        let v = field(VELOCITY_ARRAY, 3)?;
        let velocity_m_s = std::array::from_fn(|k| v.chunks_exact(3).map(|c| c[k]).collect());
        let points_mm = peak.mesh.points_mm.iter().map(|p| [p.x, p.y, p.z]).collect();
        Ok(PeakFields { points_mm, tets: peak.mesh.tets, pressure_mmhg, velocity_m_s })
    }

    /// The fields at `points_mm`: each velocity component is interpolated in its tet
    /// (the P1 field itself), then its magnitude taken.
    pub fn profile(&self, points_mm: &[Vec3]) -> Profile {
        let locator = TetLocator::new(&self.points_mm, &self.tets);
        let mut profile = Profile { pressure_mmhg: Vec::new(), speed_m_s: Vec::new() };
        for p in points_mm {
            let located = locator.locate([p.x, p.y, p.z]);
            let at = |values: &[f64]| located.map(|found| locator.interpolate_at(values, found));
            profile.pressure_mmhg.push(at(&self.pressure_mmhg));
            let v: Option<Vec<f64>> = self.velocity_m_s.iter().map(|c| at(c)).collect();
            profile.speed_m_s.push(v.map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()));
        }
        profile
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube split into 6 tets around its main diagonal, scaled by `size`.
    fn cube(size: f64) -> (Vec<[f64; 3]>, Vec<[u32; 4]>) {
        let points: Vec<[f64; 3]> = (0..8).map(|i| [(i & 1) as f64 * size, ((i >> 1) & 1) as f64 * size, ((i >> 2) & 1) as f64 * size]).collect();
        let tets = vec![[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]];
        (points, tets)
    }

    #[test]
    fn a_linear_field_is_reproduced_exactly() {
        let (points, tets) = cube(2.0);
        let field = |p: [f64; 3]| 3.0 * p[0] - 2.0 * p[1] + 0.5 * p[2] + 7.0;
        let values: Vec<f64> = points.iter().map(|&p| field(p)).collect();
        let locator = TetLocator::new(&points, &tets);
        for q in [[0.3, 1.7, 0.9], [1.99, 0.01, 1.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [2.0, 2.0, 2.0], [0.5, 0.25, 1.75]] {
            let v = locator.interpolate(&values, q).unwrap_or_else(|| panic!("{q:?} not located"));
            assert!((v - field(q)).abs() < 1e-12, "{q:?}: {v} vs {}", field(q));
        }
    }

    #[test]
    fn points_outside_the_mesh_are_not_sampled() {
        let (points, tets) = cube(1.0);
        let values = vec![1.0; 8];
        let locator = TetLocator::new(&points, &tets);
        assert!(locator.interpolate(&values, [1.5, 0.5, 0.5]).is_none());
        assert!(locator.interpolate(&values, [-10.0, 0.5, 0.5]).is_none());
        // Just outside a face: taken from the tet under it.
        assert!(locator.interpolate(&values, [1.01, 0.5, 0.5]).is_some());
    }

    #[test]
    fn the_containing_tet_has_nonnegative_coordinates_summing_to_one() {
        let (points, tets) = cube(1.0);
        let locator = TetLocator::new(&points, &tets);
        let (t, l) = locator.locate([0.2, 0.7, 0.4]).unwrap();
        assert!(l.iter().all(|&x| x >= -1e-12), "{l:?}");
        assert!((l.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(t < 6);
    }

    #[test]
    fn peak_fields_linear_in_space_are_sampled_exactly_in_mm_m_s_and_mmhg() {
        // Tube of radius 0.4 cm, 2 cm long; pressure and every velocity component linear.
        let mesh = baffle_cfd::test_meshes::tube(0.4, 2.0, 4, 10, &[]);
        let pressure_at = |p: [f64; 3]| 1333.2 * (2.0 - p[2]) + 50.0 * p[0];
        let velocity_at = |p: [f64; 3]| [10.0 * p[1], -5.0 * p[0], 120.0 + 30.0 * p[2]];
        let pressure: Vec<f64> = mesh.points_cm.iter().map(|&p| pressure_at(p)).collect();
        let velocity: Vec<[f64; 3]> = mesh.points_cm.iter().map(|&p| velocity_at(p)).collect();
        let dir = std::env::temp_dir().join(format!("baffle-sampling-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("peak.vtu");
        baffle_cfd::vtu::write_solution_vtu(&path, &mesh.points_cm, &mesh.tets, &velocity, &pressure).unwrap();
        let fields = PeakFields::read(&path).unwrap();
        // An oblique line inside the tube (mm), and one point outside it.
        let mut points: Vec<Vec3> = (0..=20).map(|k| Vec3::new(-1.5 + 0.15 * k as f64, 1.0 - 0.1 * k as f64, 0.5 + 0.9 * k as f64)).collect();
        points.push(Vec3::new(9.0, 0.0, 10.0));
        let profile = fields.profile(&points);
        for (k, p) in points[..21].iter().enumerate() {
            let q = [p.x / 10.0, p.y / 10.0, p.z / 10.0];
            let v = velocity_at(q);
            let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() / 100.0;
            let pressure = pressure_at(q) / baffle_cfd::hemodynamics::DYN_CM2_PER_MMHG;
            assert!((profile.pressure_mmhg[k].unwrap() - pressure).abs() < 1e-9, "point {k}");
            assert!((profile.speed_m_s[k].unwrap() - speed).abs() < 1e-12, "point {k}");
        }
        assert!(profile.pressure_mmhg[21].is_none() && profile.speed_m_s[21].is_none());
        let expected = profile.speed_m_s[..21].iter().flatten().cloned().fold(0.0, f64::max);
        assert_eq!(profile.v_max_m_s(), expected);
        std::fs::remove_dir_all(dir).ok();
    }
}
