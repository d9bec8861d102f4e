//! Progress and tracing: how a long-running library call tells its caller how far it has come
//! and what it did, without the library drawing anything or reading the environment. The caller
//! passes an [`Observer`]; the binary implements one as a terminal progress bar and a `--trace`
//! printer, tests implement one that records, and everything else passes [`Silent`].
//!
//! Invariants: within one stage the fractions an observer receives are in [0, 1] and never
//! decrease, and [`Observer::finished`] follows once per started stage, also when the stage ends
//! early (an error, a panic unwinding); [`Stage`] is the one place that enforces both, so a stage
//! reports through it rather than calling the observer's progress directly. Trace lines are only
//! formatted when [`Observer::tracing`] says they are wanted, so a silent run pays nothing for
//! them. Nothing an observer does or answers may change a result: the library's output is the
//! same, bit for bit, whatever observer it is given.
//!
//! Why a trait and not callbacks or a global logger: one `&dyn Observer` argument carries all
//! four concerns through the call chain, it is `Sync` so that work on rayon workers can report
//! through the same reference, and there is no global state that two concurrent solves (or two
//! tests) could share. This module depends on nothing else in the crate.

/// Receives a long-running call's progress and diagnostics. Every method has a do-nothing
/// default, so an implementation overrides only what it shows.
///
/// Object-safe and `Sync`: the library holds it as `&dyn Observer` and may call it from any
/// thread of the caller's rayon pool (calls for one stage are never concurrent).
pub trait Observer: Sync {
    /// The stage `stage` (for example `"solve"`) advanced to `fraction`, in [0, 1] and
    /// non-decreasing within the stage. The first call of a stage (usually with 0) marks its
    /// start.
    fn progress(&self, _stage: &str, _fraction: f64) {}

    /// The stage `stage` ended (completed, or stopped early on an error).
    fn finished(&self, _stage: &str) {}

    /// The stage `stage` is in phase `phase` (for example `"gather"`) and estimates that
    /// `seconds` remain until the stage ends. An estimate, made from the rates the stage has
    /// measured so far (each stage documents what its estimate covers); reported now and then,
    /// never more than a few times a second.
    fn remaining(&self, _stage: &str, _phase: &str, _seconds: f64) {}

    /// Whether trace lines are wanted. When false the library does not even format them.
    fn tracing(&self) -> bool {
        false
    }

    /// One diagnostic line (phase times, shot counts, ...), without a trailing newline. Only
    /// called when [`tracing`](Observer::tracing) returned true.
    fn trace(&self, _line: &str) {}
}

/// The observer that shows nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct Silent;

impl Observer for Silent {}

/// A [`Silent`] with a `'static` lifetime, for defaults.
pub static SILENT: Silent = Silent;

/// One running stage: starts it (progress 0), forwards only fractions that move forward (clamped
/// to [0, 1], NaN ignored) and reports [`Observer::finished`] when dropped, so an early return or
/// a panic still ends the stage.
pub struct Stage<'a> {
    observer: &'a dyn Observer,
    name: &'a str,
    last: f64,
}

impl<'a> Stage<'a> {
    /// Starts stage `name` on `observer` (reports fraction 0).
    pub fn start(observer: &'a dyn Observer, name: &'a str) -> Stage<'a> {
        observer.progress(name, 0.0);
        Stage {
            observer,
            name,
            last: 0.0,
        }
    }

    /// Reports `fraction` if it is further than anything reported so far (values above 1 count
    /// as 1; lower values and NaN are dropped, so the observer sees a non-decreasing sequence).
    pub fn advance(&mut self, fraction: f64) {
        // Not `min`: f64::min(NaN, 1) is 1.
        let f = if fraction > 1.0 { 1.0 } else { fraction };
        if f > self.last {
            self.last = f;
            self.observer.progress(self.name, f);
        }
    }

    /// Reports the phase and the estimated seconds left ([`Observer::remaining`]); a NaN or
    /// negative estimate is dropped.
    pub fn remaining(&self, phase: &str, seconds: f64) {
        if seconds >= 0.0 && seconds.is_finite() {
            self.observer.remaining(self.name, phase, seconds);
        }
    }

    /// The observer this stage reports to (for trace lines).
    pub fn observer(&self) -> &'a dyn Observer {
        self.observer
    }
}

impl Drop for Stage<'_> {
    fn drop(&mut self) {
        self.observer.finished(self.name);
    }
}

/// An observer that passes every call on to another with each stage's name followed by a
/// context in parentheses: `solve` becomes `solve (scene 2/3 cornell-box, density 3/5)`. A job
/// that runs a stage many times (a sweep's densities, the results page's scenes) wraps its
/// observer in one, so that each bar says which of the runs it is. Contexts nest outer first: a
/// job's labelled observer wrapped again by a job it runs (the results page's scene, then the
/// sweep's density) names the stage with the outer context before the inner one.
pub struct Labelled<'a> {
    inner: &'a dyn Observer,
    context: String,
}

