//! The design options struct. Its first field is the size the caller compiled
//! against, so fields can be appended in later versions: a caller's older, shorter
//! struct keeps the defaults for the fields it does not know.

use crate::status::{guarded, out_ref, BaffleStatus, CallError};
use baffle_core::{DesignOptions, FaceLabels, TargetArea};

/// How BaffleDesignOptions.target_kind chooses the target cross-section area.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BaffleTargetKind {
    /// target_area_mm2.
    AreaMm2 = 0,
    /// A circle of annulus_diameter_mm.
    AnnulusDiameterMm = 1,
    /// Boston aortic annulus for bsa_m2 at z_score.
    Bsa = 2,
    /// Haycock BSA from height_cm and weight_kg, then the Boston annulus at z_score.
    HeightWeight = 3,
}

/// Options of baffle_design(). Fill with baffle_design_options_init(), then set
/// the target (and any tunables). Lengths in mm.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaffleDesignOptions {
    /// sizeof(BaffleDesignOptions) as the caller compiled it (set by _init).
    pub struct_size: u32,
    /// A BaffleTargetKind value.
    pub target_kind: i32,
    pub target_area_mm2: f64,
    pub annulus_diameter_mm: f64,
    pub bsa_m2: f64,
    pub height_cm: f64,
    pub weight_kg: f64,
    pub z_score: f64,
    /// ModelFaceID of the RV wall, the baffle (output), the VSD cap and the aortic cap.
    pub wall_label: i32,
    pub baffle_label: i32,
    pub vsd_cap_label: i32,
    pub aortic_cap_label: i32,
    /// Points the seam spline is resampled at.
    pub seam_samples: u32,
    /// Interior thin-plate-spline control points of the initial patch.
    pub interior_control_points: u32,
    /// Rounds of re-measuring the final surface and raising short sections.
    pub max_correction_rounds: u32,
    /// Nonzero: remesh the kept wall isotropically at remesh_edge_mm.
    pub remesh: i32,
    /// Largest allowed distance of a suture point from the surface.
    pub max_point_distance_mm: f64,
    pub remesh_edge_mm: f64,
    pub baffle_edge_mm: f64,
    pub centerline_spacing_mm: f64,
    /// Sections are sized to this multiple of the target area (>= 1).
    pub area_margin: f64,
    /// Sections with more than this fraction of vertices on the RV wall are dropped.
    pub max_wall_fraction: f64,
    /// Smoothing of the final thin-plate spline (0 interpolates).
    pub tps_regularization: f64,
    /// Appended after the first layout (a caller compiled against it keeps the default).
    /// The patient's peak flow (ml/s): the report JSON's hemodynamics_estimate then holds
    /// the reduced-order dp at peak flow and v_max (docs/hemodynamics_estimate.md); 0 or
    /// NaN (the default): no estimate, hemodynamics_estimate says why.
    pub peak_flow_ml_s: f64,
    /// Appended after peak_flow_ml_s. Nonzero: apply the target to the tunnel's sections
    /// normal to the flow too (the command line's --flow-sections): the design is run
    /// again at a raised target until the smallest flow-normal section reaches it (the
    /// report JSON's flow_sections). 0 (the default): the paper's sections only.
    pub flow_sections: i32,
}

/// Size of the first published layout (up to tps_regularization); any caller struct is
/// at least this long, and the fields after it keep their defaults for such a caller.
const V1_SIZE: usize = std::mem::offset_of!(BaffleDesignOptions, peak_flow_ml_s);

impl Default for BaffleDesignOptions {
    fn default() -> Self {
        let d = DesignOptions::default();
        BaffleDesignOptions {
            struct_size: std::mem::size_of::<BaffleDesignOptions>() as u32,
            target_kind: BaffleTargetKind::Bsa as i32,
            target_area_mm2: f64::NAN,
            annulus_diameter_mm: f64::NAN,
            bsa_m2: f64::NAN,
            height_cm: f64::NAN,
            weight_kg: f64::NAN,
            z_score: 0.0,
            wall_label: d.labels.wall,
            baffle_label: d.labels.baffle,
            vsd_cap_label: d.labels.vsd_cap,
            aortic_cap_label: d.labels.aortic_cap,
            seam_samples: d.seam_samples as u32,
            interior_control_points: d.interior_control_points as u32,
            max_correction_rounds: d.max_correction_rounds as u32,
            remesh: i32::from(d.remesh_edge_mm.is_some()),
            max_point_distance_mm: d.max_point_distance_mm,
            remesh_edge_mm: d.remesh_edge_mm.unwrap_or(0.85),
            baffle_edge_mm: d.baffle_edge_mm,
            centerline_spacing_mm: d.centerline_spacing_mm,
            area_margin: d.area_margin,
            max_wall_fraction: d.max_wall_fraction,
            tps_regularization: d.tps_regularization,
            peak_flow_ml_s: f64::NAN,
            flow_sections: 0,
        }
    }
}

