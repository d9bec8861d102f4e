//! Frame times a reviewer can trust. The repeats of one process share its memory layout, its
//! CPU's clock and whatever else ran beside it, so they spread less than the time another run
//! would measure. A timing point is therefore measured in several separate processes: the same
//! program started again as a *worker* that loads the solution from a file, builds what the
//! parent would draw, draws it and prints its frame times. The point's time is the median over
//! the processes, with a distribution-free confidence interval for that median (order
//! statistics: the interval between the k-th smallest and k-th largest of n process medians
//! covers the true median with probability `1 - 2 P(Bin(n, 1/2) < k)`, whatever the
//! distribution of times).
//!
//! While each worker runs, the CPU time the rest of the machine used is read from `/proc/stat`
//! (all CPUs' busy time less the worker's own, over its wall time, in cores): the load the times
//! were measured under, recorded and flagged when it is high enough to have moved them. On a
//! system without `/proc` the load is not recorded (and said so).
//!
//! Invariants: a worker draws the same candidates in the same order as its parent (the parent
//! refuses a reply of another length); a worker changes no file; the parent removes the
//! solution files it wrote for its workers.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use app::context::Context;
use app::prepare::Prepared;
use base::error::{Error, Result};
use base::progress::{Observer, Stage};

/// Processes each timing point is measured in by default: the fewest whose extreme medians
/// bound a 95 % confidence interval for the median (coverage `1 - 2/2^6 = 96.9 %`).
pub const DEFAULT_PROCESSES: u32 = 6;

/// The confidence the intervals are asked for.
pub const CONFIDENCE: f64 = 0.95;

/// Other work's average CPU use, in cores, above which a worker's times are flagged: a quarter
/// of a core taken from a frame that uses every core moves its time by several per cent.
pub const HIGH_LOAD_CORES: f64 = 0.25;

/// Shortest worker whose load is recorded, s: the counters tick every 10 ms, so a shorter run's
/// share of busy ticks says little.
const MIN_LOAD_SECONDS: f64 = 1.0;

/// The clock ticks per second of `/proc/stat` and `/proc/<pid>/stat` (`USER_HZ`, 100 on every
/// Linux architecture: it is part of the kernel's user-space interface).
const USER_HZ: f64 = 100.0;

/// How to measure in separate processes: the program to start as a worker and how many times.
#[derive(Debug, Clone, PartialEq)]
pub struct TimingProcesses {
    /// The `pixelflow-sim` binary (it runs `pixelflow-sim time-worker <request>`).
    pub exe: PathBuf,
    /// Workers per timing point.
    pub count: u32,
}

/// A confidence interval of a median.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
    /// The probability that the interval covers the median (below [`CONFIDENCE`] when there are
    /// too few samples for that: then it is the whole range of the samples).
    pub coverage: f64,
}

impl Interval {
    /// Whether `self` lies wholly below `other` (no overlap).
    pub fn below(&self, other: &Interval) -> bool {
        self.hi < other.lo
    }
}

/// `P(Bin(n, 1/2) <= k)`.
fn binomial_half_cdf(n: usize, k: usize) -> f64 {
    let mut c = 1.0f64; // C(n, 0)
    let mut sum = 0.0;
    for i in 0..=k.min(n) {
        sum += c;
        c = c * (n - i) as f64 / (i + 1) as f64;
    }
    sum * 0.5f64.powi(n as i32)
}

/// For `n >= 1` samples, the largest `k` whose order-statistic interval `[x_(k), x_(n+1-k)]`
/// covers the median with probability at least `confidence` (1 when even the whole range falls
/// short), and that interval's coverage.
pub fn order_statistic(n: usize, confidence: f64) -> (usize, f64) {
    let coverage = |k: usize| (1.0 - 2.0 * binomial_half_cdf(n, k - 1)).max(0.0);
    let mut k = 1;
    while 2 * (k + 1) <= n + 1 && coverage(k + 1) >= confidence {
        k += 1;
    }
    (k, coverage(k))
}

/// The narrowest order-statistic interval of the samples whose coverage of the median is at
/// least `confidence` ([`order_statistic`]); the whole range (with its smaller coverage) when
/// even that falls short; `None` for no samples.
pub fn median_interval(xs: &[f64], confidence: f64) -> Option<Interval> {
    let mut s = xs.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n == 0 {
        return None;
    }
    let (k, coverage) = order_statistic(n, confidence);
    Some(Interval {
        lo: s[k - 1],
        hi: s[n - k],
        coverage,
    })
}

/// The machine's load while one worker ran.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LoadSample {
    /// What the worker timed (`density 2`, `walkthrough`).
    pub what: String,
    /// Average CPU use of everything but the worker, in cores (busy time of all CPUs less the
    /// worker's own CPU time, over its wall time); `None` without `/proc`, or for a worker
    /// shorter than a second (the counters tick every 10 ms).
    pub other_cores: Option<f64>,
    /// The one-minute load average when the worker started; `None` without `/proc`.
    pub load_average: Option<f64>,
    /// The worker's wall time, s.
    pub seconds: f64,
}

