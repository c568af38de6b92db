//! `baffle extend`: the extended CFD domain (paper section 2.5): the designed domain
//! plus the LV back to a mid-LV plane and the aortic root up to the sinotubular
//! junction, with inflow and outflow caps; the VSD and aortic caps stay inside it as
//! measurement planes.

use crate::error::PlanError;
use crate::prepare_cmd::{read_pools, report_path, PrepareSource};
use crate::files::write_atomic;
use baffle_core::io::{read_surface_labeled, write_trimesh_vtp};
use baffle_core::FaceLabels;
use baffle_prepare::extend::{extend, ExtendOptions, ExtensionGrading, ExtendReport, StjOptions, INFLOW_CAP_LABEL, OUTFLOW_CAP_LABEL};
use baffle_prepare::PrepareOptions;
use crate::progress::Progress;
use std::path::PathBuf;

documented_settings! {
pub struct ExtendSettings {
    /// Designed domain (domain.vtp from `baffle design`): closed, mm, ModelFaceID.
    pub domain: PathBuf,
    /// The LV and aorta blood pools (the RV is read too, as `prepare` reads them).
    pub source: PrepareSource,
    /// Output extended surface (.vtp): the designed domain's faces unchanged (its VSD and
    /// aortic caps now inside: mesh with `baffle mesh --interior-labels 11,16`), the LV
    /// and aortic walls (wall label), the inflow and outflow caps. The report
    /// (<stem>-report.json) is written beside it.
    pub out: PathBuf,
    /// ModelFaceID of the new inflow cap (mid-LV plane).
    pub inflow_label: i32,
    /// ModelFaceID of the new outflow cap (sinotubular junction).
    pub outflow_label: i32,
    /// ModelFaceIDs of the domain's walls (the extension's walls get it too), baffle, VSD
    /// and aortic-annulus caps.
    pub labels: FaceLabels,
    /// Voxel edge of the union grid the LV and aorta are cut from (mm).
    pub voxel_mm: f64,
    /// Target edge of the extension's triangles (mm); default: the designed caps' rim edge.
    pub remesh_edge_mm: Option<f64>,
    /// Remesh the designed domain at this edge (mm; labels and rims kept, as `baffle mesh
    /// --remesh-surface`) before extending, and the extension at the same edge unless
    /// --remesh-edge-mm says otherwise: the whole boundary at one size with the measurement
    /// planes conforming, for a mesh study that refines the boundary too (the interior caps
    /// share their rims with the boundary, so `baffle mesh` cannot remesh an extended domain).
    pub remesh_domain_edge_mm: Option<f64>,
    // The margin and the growth are EXTENSION_MARGIN_DIAMETERS and EXTENSION_GROWTH.
    /// Coarsen the LV and aortic parts away from the designed caps, up to this many times
    /// the edge (within one cap diameter of each cap the edge stays, then grows 0.2 mm
    /// per mm); 1: the edge everywhere. Mesh the result with `baffle mesh
    /// --largest-edge-mm` at this many times the edge length.
    pub extension_coarsening: f64,
    /// Move the inflow cap (mid-LV plane) this far (mm) from the LV volume centroid along
    /// the VSD normal (positive: away from the VSD, toward the apex), for a sensitivity
    /// study; an offset that leaves no clean cut of the LV is an error (no fallback).
    /// Default: through the centroid, moved only when that cut is not clean.
    pub inflow_offset_mm: Option<f64>,
    /// Put the outflow cap this many annulus diameters above the annulus instead of at the
    /// sinotubular junction (the STJ search still runs and is reported), for a sensitivity
    /// study of the outflow length; a height past the aortic root's sections is an error.
    pub outflow_diameters: Option<f64>,
    /// The domain has no baffle (no triangle of --baffle-label), and is to be extended
    /// as it is (e.g. a capped ventricle, for a pre-repair flow). Without it such a
    /// domain is refused: `baffle extend` expects `baffle design`'s domain.
    pub no_baffle: bool,
}
}

impl Default for ExtendSettings {
    fn default() -> Self {
        ExtendSettings {
            domain: PathBuf::new(),
            source: PrepareSource::default(),
            out: PathBuf::new(),
            inflow_label: INFLOW_CAP_LABEL,
            outflow_label: OUTFLOW_CAP_LABEL,
            labels: FaceLabels::default(),
            voxel_mm: PrepareOptions::default().voxel_mm,
            remesh_edge_mm: None,
            remesh_domain_edge_mm: None,
            extension_coarsening: 1.0,
            inflow_offset_mm: None,
            outflow_diameters: None,
            no_baffle: false,
        }
    }
}

