//! One progress model for every command and every stage of `baffle plan`: the fraction
//! of the work done and what runs now. It is shown as Slicer's CLI tags on stdout only
//! when asked (`--progress-tags`, or `BAFFLE_PROGRESS_TAGS=1` in the environment), as a
//! bar on stderr when stderr is a terminal, and otherwise as plain lines on stderr, so a
//! log gets readable lines and a terminal never sees tags.

use std::cell::{Cell, RefCell};
use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Environment variable that turns Slicer's tags on (for a caller that cannot pass the flag).
pub const TAGS_ENV: &str = "BAFFLE_PROGRESS_TAGS";

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// `<filter-progress>` / `<filter-stage>` lines on stdout (Slicer parses them).
    Tags,
    /// A bar redrawn in place on stderr.
    Bar,
    /// A line on stderr every few percent or every half minute.
    Lines,
}

impl Style {
    /// Tags when asked for (flag or environment), else a bar on a terminal, else lines.
    pub fn detect(tags_flag: bool) -> Style {
        let env_tags = std::env::var(TAGS_ENV).is_ok_and(|v| v == "1");
        match (tags_flag || env_tags, std::io::stderr().is_terminal()) {
            (true, _) => Style::Tags,
            (false, true) => Style::Bar,
            (false, false) => Style::Lines,
        }
    }
}

/// A plain line is printed when the fraction has moved this much, or after `LINE_EVERY`.
const LINE_STEP: f64 = 0.05;
const LINE_EVERY: Duration = Duration::from_secs(30);
/// How often a stage without a fraction of its own (gmsh, prepare) shows it is alive.
const TICK: Duration = Duration::from_secs(1);

pub struct Progress {
    style: Style,
    /// When the whole job (a command, or the whole plan) started: the time-left estimate.
    start: Instant,
    /// The part of the whole job this piece fills.
    range: (f64, f64),
    last_line: Cell<(f64, Instant)>,
    last_stage: RefCell<String>,
    drawn: Cell<bool>,
}

impl Progress {
    pub fn new(style: Style, start: Instant, range: (f64, f64)) -> Progress {
        Progress { style, start, range, last_line: Cell::new((f64::NEG_INFINITY, start)), last_stage: RefCell::new(String::new()), drawn: Cell::new(false) }
    }

    /// The same display for a sub-range of this one (a stage of the plan).
    pub fn part(&self, range: (f64, f64)) -> Progress {
        let (lo, hi) = self.range;
        Progress::new(self.style, self.start, (lo + (hi - lo) * range.0, lo + (hi - lo) * range.1))
    }

    fn overall(&self, fraction: f64) -> f64 {
        let (lo, hi) = self.range;
        lo + (hi - lo) * fraction.clamp(0.0, 1.0)
    }

    /// "12 s elapsed, about 30 s left" (no estimate before 1 % is done).
    fn timing(&self, overall: f64) -> String {
        let elapsed = self.start.elapsed().as_secs_f64();
        if (0.01..1.0).contains(&overall) {
            format!("{} elapsed, about {} left", duration(elapsed), duration(elapsed * (1.0 - overall) / overall))
        } else {
            format!("{} elapsed", duration(elapsed))
        }
    }

    /// `fraction` (0-1) of this piece is done; `stage` names what runs, `message` details it.
    pub fn report(&self, fraction: f64, stage: &str, message: &str) {
        let overall = self.overall(fraction);
        match self.style {
            Style::Tags => {
                let mut out = std::io::stdout().lock();
                let _ = writeln!(out, "<filter-progress>{overall:.4}</filter-progress>");
                if *self.last_stage.borrow() != stage {
                    let _ = writeln!(out, "<filter-stage>{stage}</filter-stage>");
                    *self.last_stage.borrow_mut() = stage.to_string();
                }
                let _ = writeln!(out, "<filter-comment>{message}</filter-comment>");
                let _ = out.flush();
            }
            Style::Bar => {
                let width = 30;
                let done = (overall * width as f64).round() as usize;
                let text: String = format!("{stage}: {message}").chars().take(90).collect();
                let mut err = std::io::stderr().lock();
                let _ = write!(err, "\r[{}{}] {:5.1}% {} | {text}\x1b[K", "#".repeat(done), " ".repeat(width - done), 100.0 * overall, self.timing(overall));
                // A finished piece ends its line, so what the command prints next starts on its own.
                if fraction >= 1.0 {
                    let _ = writeln!(err);
                }
                let _ = err.flush();
                self.drawn.set(fraction < 1.0);
            }
            Style::Lines => {
                let (last, at) = self.last_line.get();
                let stage_changed = *self.last_stage.borrow() != stage;
                if stage_changed || overall - last >= LINE_STEP || at.elapsed() >= LINE_EVERY || fraction >= 1.0 {
                    eprintln!("{:5.1}% {} | {stage}: {message}", 100.0 * overall, self.timing(overall));
                    self.last_line.set((overall, Instant::now()));
                    *self.last_stage.borrow_mut() = stage.to_string();
                }
            }
        }
    }

