//! How well the solve's progress follows its running time: one solve of a scene with an observer
//! that stamps every progress and remaining-time report with the seconds since the stage started,
//! then the largest gap between the fraction shown and elapsed / total time over the run.
//!
//! ```text
//! cargo run --release -p pixelflow-study --example progress_fidelity [scene.toml ...]
//! ```
//!
//! Default: `scenes/cornell-box.toml`. Per scene it prints the solve's seconds, the largest
//! |fraction - elapsed / total| (the fraction shown is the latest reported, a step function, so
//! it is taken just before and just after every report), where that gap was, how long the bar
//! sat at 100 % before the stage ended, and the longest time the remaining-time estimate read
//! under 1 s while more than 5 s of the solve were still to come. docs/performance.md quotes it.
//! With `PROGRESS_FIDELITY_TRACE` set the solver's trace lines go to stderr stamped with the
//! same clock; with `PROGRESS_FIDELITY_DUMP` set, every (seconds, fraction) report, then
//! every remaining-time report as `R seconds estimate`.

use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

use base::progress::Observer;
use radiosity::{solve, SolveOptions};

/// What the observer saw: (seconds since the stage started, value), per kind of report.
#[derive(Default)]
struct Log {
    start: Option<Instant>,
    end: Option<f64>,
    fractions: Vec<(f64, f64)>,
    remaining: Vec<(f64, f64)>,
}

/// The stamping observer (only the stage `solve`).
#[derive(Default)]
struct Stamps {
    log: Mutex<Log>,
    /// Whether trace lines are printed (on stderr, stamped).
    tracing: bool,
}

impl Stamps {
    fn with(&self, f: impl FnOnce(&mut Log, f64)) {
        let mut log = self.log.lock().expect("log lock");
        let start = *log.start.get_or_insert_with(Instant::now);
        f(&mut log, start.elapsed().as_secs_f64());
    }
}

impl Observer for Stamps {
    fn progress(&self, stage: &str, fraction: f64) {
        if stage.starts_with("solve") {
            self.with(|log, t| log.fractions.push((t, fraction)));
        }
    }
    fn finished(&self, stage: &str) {
        if stage.starts_with("solve") {
            self.with(|log, t| log.end = Some(t));
        }
    }
    fn remaining(&self, stage: &str, _phase: &str, seconds: f64) {
        if stage.starts_with("solve") {
            self.with(|log, t| log.remaining.push((t, seconds)));
        }
    }
    fn tracing(&self) -> bool {
        self.tracing
    }
    fn trace(&self, line: &str) {
        self.with(|_, t| eprintln!("{t:8.3} {line}"));
    }
}

/// The largest |shown fraction - t / total| and the time it occurred.
fn largest_gap(fractions: &[(f64, f64)], total: f64) -> (f64, f64) {
    let mut worst = (0.0_f64, 0.0_f64);
    let mut shown = 0.0;
    let mut consider = |t: f64, f: f64| {
        let gap = (f - t / total).abs();
        if gap > worst.0 {
            worst = (gap, t);
        }
    };
    for &(t, f) in fractions {
        consider(t, shown);
        shown = f;
        consider(t, shown);
    }
    consider(total, shown);
    worst
}

/// Seconds the bar showed 100 % (>= 0.999) before the stage ended.
fn full_before_end(fractions: &[(f64, f64)], total: f64) -> f64 {
    fractions
        .iter()
        .find(|&&(_, f)| f >= 0.999)
        .map_or(0.0, |&(t, _)| total - t)
}

/// The longest stretch in which the latest estimate read under 1 s while more than 5 s of the
/// stage remained.
fn longest_zero_eta(remaining: &[(f64, f64)], total: f64) -> f64 {
    let mut longest = 0.0_f64;
    let mut since: Option<f64> = None;
    for (i, &(t, s)) in remaining.iter().enumerate() {
        let until = remaining.get(i + 1).map_or(total, |r| r.0);
        if s < 1.0 && total - t > 5.0 {
            let from = *since.get_or_insert(t);
            longest = longest.max(until.min(total - 5.0) - from);
        } else {
            since = None;
        }
    }
    longest
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut paths: Vec<PathBuf> = std::env::args().skip(1).map(PathBuf::from).collect();
    if paths.is_empty() {
        paths.push("scenes/cornell-box.toml".into());
    }
    println!("| scene | solve (s) | largest gap | at (s) | at 100 % for (s) | ETA < 1 s with > 5 s left (s) |");
    println!("|---|---:|---:|---:|---:|---:|");
    for path in paths {
        let scene = scene::load_scene(&path)?;
        let stamps = Stamps {
            tracing: std::env::var_os("PROGRESS_FIDELITY_TRACE").is_some(),
            ..Stamps::default()
        };
        solve(
            &scene,
            &SolveOptions {
                observer: &stamps,
                memory_limit: u64::MAX,
                snapshots: None,
            },
        )?;
        let log = stamps.log.into_inner().expect("log lock");
        let total = log.end.unwrap_or(0.0).max(1e-9);
        let (gap, at) = largest_gap(&log.fractions, total);
        println!(
            "| {} | {total:.1} | {gap:.3} | {at:.1} | {:.1} | {:.1} |",
            path.display(),
            full_before_end(&log.fractions, total),
            longest_zero_eta(&log.remaining, total)
        );
        if std::env::var_os("PROGRESS_FIDELITY_DUMP").is_some() {
            for (t, f) in &log.fractions {
                eprintln!("{t:.3} {f:.4}");
            }
            for (t, s) in &log.remaining {
                eprintln!("R {t:.3} {s:.2}");
            }
        }
    }
    Ok(())
}
