//! `baffle sweep`: the design at several targets on one input (issue 17), so the team
//! sees what a larger tunnel costs the right ventricle and where the surgeon's seam
//! stops admitting one. Each target is a full `design`; an infeasible one is a row with
//! its reason and the largest target the seam admits, not the end of the sweep.
//!
//! Writes into --out: sweep.csv, sweep.md, sweep.json, sweep.svg and, per designed
//! target, the design's files in a subfolder named after it (z-1, z+0.5, area-80).

use crate::files::write_atomic;
use crate::report::svg_plot::{line_chart, Series};
use crate::design_cmd::{design_inputs, design_options, rv_cost_line, target_from, DesignArgs, TargetArgs};
use baffle_core::outputs::write_design_outputs;
use baffle_core::{design, DesignError, DesignReport, TargetArea};
use clap::Args;
use serde_json::json;
use std::fmt::Write;
use std::time::Instant;

#[derive(Args)]
#[command(after_help = "Examples:\n  \
    baffle sweep --surface ../shared/data/p2/design_input/capped_ventricle.vtp \\\n      \
    --points ../shared/data/p2/design_input/suture_points.mrk.json --bsa 0.37 --z-scores=-2,-1,0,1,2 --out out/p2-sweep\n  \
    baffle sweep --phantom --areas-mm2 40,60,80,120 --out out/phantom-sweep")]
pub struct SweepArgs {
    #[command(flatten)]
    design: DesignArgs,
    /// Annulus z-scores to design at (comma-separated; with --bsa or --height-cm/--weight-kg).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true, required_unless_present = "areas_mm2", conflicts_with = "areas_mm2")]
    z_scores: Vec<f64>,
    /// Target areas to design at (mm2, comma-separated), instead of --z-scores.
    #[arg(long, value_delimiter = ',')]
    areas_mm2: Vec<f64>,
}

/// One target of the sweep and what became of it.
struct Row {
    z_score: Option<f64>,
    target_area_mm2: f64,
    outcome: Outcome,
    design_ms: f64,
}

enum Outcome {
    Designed(Box<DesignReport>),
    Infeasible { max_feasible_area_mm2: f64, max_feasible_z_score: Option<f64>, reason: String },
    Failed(String),
}

impl Row {
    fn status(&self) -> &'static str {
        match self.outcome {
            Outcome::Designed(_) => "designed",
            Outcome::Infeasible { .. } => "infeasible",
            Outcome::Failed(_) => "failed",
        }
    }

    fn report(&self) -> Option<&DesignReport> {
        match &self.outcome {
            Outcome::Designed(r) => Some(r),
            _ => None,
        }
    }

    /// A designed row's figure, NaN otherwise (a gap in the plot, empty in the tables).
    fn designed(&self, f: impl Fn(&DesignReport) -> f64) -> f64 {
        self.report().map_or(f64::NAN, f)
    }

    fn max_feasible(&self) -> (f64, Option<f64>) {
        match self.outcome {
            Outcome::Infeasible { max_feasible_area_mm2, max_feasible_z_score, .. } => (max_feasible_area_mm2, max_feasible_z_score),
            _ => (f64::NAN, None),
        }
    }

    fn reason(&self) -> &str {
        match &self.outcome {
            Outcome::Designed(_) => "",
            Outcome::Infeasible { reason, .. } | Outcome::Failed(reason) => reason,
        }
    }

    fn folder(&self) -> String {
        folder_name(self.z_score, self.target_area_mm2)
    }
}

/// Subfolder of a target's design files: z-1, z+0.5, area-80.
fn folder_name(z_score: Option<f64>, target_area_mm2: f64) -> String {
    match z_score {
        Some(z) => format!("z{z:+}"),
        None => format!("area-{target_area_mm2}"),
    }
}