impl LoadSample {
    /// Whether other work used more than [`HIGH_LOAD_CORES`].
    pub fn high(&self) -> bool {
        self.other_cores.is_some_and(|c| c > HIGH_LOAD_CORES)
    }
}

/// How many of `load`'s processes ran under high load ([`LoadSample::high`]).
pub fn high_load(load: &[LoadSample]) -> usize {
    load.iter().filter(|l| l.high()).count()
}

/// The largest other-work load of `load`, in cores (`None` when none was recorded).
pub fn peak_load(load: &[LoadSample]) -> Option<f64> {
    load.iter()
        .filter_map(|l| l.other_cores)
        .max_by(f64::total_cmp)
}

/// Busy and total clock ticks of all CPUs since boot (`/proc/stat`'s `cpu` line; steal counts
/// as busy: time the hypervisor gave to others).
fn cpu_ticks() -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let line = stat.lines().next()?.strip_prefix("cpu ")?;
    let v: Vec<u64> = line
        .split_whitespace()
        .map(|t| t.parse().ok())
        .collect::<Option<_>>()?;
    // user nice system idle iowait irq softirq steal (guest time is inside user).
    let get = |i: usize| v.get(i).copied().unwrap_or(0);
    let idle = get(3) + get(4);
    let busy = get(0) + get(1) + get(2) + get(5) + get(6) + get(7);
    Some((busy, busy + idle))
}

/// This process's CPU time (user + system), s; `None` without `/proc`.
pub fn own_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start at its closing parenthesis;
    // utime and stime are fields 14 and 15 of the whole line.
    let rest = &stat[stat.rfind(')')? + 1..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / USER_HZ)
}

/// The one-minute load average.
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// A job a timing worker can run: its request travels as JSON on the worker's command line
/// (`pixelflow-sim time-worker <request>`), tagged with [`WorkerTask::JOB`]. This module knows
/// the protocol and no job: each study implements the trait for its own request, and the
/// worker's dispatch ([`crate::worker`]) names them.
pub trait WorkerTask: Serialize + DeserializeOwned + Sync {
    /// The job's name in the request.
    const JOB: &'static str;
    /// The worker threads the parent ran with.
    fn threads(&self) -> usize;
    /// Per candidate, the median frame time of each repeat, ms (the same candidates in the
    /// same order as the parent's).
    fn times(&self, job: &Context<'_>) -> Result<Vec<Vec<f64>>>;
}

/// A request as it travels: the job's name and its fields.
#[derive(Serialize, Deserialize)]
struct Envelope<T> {
    job: String,
    request: T,
}

/// The command-line argument that asks a worker for `task`.
pub fn request_json<T: WorkerTask>(task: &T) -> Result<String> {
    serde_json::to_string(&Envelope {
        job: T::JOB.to_string(),
        request: task,
    })
    .map_err(|e| Error::internal(e.to_string()))
}

/// The job a request asks for (an [`Error::InvalidOption`] for text that is not a request).
pub fn job_of(request: &str) -> Result<String> {
    let e: Envelope<serde_json::Value> = serde_json::from_str(request)
        .map_err(|e| Error::invalid_option("time-worker", request, e.to_string()))?;
    Ok(e.job)
}

/// Serves a request for job `T`: runs it with the parent's thread count and returns the reply
/// as JSON ([`WorkerReply`]).
pub fn serve<T: WorkerTask>(job: &Context<'_>, request: &str) -> Result<String> {
    let e: Envelope<T> = serde_json::from_str(request)
        .map_err(|e| Error::invalid_option("time-worker", request, e.to_string()))?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(e.request.threads().max(1))
        .build()
        .map_err(|e| Error::Runtime(format!("worker threads: {e}")))?;
    let ms = pool.install(|| e.request.times(job))?;
    let reply = WorkerReply {
        ms,
        cpu_seconds: own_cpu_seconds(),
    };
    serde_json::to_string(&reply).map_err(|e| Error::internal(e.to_string()))
}

/// Runs `f` with `p`'s solution written to a temporary solution file for
/// workers to load, removed afterwards whatever `f` returns; `tag` keeps files apart.
pub fn with_solution_file<T>(
    p: &Prepared,
    tag: &str,
    f: impl FnOnce(&Path) -> Result<T>,
) -> Result<T> {
    let file = std::env::temp_dir().join(format!(
        "pixelflow-sim-timing-{}-{tag}.pfsol",
        std::process::id()
    ));
    radiosity::file::write_solution(&base::output::Outputs::new(), &file, &p.solution, None)?;
    let result = f(&file);
    let _ = std::fs::remove_file(&file);
    result
}

/// What a worker prints: each candidate's frame times and the worker's own CPU time.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WorkerReply {
    /// Per candidate, the median frame time of each repeat, ms.
    pub ms: Vec<Vec<f64>>,
    /// The worker's CPU time at its end, s (`None` without `/proc`).
    pub cpu_seconds: Option<f64>,
}

