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

/// The rate of a phase over its latest steps in this process: since the last line, or
/// since the phase's first report before any line. A phase whose steps grow dearer (a
/// packing that gains contacts) is then estimated at its current cost, and a resumed
/// phase at what it costs now, not at a plan's calibration.
pub(crate) struct Pace {
    /// Steps and time of the last line (or of the phase's first report).
    last: (u64, Instant),
}

impl Pace {
    /// The pace of a phase first seen at `steps`.
    pub(crate) fn new(steps: u64) -> Self {
        Pace {
            last: (steps, Instant::now()),
        }
    }

    /// A line's tail when one is due ([`LINE_INTERVAL`] since the last line or the first
    /// report): `; 0.21 s/step here, about 47 min left` at `steps` of `planned` (`bound`:
    /// "about " or "at most "), the rate taken over the steps since then; an empty tail
    /// when no step was taken since. The next line is due an interval from now.
    pub(crate) fn line(&mut self, steps: u64, planned: u64, bound: &str) -> Option<String> {
        let (since, at) = self.last;
        let elapsed = at.elapsed();
        if elapsed < LINE_INTERVAL {
            return None;
        }
        self.last = (steps, Instant::now());
        Some(left(
            elapsed.as_secs_f64(),
            steps.checked_sub(since),
            (steps, planned),
            bound,
        ))
    }
}

/// `; 0.21 s/step here, about 47 min left` for `done` steps in `seconds`, at `steps` of
/// `planned`; empty without a step done.
fn left(seconds: f64, done: Option<u64>, (steps, planned): (u64, u64), bound: &str) -> String {
    let Some(done) = done.filter(|&d| d > 0) else {
        return String::new();
    };
    let rate = seconds / done as f64;
    let left = rate * planned.saturating_sub(steps) as f64;
    let pace = if rate >= 0.1 {
        format!("{rate:.2} s/step")
    } else {
        format!("{:.3} ms/step", 1e3 * rate)
    };
    format!("; {pace} here, {bound}{} left", duration(left))
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
    fn nothing_is_left_to_say_without_a_step_done() {
        assert_eq!(left(60.0, Some(0), (100, 1000), "about "), "");
        assert_eq!(left(60.0, None, (100, 1000), "about "), "");
        assert_eq!(
            left(60.0, Some(1200), (400, 1000), "at most "),
            "; 50.000 ms/step here, at most 30 s left"
        );
        assert_eq!(
            left(60.0, Some(100), (400, 1000), "about "),
            "; 0.60 s/step here, about 6.0 min left"
        );
        assert_eq!(
            steps_done("compact", 250, 1000),
            "compact: 250 / 1000 steps (25 %)"
        );
    }

    #[test]
    fn no_line_is_due_before_the_interval() {
        let mut pace = Pace::new(0);
        assert_eq!(pace.line(10, 100, "about "), None);
    }
}
