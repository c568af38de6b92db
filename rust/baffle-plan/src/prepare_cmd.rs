//! `baffle prepare`: the capped ventricle (design input) from segmented blood
//! pools (paper section 2.2.2).

use crate::error::PlanError;
use baffle_core::io::write_trimesh_vtp;
use baffle_core::FaceLabels;
use crate::files::write_atomic;
use baffle_core::TriMesh;
use baffle_prepare::{
    pools_from_labelmap, prepare, pulmonary_from_labelmap, read_labelmap, read_segmentations, BloodPools, LabelMap, LabelSurfaceOptions, PoolLabels, PrepareOptions,
    PrepareReport,
};
use crate::progress::Progress;
use std::path::{Path, PathBuf};

documented_settings! {
/// Where the blood pools come from: per-structure surfaces or a label map (also
/// `baffle plan`'s arguments for its prepare stage).
#[derive(Clone, Debug)]
pub struct PrepareSource {
    /// Folder of closed per-structure surfaces in mm: LV, RV and aorta (.vtp, .vtk or .stl).
    pub segmentations: Option<PathBuf>,
    /// Multi-label label map (.nrrd, .nii, .nii.gz); labels LV 1, RV 2, LA 3, RA 4,
    /// myo 5, aorta 6, PA 7 unless remapped. Surfaces are made in LPS mm.
    pub labelmap: Option<PathBuf>,
    /// Label value of the LV blood pool in --labelmap.
    pub lv_label: i32,
    /// Label value of the RV blood pool in --labelmap.
    pub rv_label: i32,
    /// Label value of the aorta in --labelmap.
    pub aorta_label: i32,
    /// Label value of the pulmonary artery in --labelmap: its surface is written beside
    /// the capped ventricle (<stem>-pulmonary.vtp) and ends the RV outflow path. A label
    /// map without it still prepares; the RV outflow is then not measured.
    pub pulmonary_label: i32,
    /// Skip the 3x3x3 median filter of each --labelmap label mask.
    pub no_median: bool,
}
}

/// The label map's pulmonary artery label by default (the convention: PA 7).
pub const PULMONARY_LABEL: i32 = 7;

impl Default for PrepareSource {
    fn default() -> Self {
        let pools = PoolLabels::default();
        PrepareSource {
            segmentations: None,
            labelmap: None,
            lv_label: pools.lv,
            rv_label: pools.rv,
            aorta_label: pools.aorta,
            pulmonary_label: PULMONARY_LABEL,
            no_median: false,
        }
    }
}

impl PrepareSource {
    /// Whether a segmentation folder or a label map was given.
    pub fn is_given(&self) -> bool {
        self.segmentations.is_some() || self.labelmap.is_some()
    }

    /// The pulmonary artery's surface, where there is one: in --segmentations, or the one
    /// prepare made from --labelmap beside the capped ventricle `prepared`.
    pub fn pulmonary_surface(&self, prepared: &Path) -> Option<PathBuf> {
        match (&self.segmentations, &self.labelmap) {
            (Some(dir), _) => baffle_prepare::input::pulmonary_file(dir),
            (None, Some(_)) => Some(pulmonary_path(prepared)).filter(|p| p.is_file()),
            (None, None) => None,
        }
    }

    fn pool_labels(&self) -> PoolLabels {
        PoolLabels { lv: self.lv_label, rv: self.rv_label, aorta: self.aorta_label }
    }

    fn label_options(&self) -> LabelSurfaceOptions {
        LabelSurfaceOptions { median: !self.no_median, ..LabelSurfaceOptions::default() }
    }
}

documented_settings! {
pub struct PrepareSettings {
    pub source: PrepareSource,
    /// Output capped ventricle (.vtp): ModelFaceID 2 RV wall, 11 VSD cap, 16 aortic cap.
    /// A report (<stem>-report.json) is written beside it.
    pub out: PathBuf,
    /// Voxel edge of the union grid (mm).
    pub voxel_mm: f64,
    /// Margin of the union grid around the RV (mm); the LV and aorta beyond it are cut off.
    pub crop_margin_mm: f64,
    /// Radius of the morphological closing of the union mask (mm).
    pub closing_radius_mm: f64,
    /// Target edge of the final isotropic remesh (mm).
    pub remesh_edge_mm: f64,
    /// Keep the contour's triangles (no final remesh).
    pub no_remesh: bool,
    /// Taubin smoothing iterations of the union surface.
    pub smoothing_iterations: usize,
}
}

