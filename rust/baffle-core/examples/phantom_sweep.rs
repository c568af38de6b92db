//! A larger sweep of the seeded phantom family than CI's 50 (`tests/phantom_family.rs`):
//!
//!     cargo run --release -p baffle-core --example phantom_sweep -- [count] [first_seed]

#[path = "../tests/common/family.rs"]
mod family;

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let count: u64 = args.get(1).map_or(Ok(500), |a| a.parse().map_err(|e| format!("count {a}: {e}")))?;
    let first: u64 = args.get(2).map_or(Ok(1000), |a| a.parse().map_err(|e| format!("first seed {a}: {e}")))?;
    let start = std::time::Instant::now();
    let tally = family::sweep(first..first + count);
    println!("phantom family, seeds {first}-{}: {} ({:.1} s)", first + count - 1, tally.summary(), start.elapsed().as_secs_f64());
    for problem in tally.rejected_seams.iter().chain(&tally.problems) {
        println!("  {problem}");
    }
    Ok(())
}