/// Fill `out_options` with the defaults (the paper's values) and struct_size; the
/// target values are NaN until the caller sets one.
///
/// # Safety
/// `out_options` must be NULL or point to writable memory for the struct.
#[no_mangle]
pub unsafe extern "C" fn baffle_design_options_init(out_options: *mut BaffleDesignOptions) -> BaffleStatus {
    guarded(|| {
        *out_ref(out_options, "out_options")? = BaffleDesignOptions::default();
        Ok(())
    })
}

/// Read the caller's struct, of whatever size it says it has, over the defaults.
///
/// # Safety
/// `ptr` must be NULL or point to at least `struct_size` readable bytes.
pub(crate) unsafe fn read_options(ptr: *const BaffleDesignOptions) -> Result<BaffleDesignOptions, CallError> {
    read_sized(ptr, V1_SIZE, "options", "baffle_design_options_init")
}

/// A caller's options struct whose first field (u32) is the size the caller compiled
/// against: at least `min_size` bytes (its first published layout) are read over `T`'s
/// defaults, so a caller of an older, shorter layout keeps the defaults of newer fields.
///
/// # Safety
/// `ptr` must be NULL or point to at least `struct_size` readable bytes.
pub(crate) unsafe fn read_sized<T: Default>(ptr: *const T, min_size: usize, name: &str, init: &str) -> Result<T, CallError> {
    if ptr.is_null() {
        return Err(CallError::null(name));
    }
    let size = std::ptr::read_unaligned(ptr.cast::<u32>()) as usize;
    if !(min_size..=std::mem::size_of::<T>()).contains(&size) {
        return Err(CallError::new(
            BaffleStatus::UnsupportedVersion,
            format!(
                "{name}.struct_size is {size}; this library (ABI {}) takes {min_size}..{} (call {init})",
                crate::BAFFLE_ABI_VERSION,
                std::mem::size_of::<T>()
            ),
        ));
    }
    let mut options = T::default();
    std::ptr::copy_nonoverlapping(ptr.cast::<u8>(), std::ptr::addr_of_mut!(options).cast::<u8>(), size);
    Ok(options)
}

impl BaffleDesignOptions {
    pub(crate) fn target(&self) -> Result<TargetArea, CallError> {
        let kind = self.target_kind;
        Ok(match kind {
            k if k == BaffleTargetKind::AreaMm2 as i32 => TargetArea::AreaMm2(self.target_area_mm2),
            k if k == BaffleTargetKind::AnnulusDiameterMm as i32 => TargetArea::AnnulusDiameterMm(self.annulus_diameter_mm),
            k if k == BaffleTargetKind::Bsa as i32 => TargetArea::Bsa { bsa_m2: self.bsa_m2, z_score: self.z_score },
            k if k == BaffleTargetKind::HeightWeight as i32 => {
                TargetArea::HeightWeight { height_cm: self.height_cm, weight_kg: self.weight_kg, z_score: self.z_score }
            }
            other => return Err(CallError::invalid(format!("options.target_kind = {other} is not a BaffleTargetKind"))),
        })
    }

    /// The peak flow for the estimate (ml/s): None for 0 or NaN, an error for any other
    /// value that is not positive and finite.
    pub(crate) fn peak_flow_ml_s(&self) -> Result<Option<f64>, CallError> {
        match self.peak_flow_ml_s {
            q if q.is_nan() || q == 0.0 => Ok(None),
            q if q.is_finite() && q > 0.0 => Ok(Some(q)),
            q => Err(CallError::invalid(format!("options.peak_flow_ml_s = {q}: give a positive, finite peak flow (ml/s), or 0 or NaN for none"))),
        }
    }

    /// The core's options, range-checked by `DesignOptions::validate` (so no value can
    /// make the design allocate without bound or loop forever).
    pub(crate) fn design_options(&self) -> Result<DesignOptions, CallError> {
        let options = DesignOptions {
            labels: FaceLabels {
                wall: self.wall_label,
                baffle: self.baffle_label,
                vsd_cap: self.vsd_cap_label,
                aortic_cap: self.aortic_cap_label,
            },
            seam_samples: self.seam_samples as usize,
            interior_control_points: self.interior_control_points as usize,
            max_correction_rounds: self.max_correction_rounds as usize,
            max_point_distance_mm: self.max_point_distance_mm,
            remesh_edge_mm: (self.remesh != 0).then_some(self.remesh_edge_mm),
            baffle_edge_mm: self.baffle_edge_mm,
            centerline_spacing_mm: self.centerline_spacing_mm,
            area_margin: self.area_margin,
            max_wall_fraction: self.max_wall_fraction,
            tps_regularization: self.tps_regularization,
        };
        options.validate().map_err(|e| CallError::invalid(e.to_string()))?;
        Ok(options)
    }
}
