//! One progress model for every command and every stage of `baffle plan`: the fraction
//! of the work done and what runs now, and the lines a command says. Nothing here prints:
//! the text goes to the front end's [`Console`] (baffle-cli's: the lines and Slicer's tags
//! on stdout, the rest on stderr). Progress is shown as Slicer's CLI tags only when asked
//! (`--progress-tags`, or `BAFFLE_PROGRESS_TAGS=1` in the environment), as a bar when the
//! console's status text reaches a terminal, and otherwise as plain lines, so a log gets
//! readable lines and a terminal never sees tags.

use std::cell::{Cell, RefCell};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Where a command's text goes; the front end decides how it is shown.
pub trait Console: Send + Sync {
    /// One line of the command's own output (the command line: stdout).
    fn line(&self, text: &str);
    /// Progress text, exactly as given (newlines and carriage returns included; the
    /// command line: stderr, flushed).
    fn status(&self, text: &str);
    /// Whether the status text reaches a terminal (a bar redrawn in place) or a log.
    fn status_is_terminal(&self) -> bool;
    /// The fraction of the whole job done (0-1), the stage running and what it does, for
    /// a front end that draws progress itself ([`Style::Fractions`]; the C ABI's callback).
    fn fraction(&self, _overall: f64, _stage: &str, _message: &str) {}
}

/// Asked by a long job while it runs: true stops it (a front end's cancel button).
pub type Cancel = Arc<dyn Fn() -> bool + Send + Sync>;

/// A console that drops all text: for callers that want none, and tests.
pub struct Quiet;

impl Console for Quiet {
    fn line(&self, _: &str) {}
    fn status(&self, _: &str) {}
    fn status_is_terminal(&self) -> bool {
        false
    }
}

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
    /// Every report handed to [`Console::fraction`] as numbers (a library caller's callback).
    Fractions,
}

impl Style {
    /// Tags when asked for (flag or environment), else a bar on a terminal, else lines.
    pub fn detect(tags_flag: bool, terminal: bool) -> Style {
        let env_tags = std::env::var(TAGS_ENV).is_ok_and(|v| v == "1");
        match (tags_flag || env_tags, terminal) {
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
    console: Arc<dyn Console>,
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
    pub fn new(console: Arc<dyn Console>, style: Style, start: Instant, range: (f64, f64)) -> Progress {
        let last_line = Cell::new((f64::NEG_INFINITY, start));
        Progress { console, style, start, range, last_line, last_stage: RefCell::new(String::new()), drawn: Cell::new(false) }
    }

    /// A whole job starting now on `console`: tags when `tags` (or the environment) asks.
    pub fn start(console: Arc<dyn Console>, tags: bool) -> Progress {
        let style = Style::detect(tags, console.status_is_terminal());
        Progress::new(console, style, Instant::now(), (0.0, 1.0))
    }

    /// Another whole job on the same console and in the same style, starting now.
    pub fn restart(&self) -> Progress {
        Progress::new(self.console.clone(), self.style, Instant::now(), (0.0, 1.0))
    }

    /// The same display for a sub-range of this one (a stage of the plan).
    pub fn part(&self, range: (f64, f64)) -> Progress {
        let (lo, hi) = self.range;
        Progress::new(self.console.clone(), self.style, self.start, (lo + (hi - lo) * range.0, lo + (hi - lo) * range.1))
    }

    /// A line of the command's output.
    pub fn say(&self, text: &str) {
        self.console.line(text);
    }

    /// A line beside the progress (a warning the run goes on after).
    pub fn note(&self, text: &str) {
        self.console.status(&format!("{text}\n"));
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
                self.say(&format!("<filter-progress>{overall:.4}</filter-progress>"));
                if *self.last_stage.borrow() != stage {
                    self.say(&format!("<filter-stage>{stage}</filter-stage>"));
                    *self.last_stage.borrow_mut() = stage.to_string();
                }
                self.say(&format!("<filter-comment>{message}</filter-comment>"));
            }
            Style::Bar => {
                let width = 30;
                let done = (overall * width as f64).round() as usize;
                let text: String = format!("{stage}: {message}").chars().take(90).collect();
                // A finished piece ends its line, so what the command prints next starts on its own.
                let end = if fraction >= 1.0 { "\n" } else { "" };
                let bar = format!("\r[{}{}] {:5.1}% {} | {text}\x1b[K{end}", "#".repeat(done), " ".repeat(width - done), 100.0 * overall, self.timing(overall));
                self.console.status(&bar);
                self.drawn.set(fraction < 1.0);
            }
            Style::Fractions => self.console.fraction(overall, stage, message),
            Style::Lines => {
                let (last, at) = self.last_line.get();
                let stage_changed = *self.last_stage.borrow() != stage;
                if stage_changed || overall - last >= LINE_STEP || at.elapsed() >= LINE_EVERY || fraction >= 1.0 {
                    self.note(&format!("{:5.1}% {} | {stage}: {message}", 100.0 * overall, self.timing(overall)));
                    self.last_line.set((overall, Instant::now()));
                    *self.last_stage.borrow_mut() = stage.to_string();
                }
            }
        }
    }

    /// Ends the bar's line, with `note` (e.g. why a full bar does not mean success).
    pub fn finish(&self, note: Option<&str>) {
        match (self.style, note) {
            (Style::Bar, Some(note)) if self.drawn.get() => self.note(&format!(" -- {note}")),
            (Style::Bar, None) if self.drawn.get() => self.note(""),
            (Style::Bar | Style::Lines, Some(note)) => self.note(note),
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
                let (console, style, start, range) = (self.console.clone(), self.style, self.start, self.range);
                let done = &done;
                scope.spawn(move || {
                    let ticker = Progress::new(console, style, start, range);
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
        let whole = Progress::new(Arc::new(Quiet), Style::Lines, Instant::now(), (0.0, 1.0));
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
            assert_ne!(Style::detect(false, true), Style::Tags);
            assert_ne!(Style::detect(false, false), Style::Tags);
        }
        assert_eq!(Style::detect(true, true), Style::Tags);
    }
}
