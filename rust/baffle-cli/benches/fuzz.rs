//! Fuzz harness on stable Rust (issue 16): mutates valid inputs of every reader and
//! perturbs valid surfaces for `design`, for a fixed time, and counts executions and
//! findings. A finding is a panic (caught), or a single input taking longer than the
//! hang limit; every other outcome (Ok or a named error) is what the code must do.
//!
//!   cargo bench -p baffle-cli --bench fuzz -- [--seconds 60] [--only vtp,design] [--seed N]
//!       [--findings DIR] [--hang-seconds 10]
//!
//! The time is split evenly over the targets. Findings are written to DIR (default
//! target/fuzz-findings) as the offending input, and the run exits 1 if there are any.
//! Mutations: bit flips, byte runs overwritten or deleted or duplicated, truncation,
//! numbers replaced by extreme values (NaN, inf, -1, 1e308, 2^32), splices of two
//! mutants. Each exec starts from a seed of the corpus (valid files built in memory
//! from the phantom; p2's files too when the patient data is present).

use baffle_core::io::{read_points, read_surface_labeled, write_trimesh_vtp, CoordinateSystem};
use baffle_test_support::perturb::{bump_wall, flip_triangle, jitter, SplitMix64};
use baffle_core::phantom::phantom_default;
use baffle_test_support::reference_data::reference_data_dir;
use baffle_core::{design, DesignOptions, TargetArea, TriMesh, Vec3};
use baffle_plan::case;
use std::io::Write;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[path = "../tests/support/inputs.rs"]
mod inputs;
use inputs::*;

/// One fuzzed reader: file extension, how to read a file, and its seed inputs.
struct Target {
    name: &'static str,
    extension: &'static str,
    seeds: Vec<Vec<u8>>,
    run: fn(&Path) -> bool,
}

#[derive(Default)]
struct Tally {
    execs: usize,
    ok: usize,
    errors: usize,
    findings: Vec<String>,
    slowest_ms: f64,
}

struct Settings {
    seconds: f64,
    only: Option<Vec<String>>,
    seed: u64,
    findings: PathBuf,
    hang: Duration,
}

