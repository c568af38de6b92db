//! The work behind the `baffle` command line, as a library: the plan pipeline (its
//! stages, the CFD case it writes, the embedded and svMultiPhysics runs, the sampling
//! along the centerline, the verdict and the report) and each command's own run, so the
//! command line only parses arguments and other front ends can call the same pipeline.
//!
//! Module dependency order: a module uses only modules above it (no circles; check with
//! `grep -n "crate::" src/*.rs src/report/mod.rs`).
//!
//! 1. `files`, `progress`, `sampling`, `case`: atomic writes, the progress model, fields
//!    sampled along a centerline, the simulate case (JSON) and its settings.
//! 2. `feasibility`, `verdict` (case), `export_cmd` (case), `prepare_cmd`, `mesh_cmd`,
//!    `centerline_cmd` (files, progress, sampling).
//! 3. `design_cmd` (feasibility), `extend_cmd` (prepare_cmd), `simulate_report` (case,
//!    verdict: the summary both engines write), `template_cmd` (design_cmd).
//! 4. `simulate_svmp` (export_cmd, simulate_report), `plan_stages` (design_cmd,
//!    prepare_cmd: the plan's arguments, stages and paths).
//! 5. `simulate_cmd` (simulate_report, simulate_svmp), `report` (plan_stages, verdict,
//!    sampling, centerline_cmd, prepare_cmd, design_cmd).
//! 6. `sweep_cmd` (design_cmd, report's plots), `plan_cmd` (every stage, report).

pub mod files;
pub mod progress;
pub mod sampling;
pub mod case;

pub mod feasibility;
pub mod verdict;
pub mod export_cmd;
pub mod prepare_cmd;
pub mod mesh_cmd;
pub mod centerline_cmd;

pub mod design_cmd;
pub mod extend_cmd;
pub mod simulate_report;
pub mod template_cmd;

pub mod simulate_svmp;
pub mod plan_stages;

pub mod simulate_cmd;
pub mod report;

pub mod sweep_cmd;
pub mod plan_cmd;