/// `baffle extend`, shown and said on `progress`.
pub fn run_extend(args: &ExtendSettings, progress: &Progress) -> Result<(), PlanError> {
    let result = progress.while_running("extend", || extend_to_file(args));
    progress.finish(None);
    let (r, report) = result?;
    progress.say(&format!(
        "{} triangles ({} designed), {:.0} mm3 (designed {:.0}); inflow cap {:.1} mm2 {:.1} mm beyond the VSD, outflow cap {:.1} mm2 {:.1} mm above the annulus; baffle area change {:+.2e}",
        r.triangles, r.designed_triangles, r.volume_mm3, r.designed_volume_mm3, r.inflow_cap.area_mm2, r.mid_lv_plane.distance_from_vsd_mm,
        r.outflow_cap.area_mm2, r.stj.distance_from_annulus_mm, r.baffle_area_relative_change
    ));
    let m = &r.mid_lv_plane;
    progress.say(&format!("inflow: {}, {:.1} mm beyond the VSD (moved {:+.0} mm from the LV centroid); the LV part with {}", m.rule, m.distance_from_vsd_mm, m.moved_from_centroid_mm, m.rv_in_lv_part));
    if let Some(contact) = &m.other_lv_rv_contact {
        progress.say(&format!("note: {contact}"));
    }
    progress.say(&format!("outflow: {}", r.stj.note));
    progress.say(&format!("wrote {}, {}", args.out.display(), report.display()));
    Ok(())
}

/// Where the extension keeps the designed rims' edge: one cap diameter from each cap
/// covers the LV flow converging into the VSD and the jet leaving the annulus, whose
/// pressure the measurement planes average.
pub const EXTENSION_MARGIN_DIAMETERS: f64 = 1.0;
/// How fast the extension's edge grows beyond (mm per mm): neighbouring triangles then
/// differ by at most a fifth, and gmsh's tetrahedra grade as smoothly.
pub const EXTENSION_GROWTH: f64 = 0.2;

/// The grading of `--extension-coarsening` (`None` at 1: one edge everywhere).
fn extension_grading(coarsening: f64) -> Result<Option<ExtensionGrading>, String> {
    if !(coarsening.is_finite() && coarsening >= 1.0) {
        return Err(format!("--extension-coarsening must be at least 1 (times the edge), got {coarsening}"));
    }
    Ok((coarsening > 1.0).then_some(ExtensionGrading { margin_diameters: EXTENSION_MARGIN_DIAMETERS, growth: EXTENSION_GROWTH, largest_ratio: coarsening }))
}

/// Build the extended domain and write it and its report (each whole or not at all).
pub fn extend_to_file(args: &ExtendSettings) -> Result<(ExtendReport, PathBuf), PlanError> {
    extend_and_write(args).map_err(PlanError::Extend)
}

/// The extended domain of `args` and its report written (its errors as messages).
fn extend_and_write(args: &ExtendSettings) -> Result<(ExtendReport, PathBuf), String> {
    let labeled = read_surface_labeled(&args.domain).map_err(|e| e.to_string())?;
    if !labeled.has_model_face_id {
        return Err(format!("{}: no ModelFaceID cell array; the designed domain's caps need their labels", args.domain.display()));
    }
    let pools = read_pools(&args.source)?;
    let options = ExtendOptions {
        union: PrepareOptions { voxel_mm: args.voxel_mm, ..PrepareOptions::default() },
        labels: args.labels,
        inflow_label: args.inflow_label,
        outflow_label: args.outflow_label,
        remesh_edge_mm: args.remesh_edge_mm.or(args.remesh_domain_edge_mm),
        remesh_domain_edge_mm: args.remesh_domain_edge_mm,
        stj: StjOptions { fixed_diameters: args.outflow_diameters, ..StjOptions::default() },
        inflow_offset_mm: args.inflow_offset_mm,
        without_baffle: args.no_baffle,
        grading: extension_grading(args.extension_coarsening)?,
        ..ExtendOptions::default()
    };
    let extended = extend(&labeled.mesh, &pools, &options).map_err(|e| format!("{}: {e}", args.domain.display()))?;
    crate::files::create_parent_dir(&args.out)?;
    write_trimesh_vtp(&args.out, &extended.surface).map_err(|e| e.to_string())?;
    let report = report_path(&args.out);
    let text = serde_json::to_string_pretty(&extended.report).map_err(|e| e.to_string())?;
    if let Err(e) = write_atomic(&report, text.as_bytes()) {
        let _ = std::fs::remove_file(&args.out);
        return Err(e);
    }
    Ok((extended.report, report))
}