/// Runs `exe time-worker <request>` `count` times one after the other and returns, per
/// candidate, each process's median frame time, with the load each process ran under (labelled
/// `what`). Reports stage `timing (what)` to `observer`, one step per process.
pub fn in_processes<T: WorkerTask>(
    tp: &TimingProcesses,
    request: &T,
    candidates: usize,
    what: &str,
    observer: &dyn Observer,
) -> Result<(Vec<Vec<f64>>, Vec<LoadSample>)> {
    let name = format!("timing ({what})");
    let mut stage = Stage::start(observer, &name);
    let request = request_json(request)?;
    let mut per_candidate = vec![Vec::new(); candidates];
    let mut load = Vec::new();
    for k in 0..tp.count {
        let before = cpu_ticks();
        let load_average = load_average();
        let t = Instant::now();
        let out = Command::new(&tp.exe)
            .arg("time-worker")
            .arg(&request)
            .output()
            .map_err(|e| Error::Runtime(format!("cannot start {}: {e}", tp.exe.display())))?;
        let seconds = t.elapsed().as_secs_f64();
        let after = cpu_ticks();
        if !out.status.success() {
            return Err(Error::Runtime(format!(
                "timing worker {} failed ({}): {}",
                tp.exe.display(),
                out.status,
                String::from_utf8_lossy(&out.stderr).trim()
            )));
        }
        let reply: WorkerReply = serde_json::from_slice(&out.stdout)
            .map_err(|e| Error::Runtime(format!("timing worker's reply: {e}")))?;
        if reply.ms.len() != candidates {
            return Err(Error::internal(format!(
                "a timing worker drew {} candidates, its parent {candidates}",
                reply.ms.len()
            )));
        }
        for (all, reps) in per_candidate.iter_mut().zip(reply.ms) {
            all.push(app::rates::median(reps));
        }
        let other_cores = match (before, after, reply.cpu_seconds) {
            (Some(b), Some(a), Some(own)) if seconds >= MIN_LOAD_SECONDS => {
                let busy = a.0.saturating_sub(b.0) as f64 / USER_HZ;
                Some(((busy - own) / seconds).max(0.0))
            }
            _ => None,
        };
        load.push(LoadSample {
            what: what.to_string(),
            other_cores,
            load_average,
            seconds,
        });
        stage.advance((k + 1) as f64 / tp.count as f64);
    }
    Ok((per_candidate, load))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binomial_half_cdf_by_hand() {
        // C(6, 0) / 64, (1 + 6 + 15) / 64, all of it.
        assert_eq!(binomial_half_cdf(6, 0), 1.0 / 64.0);
        assert_eq!(binomial_half_cdf(6, 2), 22.0 / 64.0);
        assert_eq!(binomial_half_cdf(6, 6), 1.0);
    }

    #[test]
    fn six_processes_give_the_range_at_96_9_percent() {
        let i = median_interval(&[3.0, 1.0, 2.0, 6.0, 5.0, 4.0], CONFIDENCE).unwrap();
        assert_eq!((i.lo, i.hi), (1.0, 6.0));
        assert!((i.coverage - (1.0 - 2.0 / 64.0)).abs() < 1e-15);
    }

    #[test]
    fn ten_processes_drop_one_from_each_end() {
        // k = 2: 1 - 2 (1 + 10) / 1024 = 0.9785; k = 3 would give 1 - 2 * 56 / 1024 = 0.891.
        let xs: Vec<f64> = (1..=10).map(f64::from).collect();
        let i = median_interval(&xs, CONFIDENCE).unwrap();
        assert_eq!((i.lo, i.hi), (2.0, 9.0));
        assert!((i.coverage - (1.0 - 22.0 / 1024.0)).abs() < 1e-15);
    }

    #[test]
    fn too_few_samples_give_the_range_with_its_smaller_coverage() {
        let i = median_interval(&[2.0, 1.0, 3.0, 5.0, 4.0], CONFIDENCE).unwrap();
        assert_eq!((i.lo, i.hi), (1.0, 5.0));
        assert!((i.coverage - 0.9375).abs() < 1e-15);
        let one = median_interval(&[7.0], CONFIDENCE).unwrap();
        assert_eq!((one.lo, one.hi, one.coverage), (7.0, 7.0, 0.0));
        assert!(median_interval(&[], CONFIDENCE).is_none());
    }

    #[test]
    fn own_cpu_time_is_read_where_proc_exists() {
        if std::path::Path::new("/proc/self/stat").exists() {
            let mut x = 0u64;
            for i in 0..20_000_000u64 {
                x = x.wrapping_mul(31).wrapping_add(i);
            }
            assert!(x != 1);
            let s = own_cpu_seconds().unwrap();
            assert!(s.is_finite() && s >= 0.0, "{s}");
            let (busy, total) = cpu_ticks().unwrap();
            assert!(busy <= total);
        }
    }
}