    /// Ends the bar's line, with `note` (e.g. why a full bar does not mean success).
    pub fn finish(&self, note: Option<&str>) {
        match (self.style, note) {
            (Style::Bar, Some(note)) if self.drawn.get() => eprintln!(" -- {note}"),
            (Style::Bar, None) if self.drawn.get() => eprintln!(),
            (Style::Bar | Style::Lines, Some(note)) => eprintln!("{note}"),
            _ => {}
        }
        self.drawn.set(false);
    }

    /// Run `work`, a step that reports no fraction of its own (gmsh, the voxel union),
    /// showing its stage and elapsed time while it runs, and a line when it ends.
    pub fn while_running<T>(&self, stage: &str, work: impl FnOnce() -> T) -> T {
        let stage_start = Instant::now();
        self.report(0.0, stage, "running");
        let done = AtomicBool::new(false);
        let result = std::thread::scope(|scope| {
            if self.style == Style::Bar {
                let (style, start, range) = (self.style, self.start, self.range);
                let done = &done;
                scope.spawn(move || {
                    let ticker = Progress::new(style, start, range);
                    let mut next = TICK;
                    // Short sleeps, so the stage's end is not held up by a whole tick.
                    while !done.load(Ordering::Relaxed) {
                        std::thread::sleep(Duration::from_millis(100));
                        if stage_start.elapsed() >= next {
                            ticker.report(0.0, stage, &format!("running, {}", duration(stage_start.elapsed().as_secs_f64())));
                            next += TICK;
                        }
                    }
                });
            }
            let result = work();
            done.store(true, Ordering::Relaxed);
            result
        });
        self.report(1.0, stage, &format!("done in {}", duration(stage_start.elapsed().as_secs_f64())));
        result
    }
}

/// "45 s", "3 min 20 s", "1 h 05 min".
pub fn duration(seconds: f64) -> String {
    let s = seconds.max(0.0).round() as u64;
    match s {
        0..=59 => format!("{s} s"),
        60..=3599 => format!("{} min {:02} s", s / 60, s % 60),
        _ => format!("{} h {:02} min", s / 3600, (s % 3600) / 60),
    }
}

/// A steady solve's fraction: how far its residual has fallen on a log scale towards
/// the target (it converges at 1), or the share of the iteration cap used if that is larger.
pub fn steady_fraction(relative_residual: Option<f64>, tolerance: f64, iteration: usize, max_iterations: usize) -> f64 {
    let by_iterations = iteration as f64 / max_iterations.max(1) as f64;
    let by_residual = match relative_residual {
        Some(r) if r > 0.0 && tolerance > 0.0 && tolerance < 1.0 => (r.ln() / tolerance.ln()).clamp(0.0, 1.0),
        _ => 0.0,
    };
    // Shown below 1 until the solve says it converged: the cap is not success.
    by_residual.max(by_iterations).min(0.999)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_a_person_would_say_them() {
        assert_eq!(duration(44.6), "45 s");
        assert_eq!(duration(200.0), "3 min 20 s");
        assert_eq!(duration(3900.0), "1 h 05 min");
    }

    #[test]
    fn a_part_maps_into_its_parents_range() {
        let whole = Progress::new(Style::Lines, Instant::now(), (0.0, 1.0));
        let stage = whole.part((0.5, 0.75));
        let inner = stage.part((0.5, 1.0));
        assert_eq!(inner.range, (0.625, 0.75));
        assert_eq!(inner.overall(0.5), 0.6875);
        assert_eq!(inner.overall(2.0), 0.75);
    }

    #[test]
    fn a_steady_fraction_follows_the_residual_and_stays_below_one_at_the_cap() {
        assert!((steady_fraction(Some(1e-2), 1e-4, 3, 60) - 0.5).abs() < 1e-12);
        assert_eq!(steady_fraction(Some(0.5), 1e-4, 30, 60), 0.5);
        assert_eq!(steady_fraction(Some(1e-3), 1e-4, 60, 60), 0.999);
        assert_eq!(steady_fraction(None, 1e-4, 0, 60), 0.0);
    }

    #[test]
    fn tags_are_used_only_when_asked() {
        // Without the flag and without the variable, never tags (a terminal or a log).
        if std::env::var(TAGS_ENV).is_err() {
            assert_ne!(Style::detect(false), Style::Tags);
        }
        assert_eq!(Style::detect(true), Style::Tags);
    }
}
