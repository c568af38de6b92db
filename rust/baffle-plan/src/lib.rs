//! The work behind the `baffle` command line, as a library: the plan pipeline (its
//! stages, the CFD case it writes, the embedded and svMultiPhysics runs, the sampling
//! along the centerline, the verdict and the report) and each command's own run, each
//! taking plain typed settings (`*Settings`, their defaults in `Default`), so the command
//! line (baffle-cli) only parses its arguments into them and other
//! front ends can call the same pipeline.
//!
//! Module dependency order: a module uses only modules above it, so there are no circles
//! (the test `each_module_uses_only_modules_declared_before_it` holds lib.rs to it).
//!
//! 1. `error`, `files`, `progress`, `sampling`, `case`, `run_summary`, `mesh_convergence`:
//!    the stages' error type (`PlanError`), atomic writes and typed reads, the progress model, fields sampled along a centerline, the
//!    simulate case (JSON) and its settings, a run's summary.json read back, the grid
//!    convergence index of a mesh study.
//! 2. `feasibility`, `verdict` (run_summary, mesh_convergence), `svmp_case` (case: the svMultiPhysics export),
//!    `export_cmd` (svmp_case), `prepare_cmd`, `mesh_cmd`,
//!    `centerline_cmd` (files, progress, sampling).
//! 3. `design_cmd` (feasibility), `extend_cmd` (prepare_cmd), `simulate_report` (case,
//!    run_summary, verdict: the summary both engines write), `template_cmd` (design_cmd).
//! 4. `simulate_svmp` (svmp_case, simulate_report), `plan_stages` (design_cmd,
//!    prepare_cmd: the plan's settings, stages and folder layout, `PlanLayout`).
//! 5. `simulate_cmd` (simulate_report, simulate_svmp), `report` (plan_stages, verdict, mesh_convergence,
//!    sampling, centerline_cmd, prepare_cmd, design_cmd).
//! 6. `plan_cmd` (every stage, report).
//! 7. `sweep_cmd` (design_cmd, report's plots, plan_cmd's stages for `--cfd`).

/// Declares a settings struct exactly as written (its fields' doc comments stay its
/// rustdoc) and gives it `FIELD_DOCS`: each field's name and doc comment lines. The
/// command line's help shows these texts (baffle-cli's `settings_args!`), so an option's
/// help is written once, here, on the field it sets. Declared before the modules, which
/// use it by its name alone; the struct inside is not indented, so it reads (and its
/// history blames) as a plain struct.
macro_rules! documented_settings {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $($(#[doc = $doc:literal])* $field_vis:vis $field:ident: $ty:ty),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        $vis struct $name {
            $($(#[doc = $doc])* $field_vis $field: $ty),+
        }

        impl $name {
            /// Each field's name and the lines of its doc comment, as rustdoc gets them
            /// (one `#[doc]` string a `///` line, its leading space kept): the command
            /// line's help texts of the options that set these fields.
            pub const FIELD_DOCS: &'static [(&'static str, &'static [&'static str])] = &[$((stringify!($field), &[$($doc),*])),+];
        }
    };
}

pub mod error;
pub mod files;
pub mod progress;
pub mod sampling;
pub mod case;
pub mod run_summary;
pub mod mesh_convergence;

pub mod feasibility;
pub mod verdict;
pub mod svmp_case;
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

pub mod plan_cmd;
pub mod sweep_cmd;

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// The modules in the order lib.rs declares them.
    fn declared_modules(lib: &str) -> Vec<&str> {
        lib.lines().filter_map(|l| l.strip_prefix("pub mod ")?.strip_suffix(';')).collect()
    }

    /// The crate modules a source file names (`crate::x` and `use crate::{x, y::z}`),
    /// comments left out.
    fn used_modules(source: &str) -> Vec<String> {
        let code: String = source.lines().filter(|l| !l.trim_start().starts_with("//")).collect::<Vec<_>>().join("\n");
        let mut used = Vec::new();
        for (k, _) in code.match_indices("crate::") {
            let rest = &code[k + "crate::".len()..];
            if let Some(group) = rest.strip_prefix('{') {
                // Top-level items of the group up to its closing brace.
                let (mut depth, mut item) = (0, String::new());
                for c in group.chars() {
                    match c {
                        '{' => depth += 1,
                        '}' if depth == 0 => break,
                        '}' => depth -= 1,
                        ',' if depth == 0 => used.push(std::mem::take(&mut item)),
                        _ => item.push(c),
                    }
                }
                used.push(item);
            } else {
                used.push(rest.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect());
            }
        }
        used.iter().map(|u| u.trim().split("::").next().unwrap_or_default().to_string()).filter(|u| !u.is_empty()).collect()
    }

    #[test]
    fn each_module_uses_only_modules_declared_before_it() {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let lib = std::fs::read_to_string(src.join("lib.rs")).unwrap();
        let order = declared_modules(&lib);
        assert!(order.len() > 10, "lib.rs declares only {order:?}");
        for (k, module) in order.iter().enumerate() {
            let file = [src.join(format!("{module}.rs")), src.join(module).join("mod.rs")].into_iter().find(|f| f.exists());
            let file = file.unwrap_or_else(|| panic!("no source file for module {module}"));
            let source = std::fs::read_to_string(&file).unwrap();
            for used in used_modules(&source) {
                let position = order.iter().position(|m| *m == used);
                let position = position.unwrap_or_else(|| panic!("{}: uses crate::{used}, not a module of lib.rs", file.display()));
                assert!(position < k, "{}: uses crate::{used}, declared after {module} in lib.rs (a circle or a wrong order)", file.display());
            }
        }
    }

    #[test]
    fn used_modules_reads_paths_and_groups() {
        let source = "//! [`crate::late`]\nuse crate::a::{B, C};\nuse crate::{d, e::{F, G}};\nlet x = crate::h::f();";
        assert_eq!(used_modules(source), ["a", "d", "e", "h"]);
    }
}
