//! Tetrahedral meshing of a closed labelled surface by gmsh run as a child process.
//!
//! Choice: the caller's surface triangulation is kept as the mesh boundary (gmsh's
//! discrete surfaces are not remeshed), so every boundary triangle, its `ModelFaceID` and
//! its points' coordinates come back bit-identical; gmsh only fills the inside (3D
//! Delaunay + optimisation) with interior sizes up to `edge_length_mm`, grading from the
//! boundary triangles' own size. The design surface is remeshed at 0.85 mm (the paper's
//! surface size), finer than the paper's coarse/nominal volume sizes. For a mesh-size
//! study that also refines the boundary, set `remesh_surface`: the surface is first
//! remeshed isotropically at `edge_length_mm` by baffle-core's label-preserving remesher.
//!
//! Interior surfaces (measurement planes) are handed to gmsh as discrete surfaces embedded
//! in the volume (`Surface{..} In Volume{1}`), so their triangles stay element faces.

use crate::error::MeshError;
use crate::gmsh::{failed, find_gmsh, run_gmsh};
use crate::msh::{read_msh22, surface_msh22_text, MshVolume};
use crate::quality::{quality_report, QualityReport};
use crate::tetmesh::{face_key, FaceSet, TetMesh};
use baffle_core::geometry::mesh::manifold_report;
use baffle_core::geometry::remesh::{remesh_isotropic, RemeshOptions};
use baffle_core::geometry::spatial::TriangleBvh;
use baffle_core::{TriMesh, Vec3};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Points closer than this fraction of the bounding-box diagonal are the same point
/// (interior-surface rims on the boundary; gmsh's 16-digit node coordinates).
pub const POINT_MATCH_TOLERANCE: f64 = 1e-9;

/// Largest accepted |tet volume - enclosed volume| / enclosed volume.
pub const VOLUME_MISMATCH_TOLERANCE: f64 = 1e-8;

#[derive(Clone, Debug, PartialEq)]
pub struct MeshOptions {
    /// Largest tet edge length gmsh aims for (mm): the paper's 1.25 / 0.95 / 0.75.
    pub edge_length_mm: f64,
    /// Largest tet edge where the boundary's own triangles are longer (a graded
    /// extension: gmsh sizes the inside from the boundary's edges); `None`: `edge_length_mm`.
    pub largest_edge_mm: Option<f64>,
    /// gmsh to run; `None`: `$BAFFLE_GMSH`, then `gmsh` on PATH, then the Python wheel.
    pub gmsh_executable: Option<PathBuf>,
    /// Labelled triangle surfaces inside the domain (measurement planes) that must stay
    /// conforming sets of element faces. Their labels must be positive and differ from the
    /// boundary's; their points on the boundary must coincide with boundary points.
    pub interior_surfaces: Vec<TriMesh>,
    /// Keep gmsh's input, script, log and output (their directory is printed to stderr).
    pub keep_temp: bool,
    /// gmsh is stopped after this long; `None`: a limit derived from the expected
    /// number of tetrahedra (see [`gmsh_time_limit`]).
    pub timeout: Option<Duration>,
    /// gmsh threads (`-nt`).
    pub threads: usize,
    /// Remesh the boundary at `edge_length_mm` first (see the module doc); off keeps the
    /// caller's triangles.
    pub remesh_surface: bool,
    /// Also run gmsh's Netgen optimiser (slower; usually fewer slivers).
    pub optimize_netgen: bool,
}

impl Default for MeshOptions {
    fn default() -> Self {
        MeshOptions {
            edge_length_mm: 0.95,
            largest_edge_mm: None,
            gmsh_executable: None,
            interior_surfaces: Vec::new(),
            keep_temp: false,
            timeout: None,
            threads: 2,
            remesh_surface: false,
            optimize_netgen: false,
        }
    }
}

/// Tetrahedral mesh of the closed labelled `surface` (mm), with its quality figures.
/// Errors name the problem: open surface, bad label, gmsh missing or failing, a lost
/// boundary triangle, an inverted or degenerate tet (by index), a volume mismatch.
pub fn mesh_surface(
    surface: &TriMesh,
    opts: &MeshOptions,
) -> Result<(TetMesh, QualityReport), MeshError> {
    check_options(opts)?;
    let expected_tets = check_expected_size(surface, opts)?;
    let boundary = prepared_boundary(surface, opts)?;
    let input = MeshInput::new(&boundary, &opts.interior_surfaces)?;
    let gmsh = find_gmsh(opts.gmsh_executable.as_deref())?;
    let work = WorkDir::create(opts.keep_temp)?;
    let limit = gmsh_time_limit(opts, expected_tets);
    let msh = run_in(&work.path, &input, opts, &gmsh, limit)?;
    let mesh = match assemble(&input, &msh) {
        // gmsh's own optimizer can leave a sliver (p1 with its inflow cap moved 2.5 mm: scaled
        // Jacobian 3e-10); Netgen's optimizer removes slivers, so one more run with it.
        Err(MeshError::DegenerateTet(first)) if !opts.optimize_netgen => {
            let with_netgen = MeshOptions { optimize_netgen: true, ..opts.clone() };
            let msh = run_in(&work.path, &input, &with_netgen, &gmsh, limit)?;
            assemble(&input, &msh).map_err(|e| match e {
                MeshError::DegenerateTet(second) => {
                    MeshError::DegenerateTet(format!("{first}; again with Netgen's optimizer: {second}"))
                }
                e => e,
            })?
        }
        result => result?,
    };
    check_volume(&mesh, input.enclosed_volume_mm3)?;
    let report = quality_report(&mesh)
        .ok_or_else(|| MeshError::InvalidMesh("gmsh produced no tets".into()))?;
    Ok((mesh, report))
}