pub fn run_sweep(args: &SweepArgs) -> Result<(), String> {
    // Design options that make no sense per target are refused, not silently dropped.
    if args.design.reference_baffle.is_some() || args.design.progress_tags {
        return Err("baffle sweep takes neither --reference-baffle nor --progress-tags (run baffle design on one target)".into());
    }
    let options = design_options(&args.design)?;
    let (surface, points, default_bsa) = design_inputs(&args.design)?;
    let targets = sweep_targets(args, default_bsa)?;
    std::fs::create_dir_all(&args.design.out).map_err(|e| format!("{}: {e}", args.design.out.display()))?;
    let started = Instant::now();
    let mut rows = Vec::new();
    for (z_score, target) in targets {
        // The area first: a target that cannot even be computed is a row, not a stop.
        let target_area_mm2 = target.area_mm2().unwrap_or(f64::NAN);
        let clock = Instant::now();
        let outcome = match design(&surface, &points, &target, &options, &mut |_, _| true) {
            Ok(result) => {
                write_design_outputs(&args.design.out.join(folder_name(z_score, target_area_mm2)), &result).map_err(|e| e.to_string())?;
                Outcome::Designed(Box::new(result.report))
            }
            Err(DesignError::Infeasible { max_feasible_area_mm2, max_feasible_z_score, reason, .. }) => {
                Outcome::Infeasible { max_feasible_area_mm2, max_feasible_z_score, reason }
            }
            Err(e) => Outcome::Failed(e.to_string()),
        };
        let row = Row { z_score, target_area_mm2, outcome, design_ms: clock.elapsed().as_secs_f64() * 1e3 };
        println!("{}", summary_line(&row));
        rows.push(row);
    }
    let total_s = started.elapsed().as_secs_f64();
    let out = &args.design.out;
    write_atomic(&out.join("sweep.csv"), csv(&rows).as_bytes())?;
    write_atomic(&out.join("sweep.md"), markdown(&rows).as_bytes())?;
    write_atomic(&out.join("sweep.svg"), plot(&rows).as_bytes())?;
    write_atomic(&out.join("sweep.json"), json_doc(&rows, total_s).to_string().as_bytes())?;
    println!("{} targets in {total_s:.1} s; wrote {}", rows.len(), out.display());
    Ok(())
}

/// The sweep's targets, each with its z-score when the list was of z-scores.
fn sweep_targets(args: &SweepArgs, default_bsa: Option<f64>) -> Result<Vec<(Option<f64>, TargetArea)>, String> {
    if !args.areas_mm2.is_empty() {
        return Ok(args.areas_mm2.iter().map(|&a| (None, TargetArea::AreaMm2(a))).collect());
    }
    let base = &args.design.target;
    if base.target_area_mm2.is_some() || base.annulus_diameter_mm.is_some() {
        return Err("--z-scores needs the body size (--bsa or --height-cm/--weight-kg), not a fixed --target-area-mm2 or --annulus-diameter-mm".into());
    }
    args.z_scores
        .iter()
        .map(|&z| {
            let target = target_from(&TargetArgs { z_score: z, ..base.clone() }, default_bsa)?;
            Ok((Some(z), target))
        })
        .collect()
}

fn summary_line(row: &Row) -> String {
    let what = match &row.outcome {
        Outcome::Designed(r) => format!("baffle {:.1} mm2; {}", r.baffle_area_mm2, rv_cost_line(&r.rv_cost)),
        Outcome::Infeasible { max_feasible_area_mm2, .. } => format!("infeasible: the seam admits at most {max_feasible_area_mm2:.1} mm2"),
        Outcome::Failed(reason) => format!("failed: {reason}"),
    };
    format!("{}: target {:.1} mm2: {what} ({:.0} ms)", row.folder(), row.target_area_mm2, row.design_ms)
}

/// A number for the tables: empty when not measured.
fn cell(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        String::new()
    }
}

fn optional(v: Option<f64>, decimals: usize) -> String {
    cell(v.unwrap_or(f64::NAN), decimals)
}

const CSV_HEADER: &str = "z_score,target_area_mm2,status,baffle_area_mm2,min_section_area_mm2,rv_volume_before_ml,rv_volume_after_ml,rv_volume_taken_ml,baffle_area_outside_ventricle_mm2,max_feasible_area_mm2,max_feasible_z_score,design_ms,reason";