fn main() {
    let settings = parse_args();
    std::panic::set_hook(Box::new(|_| {})); // panics are counted, not printed
    let scratch = std::env::temp_dir().join(format!("baffle-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).expect("scratch folder");
    let targets: Vec<Target> =
        reader_targets().into_iter().filter(|t| settings.only.as_ref().map_or(true, |o| o.iter().any(|n| n == t.name))).collect();
    let fuzz_design = settings.only.as_ref().map_or(true, |o| o.iter().any(|n| n == "design"));
    let slots = targets.len() + usize::from(fuzz_design);
    let per_target = Duration::from_secs_f64(settings.seconds / slots.max(1) as f64);
    let mut total_findings = 0;
    // An allocation failure aborts the process (no hook on stable Rust): the input it
    // died on is then still in the scratch folder.
    println!("fuzz: {} s over {slots} targets, seed {}, scratch {}", settings.seconds, settings.seed, scratch.display());
    for (i, target) in targets.iter().enumerate() {
        let tally = fuzz_reader(target, &settings, &scratch, per_target, settings.seed.wrapping_add(i as u64));
        total_findings += report(target.name, target.seeds.len(), &tally);
    }
    if fuzz_design {
        let (corpus, tally) = fuzz_design_on_perturbed_surfaces(&settings, per_target);
        total_findings += report("design", corpus, &tally);
    }
    std::fs::remove_dir_all(&scratch).ok();
    println!("fuzz: {total_findings} findings");
    if total_findings > 0 {
        println!("fuzz: inputs in {}", settings.findings.display());
        std::process::exit(1);
    }
}

fn parse_args() -> Settings {
    let mut s = Settings {
        seconds: 60.0,
        only: None,
        seed: 16,
        findings: PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../target/fuzz-findings")),
        hang: Duration::from_secs(10),
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |i: usize| args.get(i + 1).cloned().unwrap_or_else(|| panic!("{} needs a value", args[i]));
    let mut i = 0;
    while i < args.len() {
        match args[i].as_str() {
            "--seconds" => s.seconds = value(i).parse().expect("--seconds: a number"),
            "--only" => s.only = Some(value(i).split(',').map(str::to_owned).collect()),
            "--seed" => s.seed = value(i).parse().expect("--seed: an integer"),
            "--findings" => s.findings = PathBuf::from(value(i)),
            "--hang-seconds" => s.hang = Duration::from_secs_f64(value(i).parse().expect("--hang-seconds: a number")),
            "--bench" => {
                i += 1;
                continue;
            }
            other => panic!("unknown argument {other}"),
        }
        i += 2;
    }
    s
}

fn report(name: &str, corpus: usize, t: &Tally) -> usize {
    println!(
        "fuzz {name:>7}: corpus {corpus:>2}, {:>7} execs ({} ok, {} named errors), slowest {:.0} ms, {} findings",
        t.execs,
        t.ok,
        t.errors,
        t.slowest_ms,
        t.findings.len()
    );
    for f in &t.findings {
        println!("  finding: {f}");
    }
    t.findings.len()
}

fn fuzz_reader(target: &Target, settings: &Settings, scratch: &Path, budget: Duration, seed: u64) -> Tally {
    let mut rng = SplitMix64::new(seed);
    let mut tally = Tally::default();
    let path = scratch.join(format!("input.{}", target.extension));
    let start = Instant::now();
    while start.elapsed() < budget {
        let input = mutant(&target.seeds, &mut rng);
        std::fs::write(&path, &input).expect("write the mutant");
        let t0 = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| (target.run)(&path)));
        let elapsed = t0.elapsed();
        tally.execs += 1;
        tally.slowest_ms = tally.slowest_ms.max(elapsed.as_secs_f64() * 1e3);
        let problem = match outcome {
            Ok(true) => {
                tally.ok += 1;
                None
            }
            Ok(false) => {
                tally.errors += 1;
                None
            }
            Err(_) => Some("panic"),
        };
        let problem = problem.or((elapsed > settings.hang).then_some("slow"));
        if let Some(kind) = problem {
            let file = save_finding(&settings.findings, target.name, kind, tally.execs, target.extension, &input);
            tally.findings.push(format!("{kind} ({:.1} s) on {}", elapsed.as_secs_f64(), file.display()));
        }
    }
    tally
}

fn save_finding(dir: &Path, target: &str, kind: &str, exec: usize, extension: &str, input: &[u8]) -> PathBuf {
    std::fs::create_dir_all(dir).ok();
    let file = dir.join(format!("{target}-{kind}-{exec}.{extension}"));
    std::fs::File::create(&file).and_then(|mut f| f.write_all(input)).ok();
    file
}

// ---- mutations ---------------------------------------------------------------

fn mutant(seeds: &[Vec<u8>], rng: &mut SplitMix64) -> Vec<u8> {
    let mut data = seeds[rng.below(seeds.len())].clone();
    for _ in 0..1 + rng.below(4) {
        mutate(&mut data, seeds, rng);
    }
    data
}

const EXTREMES: [&str; 10] = ["NaN", "inf", "-1", "0", "1e308", "-1e308", "4294967296", "99999999999", "-0", "1e-320"];

fn mutate(data: &mut Vec<u8>, seeds: &[Vec<u8>], rng: &mut SplitMix64) {
    if data.is_empty() {
        data.push(rng.next_u64() as u8);
        return;
    }
    let at = rng.below(data.len());
    match rng.below(7) {
        0 => data[at] ^= 1 << rng.below(8),
        1 => {
            let end = (at + 1 + rng.below(16)).min(data.len());
            data[at..end].iter_mut().for_each(|b| *b = rng.next_u64() as u8);
        }
        2 => {
            let end = (at + 1 + rng.below(64)).min(data.len());
            data.drain(at..end);
        }
        3 => data.truncate(at),
        4 => {
            let end = (at + 1 + rng.below(64)).min(data.len());
            let chunk = data[at..end].to_vec();
            let to = rng.below(data.len());
            data.splice(to..to, chunk);
        }
        5 => replace_number(data, at, EXTREMES[rng.below(EXTREMES.len())]),
        _ => {
            // Splice: this input's head with another seed's tail.
            let other = &seeds[rng.below(seeds.len())];
            let from = rng.below(other.len().max(1));
            data.truncate(at);
            data.extend_from_slice(&other[from.min(other.len())..]);
        }
    }
}

/// Replace the number (digits, sign, point, exponent) at or after `at` by `value`.
fn replace_number(data: &mut Vec<u8>, at: usize, value: &str) {
    let is_num = |b: u8| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'e' || b == b'E' || b == b'+';
    let Some(start) = (at..data.len()).find(|&i| data[i].is_ascii_digit()) else { return };
    let start = (0..start).rev().take_while(|&i| is_num(data[i])).last().unwrap_or(start);
    let end = (start..data.len()).find(|&i| !is_num(data[i])).unwrap_or(data.len());
    data.splice(start..end, value.bytes());
}

// ---- readers and their seeds ---------------------------------------------------

fn reader_targets() -> Vec<Target> {
    let phantom = phantom_default();
    let surface = &phantom.surface;
    let small = first_triangles(surface, 60);
    let p2 = reference_data_dir().join("p2/design_input");
    let p2_file = |name: &str| std::fs::read(p2.join(name)).ok();
    let mut vtp = vec![vtp_bytes(&small), vtp_bytes(surface)];
    vtp.extend(p2_file("capped_ventricle.vtp")); // zlib-compressed binary, as SimVascular writes
    let mut mrk = vec![markups_bytes(&phantom.suture_points_mm)];
    mrk.extend(p2_file("suture_points.mrk.json"));
    let points = &phantom.suture_points_mm;
    vec![
        Target { name: "vtp", extension: "vtp", seeds: vtp, run: read_surface_ok },
        Target { name: "vtk", extension: "vtk", seeds: vec![legacy_vtk(&small, false), legacy_vtk(&small, true)], run: read_surface_ok },
        Target { name: "stl", extension: "stl", seeds: vec![ascii_stl(&small), binary_stl(&small)], run: read_surface_ok },
        Target { name: "mrk", extension: "mrk.json", seeds: mrk, run: read_points_ok },
        Target { name: "fcsv", extension: "fcsv", seeds: vec![fcsv(points)], run: read_points_ok },
        Target { name: "csv", extension: "csv", seeds: vec![csv(points)], run: read_points_ok },
        Target { name: "nrrd", extension: "nrrd", seeds: vec![nrrd(false), nrrd(true)], run: read_labelmap_ok },
        Target { name: "nii", extension: "nii", seeds: vec![nifti()], run: read_labelmap_ok },
        Target { name: "niigz", extension: "nii.gz", seeds: vec![gzip(&nifti())], run: read_labelmap_ok },
        Target { name: "case", extension: "json", seeds: vec![case::EXAMPLE.as_bytes().to_vec()], run: read_case_ok },
    ]
}

fn read_surface_ok(path: &Path) -> bool {
    read_surface_labeled(path).is_ok()
}

fn read_points_ok(path: &Path) -> bool {
    read_points(path).is_ok()
}

fn read_labelmap_ok(path: &Path) -> bool {
    baffle_prepare::read_labelmap(path).is_ok()
}

fn read_case_ok(path: &Path) -> bool {
    case::read_case(path).and_then(|c| case::settings(&c)).is_ok()
}

// ---- design on perturbed surfaces ------------------------------------------------

struct DesignCase {
    surface: TriMesh,
    points: Vec<Vec3>,
    bsa_m2: f64,
}

/// The phantom, and p2 when its data is present.
fn design_corpus() -> Vec<DesignCase> {
    let p = phantom_default();
    let mut corpus = vec![DesignCase { surface: p.surface, points: p.suture_points_mm, bsa_m2: p.bsa_m2 }];
    let p2 = reference_data_dir().join("p2/design_input");
    if let (Ok(s), Ok(pts)) = (read_surface_labeled(&p2.join("capped_ventricle.vtp")), read_points(&p2.join("suture_points.mrk.json"))) {
        corpus.push(DesignCase { surface: s.mesh, points: pts.to_frame(CoordinateSystem::Lps), bsa_m2: 0.37 });
    }
    corpus
}

/// Perturb one corpus surface: a bump (0.5-6 mm, 5-120 vertices), noise, or a flipped
/// triangle; the suture points stay as they were.
fn perturbed(case: &DesignCase, rng: &mut SplitMix64) -> TriMesh {
    let s = &case.surface;
    match rng.below(4) {
        0 | 1 => {
            let height = 0.5 + 5.5 * (rng.symmetric_unit() + 1.0) / 2.0;
            let sign = if rng.below(4) == 0 { -1.0 } else { 1.0 };
            bump_wall(s, rng.below(s.points.len()), 5 + rng.below(116), sign * height, 2)
        }
        2 => jitter(s, 0.02 + 0.3 * (rng.symmetric_unit() + 1.0) / 2.0, rng.next_u64()),
        _ => flip_triangle(s, rng.below(s.triangles.len())),
    }
}

fn fuzz_design_on_perturbed_surfaces(settings: &Settings, budget: Duration) -> (usize, Tally) {
    let corpus = design_corpus();
    let mut rng = SplitMix64::new(settings.seed ^ 0xD5);
    let mut tally = Tally::default();
    let start = Instant::now();
    while start.elapsed() < budget {
        let case = &corpus[rng.below(corpus.len())];
        let surface = perturbed(case, &mut rng);
        let target = TargetArea::Bsa { bsa_m2: case.bsa_m2, z_score: 0.0 };
        let t0 = Instant::now();
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            design(&surface, &case.points, &target, &DesignOptions::default(), &mut |_, _| true).is_ok()
        }));
        let elapsed = t0.elapsed();
        tally.execs += 1;
        tally.slowest_ms = tally.slowest_ms.max(elapsed.as_secs_f64() * 1e3);
        let problem = match outcome {
            Ok(ok) => {
                if ok { tally.ok += 1 } else { tally.errors += 1 }
                (elapsed > settings.hang).then_some("slow")
            }
            Err(_) => Some("panic"),
        };
        if let Some(kind) = problem {
            let file = settings.findings.join(format!("design-{kind}-{}.vtp", tally.execs));
            std::fs::create_dir_all(&settings.findings).ok();
            write_trimesh_vtp(&file, &surface).ok();
            tally.findings.push(format!("{kind} ({:.1} s) on {}", elapsed.as_secs_f64(), file.display()));
        }
    }
    (corpus.len(), tally)
}