/// Split one labelled surface into the boundary (every label but `interior_labels`) and
/// one interior surface per interior label, as [`MeshOptions::interior_surfaces`] wants
/// them (e.g. `baffle extend`'s output: the VSD and aortic caps inside the extended
/// domain). Each listed label must be present.
pub fn split_interior_labels(
    surface: &TriMesh,
    interior_labels: &[i32],
) -> Result<(TriMesh, Vec<TriMesh>), MeshError> {
    let interior = interior_labels
        .iter()
        .map(|&label| {
            let part = surface.with_labels(|l| l == label);
            if part.triangles.is_empty() {
                return Err(MeshError::InvalidInput(format!(
                    "no triangle carries the interior label {label}"
                )));
            }
            Ok(part)
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok((surface.with_labels(|l| !interior_labels.contains(&l)), interior))
}

/// Most tetrahedra a mesh may have: the CFD needs about 1.5 kB a tetrahedron (p2's
/// 147k-tet mesh: 224 MB), so 5 million is about 8 GB, and gmsh would take hours.
pub const MAX_TETRAHEDRA: f64 = 5e6;
/// Fewer tetrahedra than this resolve no flow (see [`check_resolves_flow`]).
pub const MIN_TETRAHEDRA: f64 = 100.0;

/// Tetrahedra gmsh makes per regular tetrahedron's volume L^3 / (6 sqrt 2) at a local
/// size L. Measured on gmsh's meshes of p1-p3's extended domains at 0.32-0.95 mm, uniform
/// and graded: 0.54-0.72 (its tets are larger than the regular one of edge L); the upper
/// end, so that the size guard errs towards refusing.
const TETRAHEDRA_PER_REGULAR_VOLUME: f64 = 0.72;

/// Tetrahedra gmsh makes in `volume_mm3` at a local size of `size_mm`.
fn tetrahedra_at(volume_mm3: f64, size_mm: f64) -> f64 {
    TETRAHEDRA_PER_REGULAR_VOLUME * volume_mm3 * 6.0 * std::f64::consts::SQRT_2 / size_mm.powi(3)
}

/// Tetrahedra gmsh makes inside `surface` (mm). gmsh sizes the inside from the boundary
/// triangles, at most `largest_edge_mm` (`None`: `edge_length_mm`) and, where the
/// boundary is finer, at the boundary's size down to `edge_length_mm`. Each boundary
/// triangle is given the cone it spans with the surface's centroid (the cones' signed
/// volumes sum to the enclosed volume) at the size of its mean edge, clamped to that range;
/// the sum is kept between the counts at the largest and at the finest size.
pub fn expected_tetrahedra(surface: &TriMesh, edge_length_mm: f64, largest_edge_mm: Option<f64>) -> f64 {
    let largest_mm = largest_edge_mm.unwrap_or(edge_length_mm).max(edge_length_mm);
    let signed_volume_mm3 = surface.signed_volume_mm3();
    let volume_mm3 = signed_volume_mm3.abs();
    let (finest, coarsest) = (tetrahedra_at(volume_mm3, edge_length_mm), tetrahedra_at(volume_mm3, largest_mm));
    if largest_mm == edge_length_mm || surface.points.is_empty() {
        return finest;
    }
    let centroid = surface.points.iter().sum::<Vec3>() / surface.points.len() as f64;
    let outward = signed_volume_mm3.signum();
    let graded: f64 = surface
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| surface.points[v as usize]);
            let cone_mm3 = outward * (b - a).cross(&(c - a)).dot(&(a - centroid)) / 6.0;
            let size_mm = (((b - a).norm() + (c - b).norm() + (a - c).norm()) / 3.0).max(edge_length_mm).min(largest_mm);
            tetrahedra_at(cone_mm3, size_mm)
        })
        .sum();
    // max/min rather than clamp: no panic on a NaN volume (the input checks name it later).
    graded.max(coarsest).min(finest)
}

/// Refuse, before any work, a mesh too large for the machine (a tiny edge length
/// otherwise runs gmsh until it is killed); returns the expected count.
fn check_expected_size(surface: &TriMesh, opts: &MeshOptions) -> Result<f64, MeshError> {
    let expected = expected_tetrahedra(surface, opts.edge_length_mm, opts.largest_edge_mm);
    if expected > MAX_TETRAHEDRA {
        let volume_mm3 = surface.signed_volume_mm3().abs();
        return Err(MeshError::InvalidInput(format!(
            "an edge length of {} mm{} would need about {expected:.2e} tetrahedra for the {volume_mm3:.0} mm3 \
             enclosed (at most {MAX_TETRAHEDRA:.0e}, about 8 GB for the CFD); use a longer edge",
            opts.edge_length_mm,
            opts.largest_edge_mm.map(|l| format!(" (graded to {l} mm)")).unwrap_or_default()
        )));
    }
    Ok(expected)
}

