//! What the long commands print while they run: a bar on a terminal, and in a log (stderr
//! not a terminal) a line every [`LINE_INTERVAL`] with the phase's pace and what is left.

use indicatif::{ProgressBar, ProgressStyle};
use std::time::{Duration, Instant};

/// How often a line of progress is printed when stderr is not a terminal (a log file).
pub(crate) const LINE_INTERVAL: Duration = Duration::from_secs(60);

/// A progress bar over `planned_steps` steps of a phase, with elapsed time and estimate.
pub fn phase_bar(planned_steps: u64, prefix: &'static str) -> ProgressBar {
    let bar = ProgressBar::new(planned_steps);
    if let Ok(style) = ProgressStyle::with_template(
        "{prefix:>13} [{elapsed_precise}] {bar:40} {pos}/{len} steps (eta {eta}) {msg}",
    ) {
        bar.set_style(style);
    }
    bar.set_prefix(prefix);
    bar
}

/// The rate of a phase measured from its own steps in this process, so that a resumed
/// phase is estimated from what it costs now, not from a plan's calibration.
pub(crate) struct Pace {
    first: (u64, Instant),
    last_line: Instant,
}

impl Pace {
    /// The pace of a phase first seen at `steps`.
    pub(crate) fn new(steps: u64) -> Self {
        let now = Instant::now();
        Pace {
            first: (steps, now),
            last_line: now,
        }
    }

    /// Whether a line is due ([`LINE_INTERVAL`] since the last one); if so, the next one
    /// is due an interval from now.
    pub(crate) fn line_due(&mut self) -> bool {
        let due = self.last_line.elapsed() >= LINE_INTERVAL;
        if due {
            self.last_line = Instant::now();
        }
        due
    }

    /// Seconds per step since the first report, once a step has been done.
    fn seconds_per_step(&self, steps: u64) -> Option<f64> {
        let done = steps.checked_sub(self.first.0).filter(|&d| d > 0)?;
        Some(self.first.1.elapsed().as_secs_f64() / done as f64)
    }

    /// `; 0.21 s/step here, about 47 min left` at `steps` of `planned` (`bound`: "about "
    /// or "at most "), or nothing before a step has been timed.
    pub(crate) fn left(&self, steps: u64, planned: u64, bound: &str) -> String {
        let Some(rate) = self.seconds_per_step(steps) else {
            return String::new();
        };
        let left = rate * planned.saturating_sub(steps) as f64;
        let pace = if rate >= 0.1 {
            format!("{rate:.2} s/step")
        } else {
            format!("{:.3} ms/step", 1e3 * rate)
        };
        format!("; {pace} here, {bound}{} left", duration(left))
    }
}

/// `42 s` under two minutes, else `3.5 min`; `unknown` when not finite.
pub(crate) fn duration(seconds: f64) -> String {
    if !seconds.is_finite() {
        return "unknown".into();
    }
    if seconds < 120.0 {
        format!("{seconds:.0} s")
    } else {
        format!("{:.1} min", seconds / 60.0)
    }
}

/// `phase: 4000 / 10253 steps (39 %)`.
pub(crate) fn steps_done(phase: &str, steps: u64, planned: u64) -> String {
    format!(
        "{phase}: {steps} / {planned} steps ({:.0} %)",
        100.0 * steps as f64 / planned.max(1) as f64,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_in_seconds_then_minutes() {
        assert_eq!(duration(42.4), "42 s");
        assert_eq!(duration(210.0), "3.5 min");
        assert_eq!(duration(f64::NAN), "unknown");
    }

    #[test]
    fn nothing_is_left_to_say_before_a_step_is_timed() {
        let pace = Pace::new(100);
        assert_eq!(pace.left(100, 1000, "about "), "");
        let line = pace.left(101, 1000, "at most ");
        assert!(line.starts_with("; ") && line.contains("at most ") && line.ends_with(" left"));
        assert_eq!(
            steps_done("compact", 250, 1000),
            "compact: 250 / 1000 steps (25 %)"
        );
    }
}
