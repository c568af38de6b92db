//! Flow mesh (linear tetrahedra in cm) with labelled faces, and its validation.

use std::collections::HashMap;

use crate::CfdError;

/// A labelled set of triangles made of mesh nodes: a boundary face (inlet, outlet,
/// wall) or an interior measurement plane (a set of element faces).
#[derive(Clone, Debug, PartialEq)]
pub struct Face {
    pub id: i32,
    pub name: String,
    pub triangles: Vec<[u32; 3]>,
}

/// Tetrahedral mesh for the solver. Coordinates in cm.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct FlowMesh {
    pub points_cm: Vec<[f64; 3]>,
    pub tets: Vec<[u32; 4]>,
    pub faces: Vec<Face>,
}

/// What [`FlowMesh::validate`] found and repaired.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct ValidationReport {
    /// Tets with negative volume whose last two nodes were swapped.
    pub reoriented_tets: usize,
    pub volume_cm3: f64,
    pub boundary_triangles: usize,
}

/// Signed volume of a tet (positive when (b-a, c-a, d-a) is right-handed).
pub fn tet_volume_cm3(p: &[[f64; 3]], t: &[u32; 4]) -> f64 {
    let [a, b, c, d] = t.map(|i| p[i as usize]);
    let u = sub(b, a);
    let v = sub(c, a);
    let w = sub(d, a);
    dot(u, cross(v, w)) / 6.0
}

#[inline(always)]
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn max_edge_cm(p: &[[f64; 3]], t: &[u32; 4]) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..4 {
        for j in i + 1..4 {
            let e = sub(p[t[i] as usize], p[t[j] as usize]);
            m = m.max(dot(e, e).sqrt());
        }
    }
    m
}

/// Sorted node triple: key of a triangle independent of winding.
pub(crate) fn tri_key(t: [u32; 3]) -> [u32; 3] {
    let mut k = t;
    k.sort_unstable();
    k
}

/// A hash map keyed by a sorted node triple, hashed as core's edge maps are (Fx-style):
/// node numbers are not adversarial, and SipHash made the element-face map a fifth of a
/// short run's set-up.
pub(crate) type TriangleMap<V> = HashMap<[u32; 3], V, std::hash::BuildHasherDefault<baffle_core::geometry::mesh::EdgeHasher>>;

/// Element faces: sorted triple -> (tet, local index of the opposite node, count).
pub(crate) fn element_faces(tets: &[[u32; 4]]) -> TriangleMap<(u32, u8, u8)> {
    let mut map: TriangleMap<(u32, u8, u8)> = TriangleMap::with_capacity_and_hasher(tets.len() * 2 + 16, Default::default());
    for (e, t) in tets.iter().enumerate() {
        for opposite in 0..4u8 {
            let tri = opposite_triangle(t, opposite as usize);
            map.entry(tri_key(tri)).and_modify(|v| v.2 += 1).or_insert((e as u32, opposite, 1));
        }
    }
    map
}

pub(crate) fn opposite_triangle(t: &[u32; 4], opposite: usize) -> [u32; 3] {
    let mut tri = [0u32; 3];
    let mut k = 0;
    for (i, &n) in t.iter().enumerate() {
        if i != opposite {
            tri[k] = n;
            k += 1;
        }
    }
    tri
}

impl FlowMesh {
    /// Check and repair: finite points, node indices in range, no repeated nodes in a
    /// tet, inverted tets reoriented (two nodes swapped), degenerate tets (volume below
    /// 1e-9 of their longest edge cubed) rejected, faces non-empty with unique ids and
    /// valid nodes, and every face triangle an element face (boundary or interior),
    /// no element face shared by more than two tets.
    pub fn validate(&mut self) -> Result<ValidationReport, CfdError> {
        self.check_points()?;
        let reoriented_tets = self.check_tets()?;
        let faces = element_faces(&self.tets);
        if let Some((k, v)) = faces.iter().find(|(_, v)| v.2 > 2) {
            return Err(CfdError::Mesh(format!("triangle {k:?} is shared by {} tets (non-manifold)", v.2)));
        }
        self.check_faces(&faces)?;
        let volume_cm3 = self.tets.iter().map(|t| tet_volume_cm3(&self.points_cm, t)).sum();
        let boundary_triangles = faces.values().filter(|v| v.2 == 1).count();
        Ok(ValidationReport { reoriented_tets, volume_cm3, boundary_triangles })
    }

