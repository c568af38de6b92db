//! Face geometry: outward normals of boundary triangles, nodal flux weights, areas.

use std::collections::HashMap;

use crate::flow_mesh::{cross, dot, opposite_triangle, sub, tri_key, Face, FlowMesh, TriangleMap};
use crate::CfdError;

/// Whether a face lies on the domain boundary or inside it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaceKind {
    /// Boundary face: triangles oriented with the outward normal.
    Boundary,
    /// Interior measurement plane: normals follow the given winding.
    Interior,
}

/// A face prepared for integration: triangles oriented as the normals used.
#[derive(Clone, Debug)]
pub struct FaceGeometry {
    pub id: i32,
    pub name: String,
    pub kind: FaceKind,
    pub triangles: Vec<[u32; 3]>,
    /// Area-weighted normal per triangle (|n| = triangle area, cm^2).
    pub area_normals_cm2: Vec<[f64; 3]>,
    pub area_cm2: f64,
}

impl FaceGeometry {
    /// Flux weights b_i = integral of N_i n over the face (cm^2), per node.
    pub fn nodal_flux_weights(&self) -> HashMap<u32, [f64; 3]> {
        let mut w: HashMap<u32, [f64; 3]> = HashMap::new();
        for (tri, n) in self.triangles.iter().zip(&self.area_normals_cm2) {
            for &node in tri {
                let e = w.entry(node).or_insert([0.0; 3]);
                for k in 0..3 {
                    e[k] += n[k] / 3.0;
                }
            }
        }
        w
    }

    /// Unit mean normal of the face.
    pub fn mean_unit_normal(&self) -> [f64; 3] {
        let mut s = [0.0; 3];
        for n in &self.area_normals_cm2 {
            for k in 0..3 {
                s[k] += n[k];
            }
        }
        let len = dot(s, s).sqrt();
        s.map(|x| x / len.max(f64::MIN_POSITIVE))
    }

    /// Nodes of the face, sorted.
    pub fn nodes(&self) -> Vec<u32> {
        let mut v: Vec<u32> = self.triangles.iter().flatten().copied().collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

fn area_normal(p: &[[f64; 3]], t: [u32; 3]) -> [f64; 3] {
    let [a, b, c] = t.map(|i| p[i as usize]);
    cross(sub(b, a), sub(c, a)).map(|x| 0.5 * x)
}

/// Area of a face (cm^2).
pub fn face_area_cm2(mesh: &FlowMesh, face: &Face) -> f64 {
    face.triangles.iter().map(|&t| dot(area_normal(&mesh.points_cm, t), area_normal(&mesh.points_cm, t)).sqrt()).sum()
}

/// Boundary triangles of the mesh (each a face of exactly one tet), wound outward;
/// `element` is the mesh's element-face map (`element_faces`, made once for both users).
pub fn boundary_triangles(mesh: &FlowMesh, element: &TriangleMap<(u32, u8, u8)>) -> Vec<[u32; 3]> {
    let mut out: Vec<[u32; 3]> = element
        .values()
        .filter(|v| v.2 == 1)
        .map(|&(e, opp, _)| outward(&mesh.points_cm, &mesh.tets[e as usize], opp as usize))
        .collect();
    out.sort_unstable();
    out
}

/// The triangle opposite `opp` in tet `t`, wound so its normal points away from that node.
fn outward(p: &[[f64; 3]], t: &[u32; 4], opp: usize) -> [u32; 3] {
    let tri = opposite_triangle(t, opp);
    let n = area_normal(p, tri);
    let to_opposite = sub(p[t[opp] as usize], p[tri[0] as usize]);
    if dot(n, to_opposite) > 0.0 {
        [tri[0], tri[2], tri[1]]
    } else {
        tri
    }
}

/// Prepare every face of the mesh: boundary faces get outward winding, interior
/// planes keep theirs. A face mixing boundary and interior triangles is an error.
/// `element` is the mesh's element-face map (`element_faces`).
pub fn face_geometries(mesh: &FlowMesh, element: &TriangleMap<(u32, u8, u8)>) -> Result<Vec<FaceGeometry>, CfdError> {
    let mut out = Vec::with_capacity(mesh.faces.len());
    for face in &mesh.faces {
        let mut boundary = 0;
        let mut triangles = Vec::with_capacity(face.triangles.len());
        for &tri in &face.triangles {
            let &(e, opp, count) = element.get(&tri_key(tri)).ok_or_else(|| {
                CfdError::Mesh(format!("face {} '{}' triangle {tri:?} is not a face of any tet", face.id, face.name))
            })?;
            if count == 1 {
                boundary += 1;
                triangles.push(outward(&mesh.points_cm, &mesh.tets[e as usize], opp as usize));
            } else {
                triangles.push(tri);
            }
        }
        let kind = match boundary {
            0 => FaceKind::Interior,
            b if b == triangles.len() => FaceKind::Boundary,
            b => {
                let msg = format!("face {} '{}' has {b} boundary and {} interior triangles", face.id, face.name, triangles.len() - b);
                return Err(CfdError::Mesh(msg));
            }
        };
        let area_normals_cm2: Vec<[f64; 3]> = triangles.iter().map(|&t| area_normal(&mesh.points_cm, t)).collect();
        let area_cm2 = area_normals_cm2.iter().map(|n| dot(*n, *n).sqrt()).sum();
        out.push(FaceGeometry { id: face.id, name: face.name.clone(), kind, triangles, area_normals_cm2, area_cm2 });
    }
    Ok(out)
}
