//! `--flow-sections` (`baffle_core::flow_target`) on members of the seeded phantom family:
//! how many meet the target in the flow's own sections, after how many rounds, and every
//! refusal or failure by name. Each "met" is re-measured on the returned domain.
//!
//!     cargo run --release -p baffle-core --example flow_sections_sweep -- [count] [first_seed]

use baffle_core::flow_target::{design_to_flow_target, smallest_flow_section, FLOW_TARGET_TOLERANCE};
use baffle_core::phantom::phantom;
use baffle_test_support::phantom_family::family_member;
use baffle_core::{DesignError, DesignOptions, FaceLabels};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let count: u64 = args.get(1).map_or(Ok(40), |a| a.parse().map_err(|e| format!("count {a}: {e}")))?;
    let first: u64 = args.get(2).map_or(Ok(1000), |a| a.parse().map_err(|e| format!("first seed {a}: {e}")))?;
    let start = std::time::Instant::now();
    let (mut met, mut below, mut infeasible, mut refused) = (Vec::new(), 0, 0, 0);
    let mut problems = Vec::new();
    for seed in first..first + count {
        let member = family_member(seed);
        let p = phantom(&member.params);
        match design_to_flow_target(&p.surface, &p.suture_points_mm, &member.target, &DesignOptions::default(), &mut |_, _| true) {
            Ok(result) => {
                let flow = result.report.flow_sections.as_ref().ok_or("no flow_sections in the report")?;
                let remeasured = smallest_flow_section(&result.domain, FaceLabels::default()).map(|(a, _)| a);
                match remeasured {
                    Ok(a) if flow.met && a >= flow.goal_area_mm2 * (1.0 - FLOW_TARGET_TOLERANCE) => met.push(flow.rounds.len()),
                    Ok(a) if flow.met => problems.push(format!("seed {seed}: said met but re-measures {a:.2} < {:.2} mm2", flow.goal_area_mm2)),
                    Ok(_) if flow.stopped_because.is_some() => below += 1,
                    Ok(_) => problems.push(format!("seed {seed}: not met and no reason given")),
                    Err(e) => problems.push(format!("seed {seed}: re-measure failed: {e}")),
                }
            }
            Err(DesignError::Infeasible { .. }) => infeasible += 1,
            Err(DesignError::Seam(_)) => refused += 1,
            Err(e) => problems.push(format!("seed {seed}: {e}")),
        }
    }
    let rounds = |n: usize| met.iter().filter(|&&r| r == n).count();
    println!(
        "phantom family, seeds {first}-{}: {} met (1 round {}, 2 rounds {}, more {}), {below} stopped short with the reason given, {infeasible} infeasible, {refused} seams refused, {} problems ({:.1} s)",
        first + count - 1,
        met.len(),
        rounds(1),
        rounds(2),
        met.iter().filter(|&&r| r > 2).count(),
        problems.len(),
        start.elapsed().as_secs_f64()
    );
    for p in &problems {
        println!("  {p}");
    }
    Ok(())
}
