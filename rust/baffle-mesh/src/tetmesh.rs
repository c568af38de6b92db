//! Linear tetrahedral meshes in millimetres with labelled boundary and interior face sets,
//! and the checks every mesh this crate hands out has passed.

use crate::error::MeshError;
use baffle_core::{TriMesh, Vec3};
use std::collections::HashMap;

/// A tetrahedral mesh: points (mm), positively oriented tets (see [`tet_signed_volume_mm3`]),
/// and labelled sets of element faces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetMesh {
    pub points_mm: Vec<Vec3>,
    pub tets: Vec<[u32; 4]>,
    pub faces: Vec<FaceSet>,
}

/// The element faces carrying one `ModelFaceID`. A boundary set's triangles are each the
/// face of exactly one tet, wound outward; an interior set's (`interior: true`, measurement
/// planes) are each the face of exactly two tets, wound as the caller gave them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaceSet {
    pub id: i32,
    pub triangles: Vec<[u32; 3]>,
    pub interior: bool,
}

/// A tet whose volume is at most this fraction of its longest edge cubed is degenerate:
/// the CFD solver's own criterion (`baffle_cfd::FlowMesh::validate`), so `baffle mesh`
/// never writes a mesh the solver refuses.
pub const DEGENERATE_VOLUME_RATIO: f64 = 1e-9;

/// The signed volume (mm^3) of tet (a, b, c, d); positive when (b-a, c-a, d-a)
/// is right-handed, i.e. triangle a-b-c seen from d runs counter-clockwise (VTK and gmsh order).
pub fn tet_signed_volume_mm3(p: &[Vec3; 4]) -> f64 {
    (p[1] - p[0]).dot(&(p[2] - p[0]).cross(&(p[3] - p[0]))) / 6.0
}

/// The tet's longest edge (mm).
pub fn longest_edge_mm(p: &[Vec3; 4]) -> f64 {
    [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)].iter().map(|&(a, b)| (p[b] - p[a]).norm()).fold(0.0, f64::max)
}

/// The four faces of a tet, each wound outward for a positively oriented tet; face `k`
/// is opposite corner `k`.
pub fn tet_faces(t: &[u32; 4]) -> [[u32; 3]; 4] {
    let [a, b, c, d] = *t;
    [[b, c, d], [a, d, c], [a, b, d], [a, c, b]]
}

/// A triangle's vertex indices sorted, to compare faces regardless of winding.
pub fn face_key(tri: &[u32; 3]) -> [u32; 3] {
    let mut k = *tri;
    k.sort_unstable();
    k
}

impl TetMesh {
    pub fn tet_points(&self, t: usize) -> [Vec3; 4] {
        self.tets[t].map(|i| self.points_mm[i as usize])
    }

    pub fn volume_mm3(&self) -> f64 {
        (0..self.tets.len())
            .map(|t| tet_signed_volume_mm3(&self.tet_points(t)))
            .sum()
    }

    pub fn face_set(&self, id: i32) -> Option<&FaceSet> {
        self.faces.iter().find(|f| f.id == id)
    }

    /// The boundary face sets as one labelled surface on this mesh's points (unused points
    /// stay, so indices match the volume mesh).
    pub fn boundary_surface(&self) -> TriMesh {
        self.surface_of(|f| !f.interior)
    }

    /// The face sets selected by `keep` as one labelled surface on this mesh's points.
    pub fn surface_of(&self, keep: impl Fn(&FaceSet) -> bool) -> TriMesh {
        let mut mesh = TriMesh {
            points: self.points_mm.clone(),
            ..Default::default()
        };
        for set in self.faces.iter().filter(|f| keep(f)) {
            mesh.triangles.extend_from_slice(&set.triangles);
            mesh.face_ids
                .extend(std::iter::repeat_n(set.id, set.triangles.len()));
        }
        mesh
    }

    /// For every tet face (sorted key), the tets using it.
    pub fn face_tets(&self) -> HashMap<[u32; 3], Vec<u32>> {
        let mut map: HashMap<[u32; 3], Vec<u32>> = HashMap::with_capacity(self.tets.len() * 2 + 16);
        for (t, tet) in self.tets.iter().enumerate() {
            for f in tet_faces(tet) {
                map.entry(face_key(&f)).or_default().push(t as u32);
            }
        }
        map
    }

