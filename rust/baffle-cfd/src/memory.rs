//! Memory a run needs, estimated before anything is allocated, so that a mesh too
//! large for the machine is refused up front with the figures (issue 16) instead of
//! being killed by the system halfway through a run.

use crate::CfdError;

/// Peak resident memory of the embedded solver per tetrahedron. Measured (two-level
/// preconditioner, default GMRES restart): p2's published mesh, 147k tets, 213-226 MB;
/// a 622k-tet tube, 942 MB (937 MB with GMRES(30) and the assembly's per-element states,
/// 987 MB with those states and GMRES(60)): 1.5-1.6 kB a tetrahedron. 2 kB leaves room for the retry
/// ladder's whole-matrix f64 ILU and the output buffers.
pub const BYTES_PER_TET: f64 = 2000.0;
/// The program itself and the fixed buffers.
pub const BASE_BYTES: f64 = 50e6;

/// Bytes a run on `tets` tetrahedra is expected to need at its peak.
pub fn estimated_bytes(tets: usize) -> f64 {
    BASE_BYTES + BYTES_PER_TET * tets as f64
}

/// Memory the system can give a new process now (`MemAvailable` of /proc/meminfo);
/// `None` where that is not known (not Linux).
pub fn available_bytes() -> Option<f64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = meminfo.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024.0)
}

/// Refuse a run whose estimate exceeds the available memory; returns the estimate.
pub fn check_fits(tets: usize, available: Option<f64>) -> Result<f64, CfdError> {
    let needed = estimated_bytes(tets);
    match available {
        Some(free) if needed > free => Err(CfdError::Memory { tets, needed_bytes: needed, available_bytes: free }),
        _ => Ok(needed),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mesh_larger_than_the_free_memory_is_refused_with_both_figures() {
        let err = check_fits(5_000_000, Some(4e9)).unwrap_err().to_string();
        assert!(err.contains("5000000 tetrahedra") && err.contains("10.1 GB") && err.contains("4.0 GB"), "{err}");
        assert_eq!(check_fits(147_000, Some(4e9)).unwrap(), estimated_bytes(147_000));
        assert!(check_fits(5_000_000, None).is_ok(), "unknown free memory: the run is not refused");
    }

    #[test]
    fn the_estimate_covers_the_measured_peaks() {
        // p2's published mesh and the 622k-tet tube (see BYTES_PER_TET).
        assert!(estimated_bytes(147_000) > 226e6 && estimated_bytes(622_000) > 942e6);
        assert!(estimated_bytes(622_000) < 2.0 * 942e6, "not so generous that it refuses runs that fit");
    }

    #[test]
    fn this_machine_reports_its_free_memory() {
        if cfg!(target_os = "linux") {
            assert!(available_bytes().is_some_and(|b| b > 0.0));
        }
    }
}
