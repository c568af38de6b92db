//! The patient's peak flow, for a design's reduced-order dp estimate
//! (`BaffleDesignOptions.peak_flow_ml_s`) without a CFD case.

use crate::status::{guarded, out_ref, BaffleStatus, CallError};
use baffle_core::analyses::hemodynamics_estimate::peak_flow_ml_s;

/// The paper's peak flow (ml/s) for a child of `bsa_m2` (m2) at `cardiac_index_l_min_m2`
/// (L/min/m2; the paper's normal 3.48): 3.26 x BSA x CI, the peak of the CFD's default
/// waveform, so an estimate made with it is at the 3D run's peak flow. A BSA or cardiac
/// index that is not positive and finite is InvalidArgument, named in baffle_last_error().
///
/// # Safety
/// `out_peak_flow_ml_s` must be NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn baffle_peak_flow_ml_s(bsa_m2: f64, cardiac_index_l_min_m2: f64, out_peak_flow_ml_s: *mut f64) -> BaffleStatus {
    guarded(|| {
        let out = out_ref(out_peak_flow_ml_s, "out_peak_flow_ml_s")?;
        *out = peak_flow_ml_s(bsa_m2, cardiac_index_l_min_m2).map_err(CallError::invalid)?;
        Ok(())
    })
}