/// Refuse an edge so long that the mesh resolves no flow (an edge the size of the
/// domain is a typo for a user; small test shapes are meshed coarsely on purpose, so
/// `mesh_surface` itself does not refuse it).
pub fn check_resolves_flow(surface: &TriMesh, edge_length_mm: f64) -> Result<(), MeshError> {
    let volume_mm3 = surface.signed_volume_mm3().abs();
    let expected = tetrahedra_at(volume_mm3, edge_length_mm);
    if expected < MIN_TETRAHEDRA {
        let longest_mm = edge_length_mm * (expected / MIN_TETRAHEDRA).cbrt();
        return Err(MeshError::InvalidInput(format!(
            "an edge length of {edge_length_mm} mm leaves about {expected:.0} tetrahedra for the {volume_mm3:.1} mm3 enclosed \
             (at least {MIN_TETRAHEDRA:.0}): use an edge of at most {longest_mm:.1} mm"
        )));
    }
    Ok(())
}

/// gmsh's time limit: the caller's, or 2 minutes plus 1 ms per expected tetrahedron
/// (gmsh makes tens of thousands a second, so this is generous even on a busy machine).
pub fn gmsh_time_limit(opts: &MeshOptions, expected_tets: f64) -> Duration {
    opts.timeout.unwrap_or_else(|| Duration::from_secs_f64(120.0 + expected_tets / 1000.0))
}

fn check_options(opts: &MeshOptions) -> Result<(), MeshError> {
    if opts.remesh_surface && !opts.interior_surfaces.is_empty() {
        return Err(MeshError::InvalidInput(
            "remeshing the boundary would move it off the interior surfaces' rims; mesh a surface with interior surfaces as given (to refine an extended domain's boundary, remesh its designed domain: `baffle extend --remesh-domain-edge-mm`)".into(),
        ));
    }
    if !(opts.edge_length_mm.is_finite() && opts.edge_length_mm > 0.0) {
        return Err(MeshError::InvalidInput(format!(
            "edge length must be a positive number of mm, got {}",
            opts.edge_length_mm
        )));
    }
    if let Some(largest) = opts.largest_edge_mm.filter(|l| !(l.is_finite() && *l >= opts.edge_length_mm)) {
        return Err(MeshError::InvalidInput(format!(
            "the largest edge must be a length of at least the edge length {} mm, got {largest}",
            opts.edge_length_mm
        )));
    }
    if opts.threads == 0 || opts.timeout.is_some_and(|t| t.is_zero()) {
        return Err(MeshError::InvalidInput(
            "threads and timeout must be positive".into(),
        ));
    }
    Ok(())
}

/// The boundary as gmsh gets it: validated, optionally remeshed, unused points dropped.
fn prepared_boundary(surface: &TriMesh, opts: &MeshOptions) -> Result<TriMesh, MeshError> {
    check_labelled_surface(surface, "surface")?;
    check_closed(surface)?;
    let surface = if opts.remesh_surface {
        let ro = RemeshOptions {
            target_edge_mm: opts.edge_length_mm,
            ..Default::default()
        };
        let remeshed = remesh_isotropic(surface, &ro)
            .map_err(|e| MeshError::InvalidInput(format!("surface remeshing failed: {e}")))?;
        check_closed(&remeshed)?;
        remeshed
    } else {
        surface.clone()
    };
    check_not_self_intersecting(&surface)?;
    Ok(without_unused_points(&surface))
}

/// gmsh fails on a surface that passes through itself with pages of its log; say
/// where instead, before gmsh starts.
fn check_not_self_intersecting(surface: &TriMesh) -> Result<(), MeshError> {
    let bvh = TriangleBvh::new(surface).map_err(MeshError::InvalidInput)?;
    let pairs = bvh.self_intersections_par(surface, |_, _| true);
    let Some(&(a, b)) = pairs.first() else {
        return Ok(());
    };
    let [p, q, r] = surface.triangle_points(a as usize);
    let at = (p + q + r) / 3.0;
    Err(MeshError::InvalidInput(format!(
        "the surface passes through itself: triangles {a} (label {}) and {b} (label {}) cross near \
         ({:.2}, {:.2}, {:.2}) mm ({} crossing pairs in all); gmsh cannot mesh it",
        surface.face_ids[a as usize],
        surface.face_ids[b as usize],
        at.x,
        at.y,
        at.z,
        pairs.len()
    )))
}

fn check_labelled_surface(mesh: &TriMesh, what: &str) -> Result<(), MeshError> {
    if mesh.triangles.is_empty() {
        return Err(MeshError::InvalidInput(format!("{what} has no triangles")));
    }
    if mesh.face_ids.len() != mesh.triangles.len() {
        return Err(MeshError::InvalidInput(format!(
            "{what} has {} face labels for {} triangles",
            mesh.face_ids.len(),
            mesh.triangles.len()
        )));
    }
    if let Some(t) = mesh.face_ids.iter().position(|&id| id <= 0) {
        return Err(MeshError::InvalidInput(format!(
            "{what} triangle {t} has ModelFaceID {}; gmsh needs positive labels",
            mesh.face_ids[t]
        )));
    }
    let n = mesh.points.len();
    if let Some(t) = mesh
        .triangles
        .iter()
        .position(|tri| tri.iter().any(|&i| i as usize >= n))
    {
        return Err(MeshError::InvalidInput(format!(
            "{what} triangle {t} refers to a point beyond its {n} points"
        )));
    }
    if let Some(i) = mesh
        .points
        .iter()
        .position(|p| !p.iter().all(|x| x.is_finite()))
    {
        return Err(MeshError::InvalidInput(format!(
            "{what} point {i} has a non-finite coordinate"
        )));
    }
    Ok(())
}