    /// Check indices, orientation and conformity: every tet has positive volume, every
    /// boundary triangle is the face of exactly one tet, every interior one of exactly two,
    /// every other tet face is shared by exactly two tets, and face sets do not overlap.
    pub fn validate(&self) -> Result<(), MeshError> {
        self.check_indices()?;
        self.check_positive_volumes()?;
        let face_tets = self.face_tets();
        let labelled = self.check_face_sets(&face_tets)?;
        check_unlabelled_faces_paired(&face_tets, &labelled)
    }

    fn check_indices(&self) -> Result<(), MeshError> {
        let n = self.points_mm.len();
        if let Some((i, p)) = self
            .points_mm
            .iter()
            .enumerate()
            .find(|(_, p)| !p.iter().all(|x| x.is_finite()))
        {
            return Err(MeshError::InvalidMesh(format!(
                "point {i} has a non-finite coordinate {p:?}"
            )));
        }
        for (t, tet) in self.tets.iter().enumerate() {
            if let Some(&i) = tet.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::InvalidMesh(format!(
                    "tet {t} refers to point {i}, but there are {n} points"
                )));
            }
        }
        for set in &self.faces {
            for (k, tri) in set.triangles.iter().enumerate() {
                if let Some(&i) = tri.iter().find(|&&i| i as usize >= n) {
                    return Err(MeshError::InvalidMesh(format!(
                        "triangle {k} of face {} refers to point {i}, but there are {n} points",
                        set.id
                    )));
                }
            }
        }
        Ok(())
    }

    /// Every tet must have positive volume; the first offender is named.
    pub fn check_positive_volumes(&self) -> Result<(), MeshError> {
        for t in 0..self.tets.len() {
            let p = self.tet_points(t);
            let v = tet_signed_volume_mm3(&p);
            if v.is_nan() || v < 0.0 {
                let kind = if v < 0.0 { "inverted" } else { "not finite" };
                return Err(MeshError::InvalidMesh(format!("tet {t} {:?} is {kind}: signed volume {v:e} mm^3", self.tets[t])));
            }
            let longest_mm = longest_edge_mm(&p);
            if v <= DEGENERATE_VOLUME_RATIO * longest_mm.powi(3) {
                let centre = p.iter().sum::<Vec3>() / 4.0;
                return Err(MeshError::DegenerateTet(format!(
                    "tet {t} {:?} near ({:.2}, {:.2}, {:.2}) mm is degenerate: volume {v:e} mm^3, longest edge {longest_mm:.3} mm \
                     (the CFD solver refuses tets under {DEGENERATE_VOLUME_RATIO:e} of their longest edge cubed)",
                    self.tets[t], centre.x, centre.y, centre.z
                )));
            }
        }
        Ok(())
    }

    /// Returns the keys of all labelled faces after checking each set's tet counts.
    fn check_face_sets(
        &self,
        face_tets: &HashMap<[u32; 3], Vec<u32>>,
    ) -> Result<HashMap<[u32; 3], i32>, MeshError> {
        let mut labelled: HashMap<[u32; 3], i32> = HashMap::new();
        for set in &self.faces {
            let expected = if set.interior { 2 } else { 1 };
            for (k, tri) in set.triangles.iter().enumerate() {
                let key = face_key(tri);
                let found = face_tets.get(&key).map_or(0, |v| v.len());
                if found != expected {
                    return Err(MeshError::InvalidMesh(format!(
                        "triangle {k} {tri:?} of {} face {} is the face of {found} tets, expected {expected}",
                        if set.interior { "interior" } else { "boundary" },
                        set.id
                    )));
                }
                if let Some(other) = labelled.insert(key, set.id) {
                    return Err(MeshError::InvalidMesh(format!(
                        "triangle {tri:?} belongs to face {other} and face {}",
                        set.id
                    )));
                }
            }
        }
        Ok(labelled)
    }

    /// Wind every boundary triangle outward (away from the opposite corner of its tet).
    pub(crate) fn orient_boundary_outward(&mut self) -> Result<(), MeshError> {
        let face_tets = self.face_tets();
        let points = &self.points_mm;
        for set in self.faces.iter_mut().filter(|f| !f.interior) {
            for tri in set.triangles.iter_mut() {
                let Some(&t) = face_tets.get(&face_key(tri)).and_then(|v| v.first()) else {
                    return Err(MeshError::InvalidMesh(format!(
                        "boundary triangle {tri:?} of face {} is no tet's face",
                        set.id
                    )));
                };
                let tet = self.tets[t as usize];
                let apex = tet
                    .iter()
                    .copied()
                    .find(|i| !tri.contains(i))
                    .unwrap_or(tet[0]);
                let [a, b, c] = tri.map(|i| points[i as usize]);
                if (b - a).cross(&(c - a)).dot(&(points[apex as usize] - a)) > 0.0 {
                    tri.swap(1, 2);
                }
            }
        }
        Ok(())
    }
}