/// The defaults are `baffle_prepare`'s own (`PrepareOptions::default()`).
impl Default for PrepareSettings {
    fn default() -> Self {
        let o = PrepareOptions::default();
        PrepareSettings {
            source: PrepareSource::default(),
            out: PathBuf::new(),
            voxel_mm: o.voxel_mm,
            crop_margin_mm: o.crop_margin_mm,
            closing_radius_mm: o.closing_radius_mm,
            remesh_edge_mm: o.remesh_edge_mm.unwrap_or_default(),
            no_remesh: o.remesh_edge_mm.is_none(),
            smoothing_iterations: o.smoothing.iterations,
        }
    }
}

/// `baffle prepare`, shown and said on `progress`.
pub fn run_prepare(args: &PrepareSettings, progress: &Progress) -> Result<(), PlanError> {
    let result = progress.while_running("prepare", || prepare_to_file(args, progress));
    progress.finish(None);
    let (report, report_path) = result?;
    progress.say(&format!(
        "{} triangles, {:.0} mm3; VSD cap {:.1} mm2, aortic cap {:.1} mm2; {:.0} ms",
        report.triangles, report.volume_mm3, report.vsd_cap.area_mm2, report.aortic_cap.area_mm2, report.timings.total_ms
    ));
    // The caps' distance from the true interfaces when the cuts had to be moved apart.
    progress.say(&report.separation.summary());
    // A failed check is an error before anything is written: here they all passed.
    progress.say(&format!("{} self-checks passed (each cap's centroid, area and rim against the segmentations' opening; listed in the report)", report.checks.len()));
    let pulmonary = Some(pulmonary_path(&args.out)).filter(|p| args.source.labelmap.is_some() && p.is_file());
    let pulmonary = pulmonary.map(|p| format!(", {}", p.display())).unwrap_or_default();
    progress.say(&format!("wrote {}, {}{pulmonary}", args.out.display(), report_path.display()));
    Ok(())
}

/// The report written beside the capped ventricle `out`: `<stem>-report.json`.
pub fn report_path(out: &Path) -> PathBuf {
    PathBuf::from(format!("{}-report.json", out.with_extension("").display()))
}

/// The pulmonary artery's surface from a label map, beside the capped ventricle `out`:
/// `<stem>-pulmonary.vtp`.
pub fn pulmonary_path(out: &Path) -> PathBuf {
    PathBuf::from(format!("{}-pulmonary.vtp", out.with_extension("").display()))
}

/// Build the capped ventricle and write it and its report (each written whole or
/// not at all); returns the report and its path.
pub fn prepare_to_file(args: &PrepareSettings, progress: &Progress) -> Result<(PrepareReport, PathBuf), PlanError> {
    prepare_and_write(args, progress).map_err(PlanError::Prepare)
}

/// The capped ventricle and its report written; a note on `progress` when a label map has no pulmonary artery.
fn prepare_and_write(args: &PrepareSettings, progress: &Progress) -> Result<(PrepareReport, PathBuf), String> {
    let (pools, pulmonary) = read_inputs(&args.source)?;
    let mut options = PrepareOptions {
        voxel_mm: args.voxel_mm,
        crop_margin_mm: args.crop_margin_mm,
        closing_radius_mm: args.closing_radius_mm,
        remesh_edge_mm: (!args.no_remesh).then_some(args.remesh_edge_mm),
        labels: FaceLabels::default(),
        ..PrepareOptions::default()
    };
    options.smoothing.iterations = args.smoothing_iterations;
    let (mesh, report) = prepare(&pools, &options).map_err(|e| e.to_string())?;
    crate::files::create_parent_dir(&args.out)?;
    // write_trimesh_vtp writes through a temporary name and renames: atomic already.
    write_trimesh_vtp(&args.out, &mesh).map_err(|e| e.to_string())?;
    let report_path = report_path(&args.out);
    let text = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    if let Err(e) = write_atomic(&report_path, text.as_bytes()) {
        // A capped ventricle without its report is half a result: keep neither.
        let _ = std::fs::remove_file(&args.out);
        return Err(e);
    }
    if let Some(pulmonary) = pulmonary {
        write_pulmonary(&args.out, pulmonary.as_ref(), args.source.pulmonary_label, progress)?;
    }
    Ok((report, report_path))
}