fn csv(rows: &[Row]) -> String {
    let mut s = format!("{CSV_HEADER}\n");
    for r in rows {
        let (max_area, max_z) = r.max_feasible();
        let fields = [
            optional(r.z_score, 2),
            cell(r.target_area_mm2, 3),
            r.status().to_string(),
            cell(r.designed(|d| d.baffle_area_mm2), 3),
            cell(r.designed(|d| d.min_constrained_final_area_mm2), 3),
            cell(r.designed(|d| d.rv_cost.rv_volume_before_ml), 4),
            cell(r.designed(|d| d.rv_cost.rv_volume_after_ml), 4),
            cell(r.designed(|d| d.rv_cost.rv_volume_taken_ml), 4),
            cell(r.designed(|d| d.rv_cost.baffle_area_outside_ventricle_mm2), 2),
            cell(max_area, 3),
            optional(max_z, 3),
            cell(r.design_ms, 0),
            // Quoted, inner quotes doubled (RFC 4180): reasons hold commas.
            format!("\"{}\"", r.reason().replace('"', "\"\"")),
        ];
        let _ = writeln!(s, "{}", fields.join(","));
    }
    s
}

fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| z | target (mm2) | status | baffle (mm2) | smallest section (mm2) | RV before (mL) | RV after (mL) | taken (mL) | largest feasible target (mm2) | time (s) |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let (max_area, max_z) = r.max_feasible();
        let largest = match max_z {
            Some(z) if max_area.is_finite() => format!("{max_area:.1} (z = {z:.2})"),
            _ => cell(max_area, 1),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            optional(r.z_score, 2),
            cell(r.target_area_mm2, 1),
            r.status(),
            cell(r.designed(|d| d.baffle_area_mm2), 1),
            cell(r.designed(|d| d.min_constrained_final_area_mm2), 1),
            cell(r.designed(|d| d.rv_cost.rv_volume_before_ml), 2),
            cell(r.designed(|d| d.rv_cost.rv_volume_after_ml), 2),
            cell(r.designed(|d| d.rv_cost.rv_volume_taken_ml), 2),
            largest,
            cell(r.design_ms / 1e3, 1),
        );
    }
    let notes: Vec<String> = rows.iter().filter(|r| !r.reason().is_empty()).map(|r| format!("- {}: {}", r.folder(), r.reason())).collect();
    if !notes.is_empty() {
        let _ = write!(s, "\n{}\n", notes.join("\n"));
    }
    s
}

/// Three charts over the sweep's x (z-score, else target area): the areas, the baffle,
/// and the RV volumes; infeasible targets are gaps, the largest feasible target a line.
fn plot(rows: &[Row]) -> String {
    let by_z = rows.iter().all(|r| r.z_score.is_some());
    let x = |r: &Row| if by_z { r.z_score.unwrap_or(f64::NAN) } else { r.target_area_mm2 };
    let x_label = if by_z { "annulus z-score" } else { "target area (mm2)" };
    let series = |label: &str, color: &'static str, f: &dyn Fn(&Row) -> f64| Series {
        label: label.into(),
        points: rows.iter().map(|r| (x(r), f(r))).collect(),
        color,
        dashed: false,
        markers: true,
    };
    let mut areas = vec![
        Series { dashed: true, ..series("target", "#d62728", &|r| r.target_area_mm2) },
        series("smallest section", "#1f77b4", &|r| r.designed(|d| d.min_constrained_final_area_mm2)),
    ];
    let largest = rows.iter().map(|r| r.max_feasible().0).filter(|a| a.is_finite()).fold(f64::NAN, f64::min);
    if largest.is_finite() {
        let xs: Vec<f64> = rows.iter().map(x).collect();
        let (lo, hi) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        areas.push(Series { label: "largest feasible".into(), points: vec![(lo, largest), (hi, largest)], color: "#2ca02c", dashed: true, markers: false });
    }
    let charts = [
        line_chart("Target and section areas", x_label, "area (mm2)", &areas, true),
        line_chart("Baffle area", x_label, "area (mm2)", &[series("baffle", "#9467bd", &|r| r.designed(|d| d.baffle_area_mm2))], true),
        line_chart(
            "Right ventricle",
            x_label,
            "volume (mL)",
            &[
                series("RV after the baffle", "#1f77b4", &|r| r.designed(|d| d.rv_cost.rv_volume_after_ml)),
                series("taken by the pathway", "#ff7f0e", &|r| r.designed(|d| d.rv_cost.rv_volume_taken_ml)),
            ],
            true,
        ),
    ];
    stack(&charts)
}

