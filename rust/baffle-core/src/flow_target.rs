//! An optional design rule (issue 13): the target area applied to the tunnel's sections
//! normal to the flow, not only to the paper's sections.
//!
//! The paper constrains sections normal to its PCHIP centerline between the cap centroids
//! (2.4.2). That centerline runs oblique to the flow near the caps, so the sections the flow
//! crosses can be smaller than the target (p3: 61.5 against 82.2 mm2, the target 62.3). With
//! this rule the design is run again at a raised target until the smallest section normal
//! to the flow-domain centerline of the designed domain (`flow_centerline`) reaches the
//! requested one: first raised by the shortfall from what the design built, then by the
//! secant through the last two rounds.

use crate::design::{design, DesignOptions, DesignResult, Progress};
// The rule's record is part of the design's report; it lives there so the report does not
// depend on this module (which runs the design).
pub use crate::design::{FlowRound, FlowSections};
use crate::error::DesignError;
use crate::analyses::flow_centerline::{flow_centerline, flow_normal_sections, smallest_section, CenterlineOptions, Lumen};
use crate::geometry::mesh::{FaceLabels, TriMesh};
use crate::target::TargetArea;

/// The requested area is met when the smallest flow-normal section is within this fraction of it.
pub const FLOW_TARGET_TOLERANCE: f64 = 0.005;
/// Design rounds at most (p1-p3 and the phantom need at most two).
pub const MAX_FLOW_TARGET_ROUNDS: usize = 6;
/// The design target is never raised beyond this multiple of the requested area: a
/// baffle whose paper sections are twice the target and whose flow still is not there
/// does not bound the flow's narrowest section (p1-p3 needed at most 1.34x).
pub const MAX_TARGET_RAISE: f64 = 2.0;
/// Rounds stop when the flow's narrowest section grows by less than this fraction of the
/// design target's raise: there the baffle does not bound it (p3 grew by 0.05).
pub const MIN_SECTION_RESPONSE: f64 = 0.02;

/// The smallest section of a designed domain normal to its flow-domain centerline (between
/// its VSD and aortic caps), and where it lies (mm2, mm from the VSD plane).
pub fn smallest_flow_section(domain: &TriMesh, labels: FaceLabels) -> Result<(f64, f64), String> {
    let lumen = Lumen::between_caps(domain, labels.vsd_cap, labels.aortic_cap)?;
    let line = flow_centerline(&lumen, &CenterlineOptions::default())?;
    let areas = flow_normal_sections(domain, &line.points, &lumen.planes);
    smallest_section(&line.s_mm, &areas).ok_or_else(|| "no section normal to the flow-domain centerline clears both caps".to_string())
}

/// The next design target: the secant through the last two rounds where they differ,
/// else the larger of this round's target and the section the design built, scaled by the
/// shortfall. Never lower than the last target, at most twice it.
fn next_target(rounds: &[FlowRound], goal_mm2: f64, built_mm2: f64) -> f64 {
    let last = &rounds[rounds.len() - 1];
    let raised = match rounds.len() {
        n if n >= 2 && (last.min_flow_section_mm2 - rounds[n - 2].min_flow_section_mm2).abs() > 1e-6 => {
            let before = &rounds[n - 2];
            let slope = (last.min_flow_section_mm2 - before.min_flow_section_mm2) / (last.design_target_mm2 - before.design_target_mm2);
            last.design_target_mm2 + (goal_mm2 - last.min_flow_section_mm2) / slope
        }
        _ => last.design_target_mm2.max(built_mm2) * goal_mm2 / last.min_flow_section_mm2,
    };
    raised.clamp(last.design_target_mm2, 2.0 * last.design_target_mm2)
}