fn check_closed(surface: &TriMesh) -> Result<(), MeshError> {
    let report = manifold_report(surface);
    if report.is_closed_manifold() && report.inconsistently_wound_edges == 0 {
        return Ok(());
    }
    Err(MeshError::InvalidInput(format!(
        "surface is not a closed, consistently wound manifold: {} boundary edges, {} non-manifold \
         edges, {} degenerate triangles, {} inconsistently wound edges (e.g. edge {:?})",
        report.boundary_edges,
        report.non_manifold_edges,
        report.degenerate_triangles,
        report.inconsistently_wound_edges,
        report.example_edge
    )))
}

fn without_unused_points(mesh: &TriMesh) -> TriMesh {
    let mut keep = vec![false; mesh.points.len()];
    mesh.triangles
        .iter()
        .flatten()
        .for_each(|&i| keep[i as usize] = true);
    let mut new_index = vec![u32::MAX; mesh.points.len()];
    let mut points = Vec::new();
    for (i, p) in mesh.points.iter().enumerate().filter(|(i, _)| keep[*i]) {
        new_index[i] = points.len() as u32;
        points.push(*p);
    }
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| new_index[i as usize]))
        .collect();
    TriMesh {
        points,
        triangles,
        face_ids: mesh.face_ids.clone(),
    }
}

/// Points looked up by position within a tolerance (uniform grid hash).
struct PointIndex {
    cell_mm: f64,
    tolerance_mm: f64,
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl PointIndex {
    fn new(tolerance_mm: f64) -> Self {
        PointIndex {
            cell_mm: tolerance_mm.max(f64::MIN_POSITIVE) * 4.0,
            tolerance_mm,
            cells: HashMap::new(),
        }
    }

    fn cell(&self, p: &Vec3) -> [i64; 3] {
        [p.x, p.y, p.z].map(|c| (c / self.cell_mm).floor() as i64)
    }

    fn find(&self, p: &Vec3, points: &[Vec3]) -> Option<u32> {
        let c = self.cell(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let ids = self.cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]);
                    let hit = ids
                        .into_iter()
                        .flatten()
                        .find(|&&i| (points[i as usize] - p).norm() <= self.tolerance_mm);
                    if let Some(&i) = hit {
                        return Some(i);
                    }
                }
            }
        }
        None
    }

    fn insert(&mut self, p: &Vec3, index: u32) {
        let c = self.cell(p);
        self.cells.entry(c).or_default().push(index);
    }
}

/// Boundary and interior triangles on one shared point list, as gmsh gets them.
struct MeshInput {
    points_mm: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
    labels: Vec<i32>,
    boundary_labels: BTreeSet<i32>,
    interior_labels: BTreeSet<i32>,
    enclosed_volume_mm3: f64,
    index: PointIndex,
}

impl MeshInput {
    fn new(boundary: &TriMesh, interior: &[TriMesh]) -> Result<Self, MeshError> {
        let diagonal_mm = boundary.bbox_diagonal_mm();
        let mut input = MeshInput {
            points_mm: Vec::with_capacity(boundary.points.len()),
            triangles: boundary.triangles.clone(),
            labels: boundary.face_ids.clone(),
            boundary_labels: boundary.face_ids.iter().copied().collect(),
            interior_labels: BTreeSet::new(),
            enclosed_volume_mm3: boundary.signed_volume_mm3().abs(),
            index: PointIndex::new(POINT_MATCH_TOLERANCE * diagonal_mm),
        };
        for (i, p) in boundary.points.iter().enumerate() {
            if let Some(j) = input.index.find(p, &input.points_mm) {
                return Err(MeshError::InvalidInput(format!(
                    "surface points {j} and {i} coincide at {p:?}"
                )));
            }
            input.index.insert(p, i as u32);
            input.points_mm.push(*p);
        }
        for (k, s) in interior.iter().enumerate() {
            input.add_interior(s, k)?;
        }
        Ok(input)
    }

    fn add_interior(&mut self, surface: &TriMesh, k: usize) -> Result<(), MeshError> {
        let what = format!("interior surface {k}");
        check_labelled_surface(surface, &what)?;
        if let Some(id) = surface
            .face_ids
            .iter()
            .find(|id| self.boundary_labels.contains(id))
        {
            return Err(MeshError::InvalidInput(format!(
                "{what} uses ModelFaceID {id}, which the boundary also uses"
            )));
        }
        let map: Vec<u32> = surface.points.iter().map(|p| self.point_id(p)).collect();
        self.triangles
            .extend(surface.triangles.iter().map(|t| t.map(|i| map[i as usize])));
        self.labels.extend_from_slice(&surface.face_ids);
        self.interior_labels
            .extend(surface.face_ids.iter().copied());
        Ok(())
    }