impl<'a> Labelled<'a> {
    /// `inner`, with `context` after every stage name (none when `context` is empty).
    pub fn new(inner: &'a dyn Observer, context: impl Into<String>) -> Labelled<'a> {
        Labelled {
            inner,
            context: context.into(),
        }
    }

    /// The name `inner` sees for stage `stage`.
    pub fn label(&self, stage: &str) -> String {
        if self.context.is_empty() {
            return stage.to_string();
        }
        // A name that already carries an inner job's context gets this (outer) one before it,
        // in the same parentheses.
        match stage.split_once(" (") {
            Some((name, inner)) if inner.ends_with(')') => {
                format!("{name} ({}, {inner}", self.context)
            }
            _ => format!("{stage} ({})", self.context),
        }
    }
}

impl Observer for Labelled<'_> {
    fn progress(&self, stage: &str, fraction: f64) {
        self.inner.progress(&self.label(stage), fraction);
    }
    fn finished(&self, stage: &str) {
        self.inner.finished(&self.label(stage));
    }
    fn remaining(&self, stage: &str, phase: &str, seconds: f64) {
        self.inner.remaining(&self.label(stage), phase, seconds);
    }
    fn tracing(&self) -> bool {
        self.inner.tracing()
    }
    fn trace(&self, line: &str) {
        self.inner.trace(line);
    }
}

/// An observer that records every call (for a caller that inspects a job's progress afterwards,
/// and for the tests).
#[derive(Debug, Default)]
pub struct Recorder {
    /// What [`Observer::tracing`] answers.
    pub tracing: bool,
    events: std::sync::Mutex<Vec<Event>>,
}

/// One recorded call of an [`Observer`].
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// [`Observer::progress`]: the stage and its fraction done.
    Progress(String, f64),
    /// [`Observer::finished`]: the stage.
    Finished(String),
    /// [`Observer::trace`]: the line.
    Trace(String),
    /// [`Observer::remaining`]: the stage and the estimated seconds left.
    Remaining(String, f64),
}

impl Recorder {
    /// A recorder that wants trace lines.
    pub fn tracing() -> Recorder {
        Recorder {
            tracing: true,
            ..Recorder::default()
        }
    }

    /// The calls so far, in order.
    pub fn events(&self) -> Vec<Event> {
        self.events.lock().expect("recorder lock").clone()
    }

    fn push(&self, e: Event) {
        self.events.lock().expect("recorder lock").push(e);
    }
}

impl Observer for Recorder {
    fn progress(&self, stage: &str, fraction: f64) {
        self.push(Event::Progress(stage.into(), fraction));
    }
    fn finished(&self, stage: &str) {
        self.push(Event::Finished(stage.into()));
    }
    fn tracing(&self) -> bool {
        self.tracing
    }
    fn trace(&self, line: &str) {
        self.push(Event::Trace(line.into()));
    }
    fn remaining(&self, _stage: &str, phase: &str, seconds: f64) {
        self.push(Event::Remaining(phase.into(), seconds));
    }
}

#[cfg(test)]
mod tests {
    use super::Event::{Finished, Progress, Trace};
    use super::*;

    fn p(stage: &str, f: f64) -> Event {
        Progress(stage.into(), f)
    }

    #[test]
    fn silent_wants_no_trace_and_accepts_everything() {
        let o: &dyn Observer = &SILENT;
        assert!(!o.tracing());
        o.progress("solve", 0.5);
        o.finished("solve");
        o.trace("ignored");
    }

    #[test]
    fn stage_forwards_a_clamped_non_decreasing_sequence_then_finishes() {
        let r = Recorder::default();
        {
            let mut s = Stage::start(&r, "solve");
            for f in [0.25, 0.1, f64::NAN, 0.25, 0.5, -1.0, 7.0, 1.0] {
                s.advance(f);
            }
            assert!(!s.observer().tracing());
        }
        assert_eq!(
            r.events(),
            [
                p("solve", 0.0),
                p("solve", 0.25),
                p("solve", 0.5),
                p("solve", 1.0),
                Finished("solve".into())
            ]
        );
    }

    #[test]
    fn stage_finishes_on_early_exit() {
        let r = Recorder::default();
        let run = |fail: bool| -> Result<(), ()> {
            let mut s = Stage::start(&r, "load");
            if fail {
                return Err(());
            }
            s.advance(1.0);
            Ok(())
        };
        assert!(run(true).is_err());
        assert_eq!(r.events(), [p("load", 0.0), Finished("load".into())]);
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let _s = Stage::start(&r, "boom");
            panic!("inside the stage");
        }));
        assert!(caught.is_err());
        assert_eq!(r.events()[2..], [p("boom", 0.0), Finished("boom".into())]);
    }

    #[test]
    fn labelled_names_every_stage_with_its_context_and_nests() {
        let r = Recorder::tracing();
        // The results job labels its scene, the sweep it runs then its density.
        let scene = Labelled::new(&r, "scene 2/3 cornell-box");
        let density = Labelled::new(&scene, "density 3/5");
        {
            let mut s = Stage::start(&density, "solve");
            s.advance(0.5);
            s.remaining("round 1 gather", 4.0);
            assert!(s.observer().tracing());
        }
        let name = "solve (scene 2/3 cornell-box, density 3/5)";
        assert_eq!(
            r.events(),
            [
                p(name, 0.0),
                p(name, 0.5),
                Event::Remaining("round 1 gather".into(), 4.0),
                Finished(name.into())
            ]
        );
        assert_eq!(Labelled::new(&r, "").label("solve"), "solve");
    }

    #[test]
    fn observer_is_shared_across_threads() {
        let r = Recorder::tracing();
        let o: &dyn Observer = &r;
        std::thread::scope(|s| {
            for i in 0..4 {
                s.spawn(move || {
                    if o.tracing() {
                        o.trace(&format!("worker {i}"));
                    }
                });
            }
        });
        let mut lines: Vec<String> = r
            .events()
            .into_iter()
            .map(|e| match e {
                Trace(l) => l,
                other => panic!("unexpected {other:?}"),
            })
            .collect();
        lines.sort();
        assert_eq!(lines, ["worker 0", "worker 1", "worker 2", "worker 3"]);
    }
}