/// The charts one below the other in one SVG document.
fn stack(charts: &[String]) -> String {
    let size = |svg: &str, attr: &str| -> f64 {
        let key = format!("{attr}=\"");
        svg.find(&key).and_then(|i| svg[i + key.len()..].split('"').next()?.parse().ok()).unwrap_or(0.0)
    };
    let width = charts.iter().map(|c| size(c, "width")).fold(0.0, f64::max);
    let mut y = 0.0;
    let mut body = String::new();
    for c in charts {
        let _ = write!(body, r#"<g transform="translate(0 {y})">{c}</g>"#);
        y += size(c, "height");
    }
    format!(r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{y}" viewBox="0 0 {width} {y}">{body}</svg>"#)
}

fn json_doc(rows: &[Row], total_s: f64) -> serde_json::Value {
    let number = |v: f64| if v.is_finite() { json!(v) } else { serde_json::Value::Null };
    json!({
        "total_s": total_s,
        "rows": rows.iter().map(|r| {
            let (max_area, max_z) = r.max_feasible();
            json!({
                "folder": r.folder(),
                "z_score": r.z_score,
                "target_area_mm2": number(r.target_area_mm2),
                "status": r.status(),
                "baffle_area_mm2": number(r.designed(|d| d.baffle_area_mm2)),
                "min_section_area_mm2": number(r.designed(|d| d.min_constrained_final_area_mm2)),
                "rv_volume_before_ml": number(r.designed(|d| d.rv_cost.rv_volume_before_ml)),
                "rv_volume_after_ml": number(r.designed(|d| d.rv_cost.rv_volume_after_ml)),
                "rv_volume_taken_ml": number(r.designed(|d| d.rv_cost.rv_volume_taken_ml)),
                "baffle_area_outside_ventricle_mm2": number(r.designed(|d| d.rv_cost.baffle_area_outside_ventricle_mm2)),
                "max_feasible_area_mm2": number(max_area),
                "max_feasible_z_score": max_z,
                "design_ms": r.design_ms,
                "reason": r.reason(),
            })
        }).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows() -> Vec<Row> {
        vec![
            Row { z_score: Some(-1.0), target_area_mm2: 50.0, outcome: Outcome::Failed("seam, \"crossing\" the cap".into()), design_ms: 12.0 },
            Row {
                z_score: Some(2.0),
                target_area_mm2: 120.0,
                outcome: Outcome::Infeasible { max_feasible_area_mm2: 95.5, max_feasible_z_score: Some(1.1), reason: "no amplitude".into() },
                design_ms: 80.0,
            },
        ]
    }

    #[test]
    fn every_row_is_in_the_tables_with_its_reason() {
        let rows = rows();
        let csv = csv(&rows);
        let lines: Vec<&str> = csv.lines().collect();
        assert_eq!(lines.len(), 3);
        assert!(lines[1].starts_with("-1.00,50.000,failed,"), "{}", lines[1]);
        assert!(lines[1].ends_with(",\"seam, \"\"crossing\"\" the cap\""), "{}", lines[1]);
        assert!(lines[2].contains(",infeasible,") && lines[2].contains(",95.500,1.100,"), "{}", lines[2]);
        let md = markdown(&rows);
        assert!(md.contains("| 2.00 | 120.0 | infeasible |") && md.contains("95.5 (z = 1.10)"), "{md}");
        assert!(md.contains("- z+2: no amplitude"), "{md}");
    }

    #[test]
    fn the_plot_is_one_svg_of_three_charts_without_nan() {
        let svg = plot(&rows());
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
        assert_eq!(svg.matches("<svg").count(), 4);
        assert!(svg.contains(r#"height="900""#), "{}", &svg[..200]);
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        assert!(svg.contains("largest feasible"));
    }
}