/// The label map's pulmonary artery beside the capped ventricle `out`; without it, no
/// such file (not one left from an earlier run) and a note.
fn write_pulmonary(out: &Path, pulmonary: Option<&TriMesh>, label: i32, progress: &Progress) -> Result<(), String> {
    let path = pulmonary_path(out);
    match pulmonary {
        Some(mesh) => write_trimesh_vtp(&path, mesh).map_err(|e| e.to_string()),
        None => {
            progress.say(&format!("note: no voxel of the label map has the pulmonary artery's label {label} (--pulmonary-label): the RV outflow will not be measured"));
            match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(format!("{}: {e}", path.display())),
                _ => Ok(()),
            }
        }
    }
}

/// `baffle phantom --heart`: the synthetic heart's segment surfaces and suture points in `out`.
pub fn write_synthetic_heart(out: &Path, progress: &Progress) -> Result<(), PlanError> {
    synthetic_heart_files(out, progress).map_err(PlanError::Phantom)
}

/// The synthetic heart's files in `out`, said on `progress`.
fn synthetic_heart_files(out: &Path, progress: &Progress) -> Result<(), String> {
    let heart = baffle_prepare::shapes::synthetic_heart();
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    for (name, surface) in [("LV.vtp", &heart.lv), ("RV.vtp", &heart.rv), ("aorta.vtp", &heart.aorta)] {
        write_trimesh_vtp(&out.join(name), surface).map_err(|e| e.to_string())?;
    }
    let points = out.join("suture_points.mrk.json");
    baffle_core::io::write_markups_closed_curve(&points, "BC", &heart.suture_points_mm, baffle_core::io::CoordinateSystem::Lps)
        .map_err(|e| e.to_string())?;
    progress.say(&format!("wrote {} (LV, RV and aorta segment surfaces, suture points; BSA {} m2)", out.display(), heart.bsa_m2));
    Ok(())
}

pub(crate) fn read_pools(source: &PrepareSource) -> Result<BloodPools, String> {
    match (&source.segmentations, &source.labelmap) {
        (Some(dir), _) => read_segmentations(dir).map_err(|e| e.to_string()),
        (None, Some(file)) => labelmap_pools(source, file, &read_labelmap(file).map_err(|e| e.to_string())?),
        (None, None) => Err("give --segmentations DIR or --labelmap FILE".into()),
    }
}

/// The blood pools and, from a label map, its pulmonary artery (None inside: the label
/// map has none; None outside: segmentations, whose pulmonary file is read where needed).
fn read_inputs(source: &PrepareSource) -> Result<(BloodPools, Option<Option<TriMesh>>), String> {
    let (None, Some(file)) = (&source.segmentations, &source.labelmap) else {
        return Ok((read_pools(source)?, None));
    };
    let map = read_labelmap(file).map_err(|e| e.to_string())?;
    let pools = labelmap_pools(source, file, &map)?;
    let pulmonary = pulmonary_from_labelmap(&map, &source.pool_labels(), source.pulmonary_label, &source.label_options()).map_err(|e| format!("{}: {e}", file.display()))?;
    Ok((pools, Some(pulmonary)))
}

fn labelmap_pools(source: &PrepareSource, file: &Path, map: &LabelMap) -> Result<BloodPools, String> {
    pools_from_labelmap(map, &source.pool_labels(), &source.label_options()).map_err(|e| format!("{}: {e}", file.display()))
}