/// The design with the flow-section rule: `target` applied to the flow-normal sections.
/// Returns the last round's design (its report's `flow_sections` says whether it met the
/// target); a round the design cannot make (an unreachable raised target) is its error.
pub fn design_to_flow_target(
    surface: &TriMesh,
    suture_points_mm: &[crate::geometry::mesh::Vec3],
    target: &TargetArea,
    options: &DesignOptions,
    progress: Progress,
) -> Result<DesignResult, DesignError> {
    let goal_mm2 = target.area_mm2().map_err(DesignError::Target)?;
    let (mut design_target, mut rounds) = (*target, Vec::new());
    loop {
        let mut result = design(surface, suture_points_mm, &design_target, options, &mut *progress).map_err(|e| raised(e, goal_mm2, &rounds))?;
        let (section, at) = smallest_flow_section(&result.domain, options.labels).map_err(|e| DesignError::numerical("flow-normal sections", e))?;
        rounds.push(FlowRound { design_target_mm2: result.report.target_area_mm2, min_flow_section_mm2: section, min_flow_section_at_mm: at });
        let met = section >= goal_mm2 * (1.0 - FLOW_TARGET_TOLERANCE);
        let next = next_target(&rounds, goal_mm2, result.report.min_constrained_final_area_mm2);
        let stopped_because = if met { None } else { why_stop(&rounds, goal_mm2, next) };
        if met || stopped_because.is_some() {
            if rounds.len() > 1 {
                result.report.target = format!("{}, raised to {:.1} mm2 so that the sections normal to the flow reach it", target.describe(), result.report.target_area_mm2);
            }
            result.report.flow_sections = Some(FlowSections { goal_area_mm2: goal_mm2, met, rounds, stopped_because });
            return Ok(result);
        }
        design_target = TargetArea::AreaMm2(next);
    }
}

/// Why no further round is run though the target is not met (None: run one).
fn why_stop(rounds: &[FlowRound], goal_mm2: f64, next_mm2: f64) -> Option<String> {
    let last = &rounds[rounds.len() - 1];
    let shortfall = format!("the smallest section normal to the flow is {:.1} mm2 against the target {goal_mm2:.1} mm2", last.min_flow_section_mm2);
    if rounds.len() == MAX_FLOW_TARGET_ROUNDS {
        return Some(format!("{shortfall} after {MAX_FLOW_TARGET_ROUNDS} design rounds"));
    }
    if let [.., before, last] = rounds {
        let response = (last.min_flow_section_mm2 - before.min_flow_section_mm2) / (last.design_target_mm2 - before.design_target_mm2);
        if response < MIN_SECTION_RESPONSE {
            return Some(format!(
                "{shortfall}, {:.1} mm from the VSD plane, and it widened by {:.3} mm2 per mm2 of the design target's raise: the baffle does not bound it there",
                last.min_flow_section_at_mm, response
            ));
        }
    }
    (next_mm2 > MAX_TARGET_RAISE * goal_mm2).then(|| {
        format!("{shortfall}; reaching it would take a design target above {MAX_TARGET_RAISE} times the requested area ({next_mm2:.1} mm2): the baffle does not bound it")
    })
}