    fn point_id(&mut self, p: &Vec3) -> u32 {
        self.index.find(p, &self.points_mm).unwrap_or_else(|| {
            let i = self.points_mm.len() as u32;
            self.index.insert(p, i);
            self.points_mm.push(*p);
            i
        })
    }

    fn geo_script(&self, opts: &MeshOptions) -> String {
        let join = |s: &BTreeSet<i32>| {
            s.iter()
                .map(|l| l.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        };
        let mut lines = vec![
            "Merge \"surface.msh\";".to_string(),
            format!("Surface Loop(1) = {{{}}};", join(&self.boundary_labels)),
            "Volume(1) = {1};".to_string(),
        ];
        if !self.interior_labels.is_empty() {
            lines.push(format!(
                "Surface{{{}}} In Volume{{1}};",
                join(&self.interior_labels)
            ));
        }
        lines.push("Physical Volume(1) = {1};".into());
        lines.extend([
            format!("Mesh.MeshSizeMax = {:e};", opts.largest_edge_mm.unwrap_or(opts.edge_length_mm)),
            "Mesh.Algorithm3D = 1;".into(),
            "Mesh.Optimize = 1;".into(),
            format!("Mesh.OptimizeNetgen = {};", u8::from(opts.optimize_netgen)),
            "Mesh.ElementOrder = 1;".into(),
            "Mesh.Binary = 0;".into(),
            format!("General.NumThreads = {};", opts.threads),
        ]);
        lines.join("\n") + "\n"
    }
}

/// A scratch directory, removed on drop unless kept.
struct WorkDir {
    path: PathBuf,
    keep: bool,
}

impl WorkDir {
    fn create(keep: bool) -> Result<Self, MeshError> {
        static COUNTER: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let path =
            std::env::temp_dir().join(format!("baffle-mesh-{}-{n}-{nanos}", std::process::id()));
        std::fs::create_dir_all(&path).map_err(|e| MeshError::file(&path, e.to_string()))?;
        if keep {
            eprintln!("baffle-mesh: keeping gmsh files in {}", path.display());
        }
        Ok(WorkDir { path, keep })
    }
}

impl Drop for WorkDir {
    fn drop(&mut self) {
        if !self.keep {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

fn write_file(path: &Path, text: &str) -> Result<(), MeshError> {
    std::fs::write(path, text).map_err(|e| MeshError::file(path, e.to_string()))
}

fn run_in(
    dir: &Path,
    input: &MeshInput,
    opts: &MeshOptions,
    gmsh: &crate::gmsh::GmshCommand,
    time_limit: Duration,
) -> Result<MshVolume, MeshError> {
    write_file(
        &dir.join("surface.msh"),
        &surface_msh22_text(&input.points_mm, &input.triangles, &input.labels),
    )?;
    write_file(&dir.join("domain.geo"), &input.geo_script(opts))?;
    let args: Vec<OsString> = [
        "domain.geo",
        "-3",
        "-format",
        "msh22",
        "-o",
        "volume.msh",
        "-nt",
    ]
    .iter()
    .map(OsString::from)
    .chain([OsString::from(opts.threads.to_string())])
    .collect();
    let log = dir.join("gmsh.log");
    run_gmsh(gmsh, &args, dir, &log, time_limit)?;
    let out = dir.join("volume.msh");
    if !out.is_file() {
        return Err(failed(
            "gmsh exited normally but wrote no volume.msh".into(),
            &log,
        ));
    }
    let msh = read_msh22(&out)?;
    if msh.tets.is_empty() {
        return Err(failed("gmsh wrote no tetrahedra".into(), &log));
    }
    Ok(msh)
}

/// The volume mesh on the input's exact points (input points first, gmsh's new ones
/// after), with the input's triangles as face sets, checked for conformity.
fn assemble(input: &MeshInput, msh: &MshVolume) -> Result<TetMesh, MeshError> {
    let node_to_point = map_nodes(input, msh)?;
    let tag_index = msh.node_index();
    let lookup = |tag: &u64| -> Result<u32, MeshError> {
        tag_index
            .get(tag)
            .map(|&i| node_to_point[i as usize])
            .ok_or_else(|| {
                MeshError::InvalidMesh(format!("gmsh element refers to unknown node {tag}"))
            })
    };
    let mut points_mm = input.points_mm.clone();
    points_mm.extend(
        msh.nodes_mm
            .iter()
            .zip(&node_to_point)
            .filter(|(_, &p)| p as usize >= input.points_mm.len())
            .map(|(x, _)| *x),
    );
    let tets = msh
        .tets
        .iter()
        .map(|t| {
            Ok([
                lookup(&t[0])?,
                lookup(&t[1])?,
                lookup(&t[2])?,
                lookup(&t[3])?,
            ])
        })
        .collect::<Result<Vec<_>, MeshError>>()?;
    let gmsh_faces = msh
        .triangles
        .iter()
        .map(|(label, t)| {
            Ok((
                face_key(&[lookup(&t[0])?, lookup(&t[1])?, lookup(&t[2])?]),
                *label,
            ))
        })
        .collect::<Result<HashMap<_, _>, MeshError>>()?;
    check_faces_kept(input, &gmsh_faces, msh.triangles.len())?;
    let mut mesh = TetMesh {
        points_mm,
        tets,
        faces: face_sets(input),
    };
    mesh.check_positive_volumes()?;
    mesh.orient_boundary_outward()?;
    mesh.validate()?;
    Ok(mesh)
}

/// For each gmsh node, its point index: the input point at its position, else a new
/// index after the input points. Every input point must be matched exactly once.
fn map_nodes(input: &MeshInput, msh: &MshVolume) -> Result<Vec<u32>, MeshError> {
    let n_input = input.points_mm.len();
    let mut matched_by: Vec<Option<u64>> = vec![None; n_input];
    let mut next_new = n_input as u32;
    let mut map = Vec::with_capacity(msh.nodes_mm.len());
    for (tag, p) in msh.node_tags.iter().zip(&msh.nodes_mm) {
        let index = match input.index.find(p, &input.points_mm) {
            Some(i) => {
                if let Some(other) = matched_by[i as usize].replace(*tag) {
                    return Err(MeshError::InvalidMesh(format!(
                        "gmsh nodes {other} and {tag} both lie on input point {i}"
                    )));
                }
                i
            }
            None => {
                next_new += 1;
                next_new - 1
            }
        };
        map.push(index);
    }
    if let Some(i) = matched_by.iter().position(|m| m.is_none()) {
        return Err(MeshError::InvalidMesh(format!(
            "input point {i} at {:?} is missing from gmsh's mesh",
            input.points_mm[i]
        )));
    }
    Ok(map)
}

/// gmsh must return exactly the input triangles, each with its label.
fn check_faces_kept(
    input: &MeshInput,
    gmsh_faces: &HashMap<[u32; 3], i32>,
    gmsh_count: usize,
) -> Result<(), MeshError> {
    for (k, (tri, label)) in input.triangles.iter().zip(&input.labels).enumerate() {
        match gmsh_faces.get(&face_key(tri)) {
            Some(l) if l == label => {}
            Some(l) => {
                return Err(MeshError::InvalidMesh(format!("input triangle {k} {tri:?} came back with label {l}, not {label}")))
            }
            None => {
                return Err(MeshError::InvalidMesh(format!(
                    "input triangle {k} {tri:?} (ModelFaceID {label}) is not in gmsh's mesh (surface was altered)"
                )))
            }
        }
    }
    if gmsh_count != input.triangles.len() {
        return Err(MeshError::InvalidMesh(format!(
            "gmsh returned {gmsh_count} surface triangles for {} input triangles",
            input.triangles.len()
        )));
    }
    Ok(())
}

fn face_sets(input: &MeshInput) -> Vec<FaceSet> {
    let mut sets: BTreeMap<i32, Vec<[u32; 3]>> = BTreeMap::new();
    for (tri, label) in input.triangles.iter().zip(&input.labels) {
        sets.entry(*label).or_default().push(*tri);
    }
    sets.into_iter()
        .map(|(id, triangles)| FaceSet {
            id,
            triangles,
            interior: input.interior_labels.contains(&id),
        })
        .collect()
}

fn check_volume(mesh: &TetMesh, enclosed_mm3: f64) -> Result<(), MeshError> {
    let tets_mm3 = mesh.volume_mm3();
    let relative = (tets_mm3 - enclosed_mm3).abs() / enclosed_mm3.max(f64::MIN_POSITIVE);
    if relative > VOLUME_MISMATCH_TOLERANCE {
        return Err(MeshError::InvalidMesh(format!(
            "tets fill {tets_mm3} mm^3 but the surface encloses {enclosed_mm3} mm^3 (relative difference {relative:e})"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn open_box() -> TriMesh {
        let p = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z()];
        TriMesh::new(p, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2]], vec![2; 3])
    }

    #[test]
    fn open_surface_is_rejected_before_gmsh_runs() {
        let opts = MeshOptions {
            gmsh_executable: Some("/nonexistent/gmsh".into()),
            ..Default::default()
        };
        let err = mesh_surface(&open_box(), &opts).unwrap_err().to_string();
        assert!(err.contains("3 boundary edges"), "{err}");
    }

    #[test]
    fn an_edge_as_long_as_the_domain_is_refused_with_the_longest_that_works() {
        let closed = closed_tet();
        // 1/6 mm3: about 100 tetrahedra at an edge of 0.2 mm.
        assert!(check_resolves_flow(&closed, 0.1).is_ok());
        let err = check_resolves_flow(&closed, 1.0).unwrap_err().to_string();
        assert!(err.contains("leaves about 1 tetrahedra for the 0.2 mm3") && err.contains("at most 0.2 mm"), "{err}");
        // The suggested edge is the one that gives the minimum.
        assert!(check_resolves_flow(&closed, 0.215).is_ok() && check_resolves_flow(&closed, 0.22).is_err());
    }

    #[test]
    fn a_graded_count_follows_the_boundarys_own_size_between_the_uniform_ones() {
        let closed = closed_tet();
        let at = |edge: f64, largest: Option<f64>| expected_tetrahedra(&closed, edge, largest);
        // Its edges (1 and sqrt 2 mm) are coarser than 0.1 mm: gmsh would grade up to them.
        let graded = at(0.1, Some(10.0));
        assert!(at(1.3, None) < graded && graded < at(1.1, None), "{graded}");
        // The largest edge caps the boundary's size; without grading the edge rules.
        assert!((at(0.1, Some(1.0)) - at(1.0, None)).abs() < 1e-9 * at(1.0, None));
        assert_eq!(at(0.1, Some(0.1)), at(0.1, None));
        // No panic on a value the option checks refuse later.
        assert!(!at(0.1, Some(f64::NAN)).is_nan());
    }

    #[test]
    fn bad_options_and_labels_are_rejected() {
        let mut closed = closed_tet();
        let opts = MeshOptions {
            edge_length_mm: -1.0,
            ..Default::default()
        };
        assert!(mesh_surface(&closed, &opts)
            .unwrap_err()
            .to_string()
            .contains("positive number of mm"));
        closed.face_ids[1] = 0;
        let err = mesh_surface(&closed, &MeshOptions::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("triangle 1 has ModelFaceID 0"), "{err}");
        // Remeshing with interior surfaces is refused, naming the way that works.
        closed.face_ids[1] = 2;
        let plane = TriMesh::new(vec![Vec3::x(), Vec3::y(), Vec3::z()], vec![[0, 1, 2]], vec![20]);
        let opts = MeshOptions { remesh_surface: true, interior_surfaces: vec![plane], ..Default::default() };
        let err = mesh_surface(&closed, &opts).unwrap_err().to_string();
        assert!(err.contains("baffle extend --remesh-domain-edge-mm"), "{err}");
        // A largest edge below the edge length (or not a length) is refused.
        for largest in [0.5, f64::NAN] {
            let opts = MeshOptions { largest_edge_mm: Some(largest), ..Default::default() };
            let err = mesh_surface(&closed, &opts).unwrap_err().to_string();
            assert!(err.contains("largest edge must be a length of at least the edge length 0.95 mm"), "{err}");
        }
    }

    #[test]
    fn interior_points_merge_onto_boundary_points_and_labels_must_differ() {
        let closed = closed_tet();
        let plane = TriMesh::new(
            vec![Vec3::x(), Vec3::y(), Vec3::new(0.2, 0.2, 0.2)],
            vec![[0, 1, 2]],
            vec![20],
        );
        let input = MeshInput::new(&closed, std::slice::from_ref(&plane)).unwrap();
        assert_eq!(input.points_mm.len(), 5);
        assert_eq!(input.triangles.last(), Some(&[1, 2, 4]));
        let clash = TriMesh {
            face_ids: vec![2],
            ..plane
        };
        assert!(MeshInput::new(&closed, &[clash]).is_err());
    }

    #[test]
    fn interior_labels_are_split_off_and_must_be_present() {
        let mut cube = unit_cube();
        cube.face_ids[0] = 11;
        let (boundary, interior) = split_interior_labels(&cube, &[11]).unwrap();
        assert_eq!(
            (
                boundary.triangles.len(),
                interior.len(),
                interior[0].triangles.len()
            ),
            (cube.triangles.len() - 1, 1, 1)
        );
        let err = split_interior_labels(&cube, &[16]).unwrap_err().to_string();
        assert!(err.contains("16"), "{err}");
        let opts = MeshOptions {
            remesh_surface: true,
            interior_surfaces: interior,
            ..MeshOptions::default()
        };
        assert!(check_options(&opts)
            .unwrap_err()
            .to_string()
            .contains("interior"));
    }

    /// A unit cube of 12 triangles labelled 1.
    fn unit_cube() -> TriMesh {
        let points = (0..8)
            .map(|i| Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
            .collect();
        let triangles = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        TriMesh::new(points, triangles, vec![1; 12])
    }

    #[test]
    fn geo_script_embeds_interior_surfaces() {
        let mut closed = closed_tet();
        closed.face_ids = vec![2, 11, 16, 2];
        let plane = TriMesh::new(
            vec![Vec3::x(), Vec3::y(), Vec3::new(0.2, 0.2, 0.2)],
            vec![[0, 1, 2]],
            vec![20],
        );
        let input = MeshInput::new(&closed, &[plane]).unwrap();
        let geo = input.geo_script(&MeshOptions::default());
        assert!(geo.contains("Surface Loop(1) = {2, 11, 16};"), "{geo}");
        assert!(geo.contains("Surface{20} In Volume{1};"), "{geo}");
        assert!(geo.contains("Mesh.MeshSizeMax = 9.5e-1;"), "{geo}");
        // A graded boundary: gmsh may grow the inside to the largest edge.
        let graded = input.geo_script(&MeshOptions { largest_edge_mm: Some(2.375), ..MeshOptions::default() });
        assert!(graded.contains("Mesh.MeshSizeMax = 2.375e0;"), "{graded}");
    }

    /// A stand-in for gmsh: answers `--version`, then runs `body` (sh).
    #[cfg(unix)]
    fn fake_gmsh(name: &str, body: &str) -> PathBuf {
        use std::os::unix::fs::PermissionsExt;
        let dir =
            std::env::temp_dir().join(format!("baffle-mesh-fake-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("gmsh");
        let script =
            format!("#!/bin/sh\nif [ \"$1\" = --version ]; then echo 4.15.2; exit 0; fi\n{body}\n");
        std::fs::write(&path, script).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        path
    }

    fn closed_tet() -> TriMesh {
        let mut closed = open_box();
        closed.triangles.push([1, 2, 3]);
        closed.face_ids.push(2);
        closed
    }

    #[test]
    fn a_surface_through_itself_is_named_before_gmsh_runs() {
        // Two closed tetrahedra in one surface, the second shifted into the first.
        let (a, mut b) = (closed_tet(), closed_tet());
        b.points.iter_mut().for_each(|p| *p += Vec3::new(0.2, 0.2, 0.2));
        let offset = a.points.len() as u32;
        let mut both = a.clone();
        both.points.extend(b.points);
        both.triangles.extend(b.triangles.iter().map(|t| t.map(|i| i + offset)));
        both.face_ids.extend(b.face_ids);
        let opts = MeshOptions {
            gmsh_executable: Some("/nonexistent/gmsh".into()),
            ..Default::default()
        };
        let err = mesh_surface(&both, &opts).unwrap_err().to_string();
        assert!(err.contains("passes through itself") && err.contains("cross near ("), "{err}");
    }

    #[cfg(unix)]
    #[test]
    fn failing_gmsh_is_reported_with_its_log() {
        let fake = fake_gmsh("fails", "echo 'Error   : No elements in volume 1'; exit 1");
        let err = mesh_closed_tet_with(fake, None).unwrap_err().to_string();
        assert!(
            err.contains("gmsh exited with") && err.contains("No elements in volume 1"),
            "{err}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn hanging_gmsh_is_stopped_at_the_timeout() {
        let fake = fake_gmsh("hangs", "sleep 30");
        let start = std::time::Instant::now();
        let err = mesh_closed_tet_with(fake, Some(Duration::from_millis(300))).unwrap_err().to_string();
        assert!(err.contains("did not finish within"), "{err}");
        assert!(start.elapsed() < Duration::from_secs(10));
    }

    /// gmsh's output for `closed_tet`: the tet itself, or (`sliver`) split at a node
    /// 1e-11 mm inside its base, whose tet on the base is flat (volume ~2e-12 mm^3).
    fn closed_tet_msh(sliver: bool) -> String {
        let (nodes, tets) = if sliver {
            ("5\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 0.3333333333 0.3333333333 1e-11\n", "5 4 2 1 1 1 2 3 5\n6 4 2 1 1 5 2 3 4\n7 4 2 1 1 1 5 3 4\n8 4 2 1 1 1 2 5 4\n")
        } else {
            ("4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n", "5 4 2 1 1 1 2 3 4\n")
        };
        let elements = if sliver { 8 } else { 5 };
        format!(
            "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{nodes}$EndNodes\n$Elements\n{elements}\n\
             1 2 2 2 2 1 3 2\n2 2 2 2 2 1 2 4\n3 2 2 2 2 1 4 3\n4 2 2 2 2 2 3 4\n{tets}$EndElements\n"
        )
    }

    /// `closed_tet` meshed by the program `gmsh` (a fake one) with the given time limit,
    /// the other options at their defaults.
    #[cfg(unix)]
    fn mesh_closed_tet_with(gmsh: PathBuf, timeout: Option<Duration>) -> Result<(TetMesh, QualityReport), MeshError> {
        mesh_surface(&closed_tet(), &MeshOptions { gmsh_executable: Some(gmsh), timeout, ..Default::default() })
    }

    /// A fake gmsh writing `without` unless the script turns Netgen's optimizer on.
    fn gmsh_by_optimizer(name: &str, without: &str, with_netgen: &str) -> PathBuf {
        let print = |msh: &str| format!("printf '{}' > volume.msh", msh.replace('\n', "\\n"));
        fake_gmsh(
            name,
            &format!("if grep -q 'OptimizeNetgen = 1' domain.geo; then {}; else {}; fi", print(with_netgen), print(without)),
        )
    }

    #[cfg(unix)]
    #[test]
    fn a_sliver_from_gmsh_is_meshed_again_with_netgens_optimizer() {
        let fake = gmsh_by_optimizer("sliver-then-good", &closed_tet_msh(true), &closed_tet_msh(false));
        let (mesh, _) = mesh_closed_tet_with(fake, None).unwrap();
        assert_eq!(mesh.tets.len(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn a_sliver_left_by_both_optimizers_is_named_with_its_place() {
        let fake = gmsh_by_optimizer("sliver-twice", &closed_tet_msh(true), &closed_tet_msh(true));
        let err = mesh_closed_tet_with(fake, None).unwrap_err().to_string();
        assert!(err.contains("is degenerate") && err.contains("near (0.33, 0.33, 0.00) mm") && err.contains("again with Netgen"), "{err}");
    }

    #[cfg(unix)]
    #[test]
    fn gmsh_output_with_an_inverted_tet_is_rejected() {
        // The "mesh" gmsh returns is the one tet of the input, inverted (nodes 2 and 3 swapped).
        let msh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n\
                   $Elements\n5\n1 2 2 2 2 1 3 2\n2 2 2 2 2 1 2 4\n3 2 2 2 2 1 4 3\n4 2 2 2 2 2 3 4\n5 4 2 1 1 1 3 2 4\n$EndElements\n";
        let fake = fake_gmsh(
            "inverted",
            &format!("printf '{}' > volume.msh", msh.replace('\n', "\\n")),
        );
        let err = mesh_closed_tet_with(fake, None).unwrap_err().to_string();
        assert!(err.contains("tet 0") && err.contains("inverted"), "{err}");
    }
}
