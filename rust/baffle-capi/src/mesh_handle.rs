//! The mesh handle: a labelled triangle surface built from plain arrays (or VTK's
//! offsets/connectivity pair), validated on the way in, copied out on request.

use crate::status::{arg_ref, free_handle, guarded, in_slice, out_handle, out_ref, out_slice, xyz_points, BaffleStatus, CallError};
use baffle_core::{TriMesh, Vec3};

/// Opaque, immutable triangle surface (mm) with one int32 label per triangle.
pub struct BaffleMesh {
    pub(crate) mesh: TriMesh,
}

impl BaffleMesh {
    pub(crate) fn boxed(mesh: TriMesh) -> *mut BaffleMesh {
        Box::into_raw(Box::new(BaffleMesh { mesh }))
    }
}

/// Make a mesh from points (double[points_len], x y z per point), triangles
/// (int64[triangles_len], three point indices each) and labels
/// (int32[labels_len], one ModelFaceID per triangle).
///
/// # Safety
/// Each pointer must be NULL or valid for its length; `out_mesh` must be writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_mesh_new(
    points_mm: *const f64,
    points_len: usize,
    triangles: *const i64,
    triangles_len: usize,
    labels: *const i32,
    labels_len: usize,
    out_mesh: *mut *mut BaffleMesh,
) -> BaffleStatus {
    new_mesh(points_mm, points_len, labels, labels_len, out_mesh, |point_count| {
        let corners = in_slice(triangles, triangles_len, "triangles")?;
        if !triangles_len.is_multiple_of(3) {
            return Err(CallError::invalid(format!("triangles has {triangles_len} indices, not a multiple of 3")));
        }
        corners.chunks_exact(3).enumerate().map(|(t, c)| triangle(t, c, point_count)).collect()
    })
}

/// Make a mesh from VTK's polygon layout: `offsets` (int64[cells + 1], starting at
/// 0 and ending at connectivity_len) and `connectivity` (point indices); every
/// cell must be a triangle (run vtkTriangleFilter first otherwise).
///
/// # Safety
/// Each pointer must be NULL or valid for its length; `out_mesh` must be writable.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn baffle_mesh_new_vtk(
    points_mm: *const f64,
    points_len: usize,
    offsets: *const i64,
    offsets_len: usize,
    connectivity: *const i64,
    connectivity_len: usize,
    labels: *const i32,
    labels_len: usize,
    out_mesh: *mut *mut BaffleMesh,
) -> BaffleStatus {
    new_mesh(points_mm, points_len, labels, labels_len, out_mesh, |point_count| {
        let offsets = in_slice(offsets, offsets_len, "offsets")?;
        let connectivity = in_slice(connectivity, connectivity_len, "connectivity")?;
        vtk_triangles(offsets, connectivity, point_count)
    })
}

/// The body of the mesh constructors: `out_mesh` set to NULL, the points checked, the
/// triangles made by `triangles_of` (given the point count), the labels checked against
/// them, then the new handle in `out_mesh`.
unsafe fn new_mesh(
    points_mm: *const f64,
    points_len: usize,
    labels: *const i32,
    labels_len: usize,
    out_mesh: *mut *mut BaffleMesh,
    triangles_of: impl FnOnce(usize) -> Result<Vec<[u32; 3]>, CallError>,
) -> BaffleStatus {
    guarded(|| {
        let out = out_handle(out_mesh, "out_mesh")?;
        let points = mesh_points(in_slice(points_mm, points_len, "points_mm")?)?;
        let tris = triangles_of(points.len())?;
        let face_ids = mesh_labels(in_slice(labels, labels_len, "labels")?, tris.len())?;
        *out = BaffleMesh::boxed(TriMesh::new(points, tris, face_ids));
        Ok(())
    })
}

fn mesh_points(values: &[f64]) -> Result<Vec<Vec3>, CallError> {
    // Before the copy: a surface that large would not fit in memory twice.
    if values.len() / 3 > u32::MAX as usize {
        return Err(CallError::invalid("more points than 32-bit indices can address"));
    }
    xyz_points(values, "points_mm")
}

fn point_index(cell: usize, index: i64, point_count: usize) -> Result<u32, CallError> {
    if index < 0 || index as u64 >= point_count as u64 {
        return Err(CallError::invalid(format!("triangle {cell} refers to point {index}, outside 0..{point_count}")));
    }
    Ok(index as u32)
}

fn triangle(cell: usize, corners: &[i64], point_count: usize) -> Result<[u32; 3], CallError> {
    Ok([
        point_index(cell, corners[0], point_count)?,
        point_index(cell, corners[1], point_count)?,
        point_index(cell, corners[2], point_count)?,
    ])
}