/// A raised round's infeasibility, said in terms of the requested target: the seam cannot
/// take the raise that the flow-normal sections need.
fn raised(e: DesignError, goal_mm2: f64, rounds: &[FlowRound]) -> DesignError {
    match (e, rounds.last()) {
        (DesignError::Infeasible { target_area_mm2, max_feasible_area_mm2, max_feasible_z_score, reason }, Some(last)) => DesignError::Infeasible {
            target_area_mm2,
            max_feasible_area_mm2,
            max_feasible_z_score,
            reason: format!(
                "with the paper's sections at {:.1} mm2 the smallest section normal to the flow was {:.1} mm2, below the target {goal_mm2:.1} mm2, and raising the design target to {target_area_mm2:.1} mm2 fails: {reason}",
                last.design_target_mm2, last.min_flow_section_mm2
            ),
        },
        (e, _) => e,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phantom::phantom_default;

    #[test]
    fn the_phantom_meets_the_target_in_the_flows_sections_after_raising_it() {
        let p = phantom_default();
        let target = TargetArea::Bsa { bsa_m2: p.bsa_m2, z_score: 0.0 };
        let goal = target.area_mm2().unwrap();
        let plain = design(&p.surface, &p.suture_points_mm, &target, &DesignOptions::default(), &mut |_, _| true).unwrap();
        let (before, _) = smallest_flow_section(&plain.domain, FaceLabels::default()).unwrap();
        // Measured: 67.3 mm2 against 69.8 with the paper's sections alone.
        assert!(before < goal * (1.0 - FLOW_TARGET_TOLERANCE), "{before} vs {goal}: the phantom no longer shows the gap");
        let ruled = design_to_flow_target(&p.surface, &p.suture_points_mm, &target, &DesignOptions::default(), &mut |_, _| true).unwrap();
        let flow = ruled.report.flow_sections.as_ref().unwrap();
        assert!(flow.met && flow.rounds.len() >= 2 && flow.goal_area_mm2 == goal);
        // Re-measured on the returned domain, not taken from the rounds.
        let (after, _) = smallest_flow_section(&ruled.domain, FaceLabels::default()).unwrap();
        assert!(after >= goal * (1.0 - FLOW_TARGET_TOLERANCE), "{after} vs {goal}");
        assert!(ruled.report.target_area_mm2 > goal && ruled.report.baffle_area_mm2 > plain.report.baffle_area_mm2);
        assert!(ruled.report.target.contains("raised to"), "{}", ruled.report.target);
    }

    #[test]
    fn a_raise_the_seam_cannot_take_is_said_against_the_requested_target() {
        let round = FlowRound { design_target_mm2: 84.9, min_flow_section_mm2: 75.3, min_flow_section_at_mm: 9.9 };
        let e = DesignError::Infeasible { target_area_mm2: 96.0, max_feasible_area_mm2: 90.0, max_feasible_z_score: Some(0.7), reason: "could not reach".into() };
        let text = raised(e, 84.9, &[round]).to_string();
        assert!(text.contains("smallest section normal to the flow was 75.3 mm2, below the target 84.9 mm2") && text.contains("to 96.0 mm2 fails: could not reach"), "{text}");
        // The first round's error (no raise yet) is the design's own.
        let first = DesignError::Seam("crosses itself".into());
        assert_eq!(raised(first.clone(), 84.9, &[]), first);
    }

    #[test]
    fn rounds_stop_where_the_flow_section_does_not_follow_the_target() {
        let round = |t, m| FlowRound { design_target_mm2: t, min_flow_section_mm2: m, min_flow_section_at_mm: 1.5 };
        // p3's rounds (0.05 mm2 per mm2): a further round is run.
        assert_eq!(why_stop(&[round(62.3, 61.45), round(83.3, 62.0)], 62.3, 89.0), None);
        // Under 0.02 mm2 per mm2: stopped, with where and how little.
        let why = why_stop(&[round(62.3, 50.0), round(80.0, 50.2)], 62.3, 160.0).unwrap();
        assert!(why.contains("50.2 mm2 against the target 62.3") && why.contains("1.5 mm from the VSD plane") && why.contains("does not bound it"), "{why}");
        // The next raise past twice the target stops it too, and so does the last round.
        assert!(why_stop(&[round(62.3, 50.0)], 62.3, 130.0).unwrap().contains("above 2 times the requested area"));
        let rounds: Vec<FlowRound> = (0..MAX_FLOW_TARGET_ROUNDS).map(|k| round(62.3 + k as f64, 50.0 + k as f64)).collect();
        assert!(why_stop(&rounds, 62.3, 70.0).unwrap().contains(&format!("after {MAX_FLOW_TARGET_ROUNDS} design rounds")));
    }

    #[test]
    fn the_next_target_follows_the_secant_and_never_falls() {
        let round = |t, m| FlowRound { design_target_mm2: t, min_flow_section_mm2: m, min_flow_section_at_mm: 0.0 };
        // First round: from what the design built (82.2 > 62.3), scaled by the shortfall.
        assert!((next_target(&[round(62.3, 61.5)], 62.3, 82.2) - 82.2 * 62.3 / 61.5).abs() < 1e-9);
        // Then the secant: sections grow 0.5 mm2 per mm2 of target, 1 mm2 short -> +2.
        assert!((next_target(&[round(80.0, 60.0), round(82.0, 61.0)], 62.0, 82.0) - 84.0).abs() < 1e-9);
        // A secant pointing down or past twice the target is clamped.
        assert_eq!(next_target(&[round(80.0, 63.0), round(82.0, 61.0)], 62.0, 82.0), 82.0);
        assert_eq!(next_target(&[round(80.0, 60.0), round(82.0, 60.001)], 62.0, 82.0), 164.0);
    }
}