    fn check_points(&self) -> Result<(), CfdError> {
        if self.tets.is_empty() {
            return Err(CfdError::Mesh("no tetrahedra".into()));
        }
        match self.points_cm.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
            Some(i) => Err(CfdError::Mesh(format!("point {i} has a non-finite coordinate {:?}", self.points_cm[i]))),
            None => Ok(()),
        }
    }

    fn check_tets(&mut self) -> Result<usize, CfdError> {
        let n = self.points_cm.len();
        let mut reoriented = 0;
        for (e, t) in self.tets.iter_mut().enumerate() {
            if let Some(&bad) = t.iter().find(|&&i| i as usize >= n) {
                return Err(CfdError::Mesh(format!("tet {e} references node {bad}, mesh has {n} nodes")));
            }
            if (0..4).any(|i| (i + 1..4).any(|j| t[i] == t[j])) {
                return Err(CfdError::Mesh(format!("tet {e} repeats a node: {t:?}")));
            }
            let volume = tet_volume_cm3(&self.points_cm, t);
            let scale = max_edge_cm(&self.points_cm, t).powi(3);
            if volume.abs() <= 1e-9 * scale {
                return Err(CfdError::Mesh(format!("tet {e} {t:?} is degenerate (volume {volume:.3e} cm3)")));
            }
            if volume < 0.0 {
                t.swap(2, 3);
                reoriented += 1;
            }
        }
        Ok(reoriented)
    }

    fn check_faces(&self, element_faces: &TriangleMap<(u32, u8, u8)>) -> Result<(), CfdError> {
        let n = self.points_cm.len();
        let mut ids = std::collections::HashSet::new();
        for face in &self.faces {
            if !ids.insert(face.id) {
                return Err(CfdError::Mesh(format!("face id {} appears twice", face.id)));
            }
            if face.triangles.is_empty() {
                return Err(CfdError::Mesh(format!("face {} '{}' has no triangles", face.id, face.name)));
            }
            for (k, tri) in face.triangles.iter().enumerate() {
                if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
                    let msg = format!("face {} '{}' triangle {k} references node {bad} of {n}", face.id, face.name);
                    return Err(CfdError::Mesh(msg));
                }
                if !element_faces.contains_key(&tri_key(*tri)) {
                    let msg = format!("face {} '{}' triangle {k} {tri:?} is not a face of any tet", face.id, face.name);
                    return Err(CfdError::Mesh(msg));
                }
            }
        }
        Ok(())
    }

    pub fn face(&self, id: i32) -> Option<&Face> {
        self.faces.iter().find(|f| f.id == id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_tets() -> FlowMesh {
        FlowMesh {
            points_cm: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]],
            tets: vec![[0, 1, 2, 3], [0, 1, 2, 4]],
            faces: vec![Face { id: 1, name: "wall".into(), triangles: vec![[0, 1, 3]] }],
        }
    }

    #[test]
    fn inverted_tets_are_reoriented() {
        let mut m = two_tets();
        let r = m.validate().unwrap();
        assert_eq!(r.reoriented_tets, 1);
        assert!((r.volume_cm3 - 2.0 / 6.0).abs() < 1e-12);
        assert_eq!(r.boundary_triangles, 6);
        assert!(m.tets.iter().all(|t| tet_volume_cm3(&m.points_cm, t) > 0.0));
    }

    #[test]
    fn bad_meshes_are_named() {
        let mut m = two_tets();
        m.points_cm[4] = [0.5, 0.5, 0.0];
        assert!(m.validate().unwrap_err().to_string().contains("tet 1"));
        let mut m = two_tets();
        m.tets[0][3] = 9;
        assert!(m.validate().unwrap_err().to_string().contains("node 9"));
        let mut m = two_tets();
        m.faces[0].triangles[0] = [1, 3, 4];
        assert!(m.validate().unwrap_err().to_string().contains("not a face of any tet"));
        let mut m = two_tets();
        m.faces.push(Face { id: 1, name: "again".into(), triangles: vec![[0, 1, 2]] });
        assert!(m.validate().unwrap_err().to_string().contains("twice"));
        let mut m = two_tets();
        m.points_cm[2][1] = f64::NAN;
        assert!(m.validate().unwrap_err().to_string().contains("point 2"));
    }
}
