//! One member of the phantom family designed and checked: shared by the CI sweep
//! (`tests/phantom_family.rs`) and the larger one (`examples/phantom_sweep.rs`); the
//! independent check of a design is also the patients' (`tests/seam_variants.rs`).
#![allow(dead_code)]

use baffle_core::phantom::phantom;
use baffle_test_support::phantom_family::FamilyMember;
use baffle_core::{design, DesignError, DesignOptions, DesignResult, TargetArea};

/// What the design did with one member.
pub enum Outcome {
    /// A tunnel at the target; the seam length (mm) and whether the baffle had to be pushed out.
    Designed { seam_mm: f64, expanded: bool },
    /// A named infeasibility whose largest target was designed and verified.
    Infeasible { target_area_mm2: f64, max_feasible_area_mm2: f64 },
    /// The jittered points make a seam that crosses a cap or runs between the caps:
    /// an input the design refuses by name, as it would a surgeon's.
    RejectedSeam(String),
    /// Anything else: a wrong mesh, an unexplained error, a false largest target.
    Problem(String),
}

/// Smallest re-measured checked section of a design, or why it fails: the design's own
/// checks by baffle-verify (edges, volume, every checked section re-cut), with the
/// section held to the target itself, not to the checks' rounding allowance.
pub fn verified_smallest_section_mm2(result: &DesignResult) -> Result<f64, String> {
    let checks = baffle_verify::design_checks(result);
    baffle_core::analyses::self_check::first_failure(&checks)?;
    let section = checks.iter().find(|c| c.name == "smallest checked section, re-cut").ok_or("no section check")?;
    let target_mm2 = result.report.target_area_mm2;
    if section.value < target_mm2 {
        return Err(format!("{} re-measures {:.2} mm2 < {target_mm2:.2}", section.detail, section.value));
    }
    Ok(section.value)
}

pub fn run_member(member: &FamilyMember) -> Outcome {
    let p = phantom(&member.params);
    let options = DesignOptions::default();
    let run = |target: &TargetArea| design(&p.surface, &p.suture_points_mm, target, &options, &mut |_, _| true);
    match run(&member.target) {
        Ok(result) => match verified_smallest_section_mm2(&result) {
            Ok(_) => {
                let seam = &result.seam_mm;
                let seam_mm = (0..seam.len()).map(|i| (seam[(i + 1) % seam.len()] - seam[i]).norm()).sum();
                let expanded = result.report.sections.iter().any(|s| s.alpha_mm.is_some_and(|a| a > 0.0));
                Outcome::Designed { seam_mm, expanded }
            }
            Err(why) => Outcome::Problem(why),
        },
        Err(DesignError::Infeasible { target_area_mm2, max_feasible_area_mm2, .. }) if max_feasible_area_mm2 > 1.0 => {
            match run(&TargetArea::AreaMm2(max_feasible_area_mm2)).map_err(|e| e.to_string()).and_then(|r| verified_smallest_section_mm2(&r)) {
                Ok(_) => Outcome::Infeasible { target_area_mm2, max_feasible_area_mm2 },
                Err(why) => Outcome::Problem(format!("the reported largest target {max_feasible_area_mm2:.1} mm2 fails: {why}")),
            }
        }
        Err(e @ DesignError::Seam(_)) => Outcome::RejectedSeam(e.to_string()),
        Err(e) => Outcome::Problem(e.to_string()),
    }
}

/// Tally of a sweep over seeds.
#[derive(Default)]
pub struct Tally {
    pub designed: usize,
    pub expanded: usize,
    pub infeasible: usize,
    /// Largest feasible / target area of each infeasible member.
    pub feasible_fractions: Vec<f64>,
    pub seam_range_mm: (f64, f64),
    pub rejected_seams: Vec<String>,
    pub problems: Vec<String>,
}

pub fn sweep(seeds: impl Iterator<Item = u64>) -> Tally {
    let mut tally = Tally { seam_range_mm: (f64::INFINITY, 0.0), ..Tally::default() };
    for seed in seeds {
        match run_member(&baffle_test_support::phantom_family::family_member(seed)) {
            Outcome::Designed { seam_mm, expanded } => {
                tally.designed += 1;
                tally.expanded += usize::from(expanded);
                tally.seam_range_mm = (tally.seam_range_mm.0.min(seam_mm), tally.seam_range_mm.1.max(seam_mm));
            }
            Outcome::Infeasible { target_area_mm2, max_feasible_area_mm2 } => {
                tally.infeasible += 1;
                tally.feasible_fractions.push(max_feasible_area_mm2 / target_area_mm2);
            }
            Outcome::RejectedSeam(why) => tally.rejected_seams.push(format!("seed {seed}: {why}")),
            Outcome::Problem(why) => tally.problems.push(format!("seed {seed}: {why}")),
        }
    }
    tally
}

impl Tally {
    pub fn summary(&self) -> String {
        format!(
            "{} designed ({} needed the baffle pushed out; seams {:.0}-{:.0} mm), {} infeasible with a verified largest target \
             ({:.2}-{:.2} of the target), {} seams refused by name, {} problems",
            self.designed,
            self.expanded,
            self.seam_range_mm.0,
            self.seam_range_mm.1,
            self.infeasible,
            self.feasible_fractions.iter().copied().fold(f64::INFINITY, f64::min),
            self.feasible_fractions.iter().copied().fold(0.0, f64::max),
            self.rejected_seams.len(),
            self.problems.len()
        )
    }
}
