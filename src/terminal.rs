//! The command line's progress display: the library reports progress and trace lines to an
//! [`Observer`]; this one draws an indicatif bar on stderr (only on a terminal, after a delay)
//! and prints trace lines above it.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use base::progress::Observer;

use crate::note;

/// The command line's [`Observer`]: a progress bar on stderr that appears once a stage has run
/// for a second, only if asked for and stderr is a terminal; with `--trace`, the library's trace
/// lines on stderr (printed above the bar when one is shown). Each stage gets its own bar (a
/// render's `solve`, then its `walkthrough`).
pub(crate) struct Terminal {
    bar: bool,
    trace: bool,
    /// How long a stage runs before its bar appears.
    delay: Duration,
    /// When the terminal was made (the command's start): the clock of `--trace` estimates.
    created: Instant,
    state: Mutex<BarState>,
    /// The stage and phase of the last estimate printed as a `--trace` line.
    traced: Mutex<(String, String)>,
}

/// The running stage: its name, its start, its bar once shown, and its latest estimate of the
/// time left (phase, when it came, seconds).
#[derive(Default)]
struct BarState {
    stage: String,
    started: Option<Instant>,
    bar: Option<indicatif::ProgressBar>,
    estimate: Option<(String, Instant, f64)>,
}

impl BarState {
    /// Forgets the stage and clears its bar.
    fn end(&mut self) {
        self.stage.clear();
        self.started = None;
        self.estimate = None;
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

impl Terminal {
    pub(crate) fn new(bar: bool, trace: bool) -> Self {
        Terminal {
            bar: bar && std::io::stderr().is_terminal(),
            trace,
            delay: Duration::from_secs(1),
            created: Instant::now(),
            state: Mutex::default(),
            traced: Mutex::default(),
        }
    }

    /// The `--trace` line of an estimate of the time left, for the first estimate of each
    /// phase of a stage only (the later ones of the same phase are progress, the bar's): the
    /// phase, its estimate and when it came on the command's clock, so that an estimate can be
    /// checked against when the phase really ended.
    fn trace_estimate(&self, stage: &str, phase: &str, seconds: f64) -> Option<String> {
        if !self.trace {
            return None;
        }
        let mut last = self.traced.lock().ok()?;
        if last.0 == stage && last.1 == phase {
            return None;
        }
        *last = (stage.to_string(), phase.to_string());
        let at = self.created.elapsed().as_secs_f64();
        Some(format!(
            "  {stage} at {at:.1} s: {phase}, about {} left ({seconds:.1} s)",
            human_seconds(seconds)
        ))
    }
}

impl Terminal {
    /// A line on standard error, printed above the bar when one is shown.
    pub(crate) fn note(&self, line: &str) {
        let st = self.state.lock().ok();
        match st.as_ref().and_then(|st| st.bar.as_ref()) {
            Some(bar) => bar.suspend(|| note(line)),
            None => note(line),
        }
    }
}

impl Observer for Terminal {
    fn progress(&self, stage: &str, fraction: f64) {
        if !self.bar {
            return;
        }
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        if st.started.is_some() && st.stage != stage {
            // A new stage without the last one's `finished`: its own bar all the same.
            st.end();
        }
        if st.started.is_none() {
            st.stage = stage.to_string();
        }
        let elapsed = st.started.get_or_insert_with(Instant::now).elapsed();
        if elapsed < self.delay {
            return;
        }
        let bar = st.bar.get_or_insert_with(|| {
            let b = indicatif::ProgressBar::new(1000)
                .with_prefix(stage.to_string())
                .with_elapsed(elapsed);
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{prefix} [{elapsed_precise}] {wide_bar} {percent}% {msg}",
            ) {
                b.set_style(style);
            }
            b
        });
        bar.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
        // An estimate whose time has run out while the stage still runs is not "0 s left":
        // the bar says the stage is estimating again until a new estimate comes.
        if let Some((phase, at, secs)) = &st.estimate {
            if at.elapsed().as_secs_f64() > secs + 1.0 && fraction < 1.0 {
                let text = format!("{phase}, estimating");
                if let Some(bar) = &st.bar {
                    bar.set_message(text);
                }
            }
        }
    }

    fn remaining(&self, stage: &str, phase: &str, seconds: f64) {
        let text = format!("{phase}, about {} left", human_seconds(seconds));
        if let Some(line) = self.trace_estimate(stage, phase, seconds) {
            self.note(&line);
        }
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        if st.stage != stage {
            return;
        }
        st.estimate = Some((phase.to_string(), Instant::now(), seconds));
        if let Some(bar) = &st.bar {
            bar.set_message(text);
        }
    }

    fn finished(&self, stage: &str) {
        if let Ok(mut st) = self.state.lock() {
            if st.stage == stage {
                st.end();
            }
        }
    }

    fn tracing(&self) -> bool {
        self.trace
    }

    fn trace(&self, line: &str) {
        self.note(line);
    }
}

/// `42 s`, `3 min 5 s`, `2 h 10 min`: whole units, the two largest.
fn human_seconds(s: f64) -> String {
    let s = s.round().max(0.0) as u64;
    match s {
        0..=59 => format!("{s} s"),
        60..=3599 => format!("{} min {} s", s / 60, s % 60),
        _ => format!("{} h {} min", s / 3600, s % 3600 / 60),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A terminal that shows its bar at once.
    fn terminal() -> Terminal {
        Terminal {
            bar: true,
            trace: false,
            delay: Duration::ZERO,
            created: Instant::now(),
            state: Mutex::default(),
            traced: Mutex::default(),
        }
    }

    /// `--trace` prints the solver's account, not its progress: one estimate line per phase
    /// (the first), not one per update (a gather's twenty).
    #[test]
    fn trace_prints_one_estimate_per_phase() {
        let t = Terminal {
            trace: true,
            ..terminal()
        };
        let lines: Vec<String> = [
            ("solve", "round 1 gather", 3.0),
            ("solve", "round 1 gather", 2.0),
            ("solve", "round 1 gather", 1.0),
            ("solve", "round 1 refinement", 0.5),
            ("solve", "round 2 gather", 2.0),
            ("solve", "round 2 gather", 1.0),
        ]
        .iter()
        .filter_map(|(s, p, x)| t.trace_estimate(s, p, *x))
        .collect();
        assert_eq!(lines.len(), 3, "{lines:?}");
        assert!(
            lines[0].contains("round 1 gather, about 3 s left (3.0 s)"),
            "{lines:?}"
        );
        assert!(lines[2].contains("round 2 gather"), "{lines:?}");
        // Without --trace, none.
        assert_eq!(terminal().trace_estimate("solve", "gather", 1.0), None);
    }

    fn shown(t: &Terminal) -> Option<(String, u64)> {
        let st = t.state.lock().unwrap();
        st.bar.as_ref().map(|b| (b.prefix(), b.position()))
    }

    /// The remaining-time estimate shows on the running stage's bar, not on another's.
    #[test]
    fn remaining_time_shows_on_the_stage_bar() {
        let t = terminal();
        t.progress("solve", 0.2);
        t.remaining("solve", "gather", 125.4);
        let msg = |t: &Terminal| t.state.lock().unwrap().bar.as_ref().unwrap().message();
        assert_eq!(msg(&t), "gather, about 2 min 5 s left");
        t.remaining("walkthrough", "frames", 3.0);
        assert_eq!(msg(&t), "gather, about 2 min 5 s left");
        assert_eq!(human_seconds(7322.0), "2 h 2 min");
        assert_eq!(human_seconds(0.4), "0 s");
    }

    /// An estimate that has run out while the stage runs shows as "estimating", not "0 s left".
    #[test]
    fn an_expired_estimate_shows_estimating() {
        let t = terminal();
        let msg = |t: &Terminal| t.state.lock().unwrap().bar.as_ref().unwrap().message();
        t.progress("solve", 0.2);
        t.remaining("solve", "round 1 refinement", 30.0);
        t.progress("solve", 0.3);
        assert_eq!(msg(&t), "round 1 refinement, about 30 s left");
        // The estimate made 40 s ago said 30 s: it has run out.
        if let Some(e) = &mut t.state.lock().unwrap().estimate {
            e.1 = Instant::now() - Duration::from_secs(40);
        }
        t.progress("solve", 0.4);
        assert_eq!(msg(&t), "round 1 refinement, estimating");
    }

    #[test]
    fn a_stage_after_a_finished_one_gets_a_new_bar() {
        let t = terminal();
        t.progress("solve", 0.0);
        t.progress("solve", 1.0);
        assert_eq!(shown(&t), Some(("solve".into(), 1000)));
        t.finished("solve");
        assert_eq!(shown(&t), None);
        t.progress("walkthrough", 0.0);
        assert_eq!(shown(&t), Some(("walkthrough".into(), 0)));
        t.progress("walkthrough", 0.5);
        assert_eq!(shown(&t), Some(("walkthrough".into(), 500)));
        t.finished("walkthrough");
        assert_eq!(shown(&t), None);
    }

    #[test]
    fn a_stage_without_finished_is_replaced_by_the_next() {
        let t = terminal();
        t.progress("solve", 0.7);
        t.progress("walkthrough", 0.25);
        assert_eq!(shown(&t), Some(("walkthrough".into(), 250)));
        // A late `finished` of the replaced stage leaves the running one alone.
        t.finished("solve");
        assert_eq!(shown(&t), Some(("walkthrough".into(), 250)));
    }
}