fn check_unlabelled_faces_paired(
    face_tets: &HashMap<[u32; 3], Vec<u32>>,
    labelled: &HashMap<[u32; 3], i32>,
) -> Result<(), MeshError> {
    for (key, tets) in face_tets {
        if tets.len() > 2 {
            return Err(MeshError::InvalidMesh(format!(
                "face {key:?} is shared by {} tets {tets:?}",
                tets.len()
            )));
        }
        if tets.len() == 1 && !labelled.contains_key(key) {
            return Err(MeshError::InvalidMesh(format!(
                "face {key:?} of tet {} is on the mesh boundary but in no boundary face set",
                tets[0]
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tet_flatter_than_the_solver_accepts_is_degenerate() {
        let mut mesh = unit_tet();
        mesh.points_mm[3] = Vec3::new(0.2, 0.2, 1e-9); // volume 1.7e-10 of the edge cubed
        let err = mesh.check_positive_volumes().unwrap_err();
        assert!(matches!(err, MeshError::DegenerateTet(_)) && err.to_string().contains("near ("), "{err}");
        mesh.points_mm[3] = Vec3::new(0.2, 0.2, 1e-7); // 1.7e-8: thin, but the solver takes it
        mesh.check_positive_volumes().unwrap();
    }

    fn unit_tet() -> TetMesh {
        let points_mm = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        let faces = vec![FaceSet {
            id: 1,
            triangles: tet_faces(&[0, 1, 2, 3]).to_vec(),
            interior: false,
        }];
        TetMesh {
            points_mm,
            tets: vec![[0, 1, 2, 3]],
            faces,
        }
    }

    #[test]
    fn unit_tet_is_valid_with_volume_one_sixth() {
        let mesh = unit_tet();
        mesh.validate().unwrap();
        assert!((mesh.volume_mm3() - 1.0 / 6.0).abs() < 1e-15);
        // Outward faces: the boundary surface encloses the same positive volume.
        assert!((mesh.boundary_surface().signed_volume_mm3() - 1.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn inverted_tet_is_rejected_by_name() {
        let mut mesh = unit_tet();
        mesh.tets[0] = [0, 2, 1, 3];
        let err = mesh.validate().unwrap_err().to_string();
        assert!(err.contains("tet 0") && err.contains("inverted"), "{err}");
    }

    #[test]
    fn missing_boundary_face_is_reported() {
        let mut mesh = unit_tet();
        mesh.faces[0].triangles.pop();
        let err = mesh.validate().unwrap_err().to_string();
        assert!(err.contains("in no boundary face set"), "{err}");
    }

    #[test]
    fn orient_boundary_outward_flips_inward_triangles() {
        let mut mesh = unit_tet();
        for tri in mesh.faces[0].triangles.iter_mut() {
            tri.swap(0, 1);
        }
        assert!(mesh.boundary_surface().signed_volume_mm3() < 0.0);
        mesh.orient_boundary_outward().unwrap();
        assert!((mesh.boundary_surface().signed_volume_mm3() - 1.0 / 6.0).abs() < 1e-15);
    }
}