fn vtk_triangles(offsets: &[i64], connectivity: &[i64], point_count: usize) -> Result<Vec<[u32; 3]>, CallError> {
    let (Some(&first), Some(&last)) = (offsets.first(), offsets.last()) else {
        return Err(CallError::invalid("offsets is empty; it needs cells + 1 entries starting at 0"));
    };
    if first != 0 || last != connectivity.len() as i64 {
        return Err(CallError::invalid(format!(
            "offsets must start at 0 and end at the connectivity length {} (they run {first}..{last})",
            connectivity.len()
        )));
    }
    offsets
        .windows(2)
        .enumerate()
        .map(|(cell, w)| {
            if w[1] - w[0] != 3 {
                return Err(CallError::invalid(format!(
                    "cell {cell} has {} points; only triangles are accepted (triangulate first)",
                    w[1] - w[0]
                )));
            }
            triangle(cell, &connectivity[w[0] as usize..w[1] as usize], point_count)
        })
        .collect()
}

fn mesh_labels(labels: &[i32], triangle_count: usize) -> Result<Vec<i32>, CallError> {
    if labels.len() != triangle_count {
        return Err(CallError::invalid(format!("{} labels for {triangle_count} triangles", labels.len())));
    }
    Ok(labels.to_vec())
}

/// Free a mesh (NULL is ignored).
///
/// # Safety
/// `mesh` must be NULL or a handle from this library not yet freed.
#[no_mangle]
pub unsafe extern "C" fn baffle_mesh_free(mesh: *mut BaffleMesh) {
    free_handle(mesh);
}

/// Number of points of the mesh.
///
/// # Safety
/// `mesh` must be NULL or a live handle; `out_count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_mesh_point_count(mesh: *const BaffleMesh, out_count: *mut usize) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_count, "out_count")? = arg_ref(mesh, "mesh")?.mesh.points.len();
        Ok(())
    })
}

/// Number of triangles of the mesh.
///
/// # Safety
/// `mesh` must be NULL or a live handle; `out_count` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_mesh_triangle_count(mesh: *const BaffleMesh, out_count: *mut usize) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_count, "out_count")? = arg_ref(mesh, "mesh")?.mesh.triangles.len();
        Ok(())
    })
}

/// Copy the points (3 per point) into `out_points_mm`, which holds `capacity` doubles.
///
/// # Safety
/// `mesh` must be NULL or a live handle; `out_points_mm` NULL or `capacity` writable doubles.
#[no_mangle]
pub unsafe extern "C" fn baffle_mesh_copy_points(mesh: *const BaffleMesh, out_points_mm: *mut f64, capacity: usize) -> BaffleStatus {
    copy_mesh_array(mesh, |m| &m.points, 3, out_points_mm, capacity, "out_points_mm", copy_points)
}

/// Copy the triangles (3 point indices each) into `out_triangles` (`capacity` int64s).
///
/// # Safety
/// `mesh` must be NULL or a live handle; `out_triangles` NULL or `capacity` writable int64s.
#[no_mangle]
pub unsafe extern "C" fn baffle_mesh_copy_triangles(mesh: *const BaffleMesh, out_triangles: *mut i64, capacity: usize) -> BaffleStatus {
    copy_mesh_array(mesh, |m| &m.triangles, 3, out_triangles, capacity, "out_triangles", copy_triangles)
}

/// Copy the per-triangle labels into `out_labels` (`capacity` int32s).
///
/// # Safety
/// `mesh` must be NULL or a live handle; `out_labels` NULL or `capacity` writable int32s.
#[no_mangle]
pub unsafe extern "C" fn baffle_mesh_copy_labels(mesh: *const BaffleMesh, out_labels: *mut i32, capacity: usize) -> BaffleStatus {
    copy_mesh_array(mesh, |m| &m.face_ids, 1, out_labels, capacity, "out_labels", |labels, out| out.copy_from_slice(labels))
}

/// The body of the mesh copy-out calls: one of the mesh's arrays (`array`, `per_item`
/// output values per element) written by `write` into the caller's buffer `out`
/// (`capacity` long, named `out_name` in errors).
unsafe fn copy_mesh_array<Item, Out>(
    mesh: *const BaffleMesh,
    array: fn(&TriMesh) -> &[Item],
    per_item: usize,
    out: *mut Out,
    capacity: usize,
    out_name: &str,
    write: fn(&[Item], &mut [Out]),
) -> BaffleStatus {
    guarded(|| {
        let items = array(&arg_ref(mesh, "mesh")?.mesh);
        write(items, out_slice(out, capacity, per_item * items.len(), out_name)?);
        Ok(())
    })
}

/// Write points as x y z triples into `out` (exactly 3 x points long).
pub(crate) fn copy_points(points: &[Vec3], out: &mut [f64]) {
    for (dst, p) in out.chunks_exact_mut(3).zip(points) {
        dst.copy_from_slice(&[p.x, p.y, p.z]);
    }
}

/// Write triangles as int64 index triples into `out` (exactly 3 x triangles long).
fn copy_triangles(triangles: &[[u32; 3]], out: &mut [i64]) {
    for (dst, &src) in out.iter_mut().zip(triangles.iter().flatten()) {
        *dst = i64::from(src);
    }
}
