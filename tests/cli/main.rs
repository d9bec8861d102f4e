//! The cli integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = env!("CARGO_MANIFEST_DIR");

/// The binary under test, run from the repository root (as a user runs it after cloning).
pub fn bin() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_pixelflow-sim"));
    c.current_dir(REPO);
    c
}

/// Whether child peaks can be measured: `/usr/bin/time` is present. A child's own `wait4`
/// count is no substitute: on exec the kernel folds the spawning process's high-water mark
/// into the child's (a test binary holding 400 MiB made a 25 MiB solve read as 445 MiB), and
/// `/usr/bin/time` spawns the measured program from its own small process. Tests that need it
/// print a NOT RUN line and return where it is missing.
pub fn can_measure_peaks() -> bool {
    let present = std::path::Path::new("/usr/bin/time").exists();
    if !present {
        eprintln!("NOT RUN: memory-peak check (/usr/bin/time is missing; apt-get install time)");
    }
    present
}

/// Peak resident bytes of the binary run with `args` from the repository root (the run must
/// succeed), measured by `/usr/bin/time` ([`can_measure_peaks`]).
pub fn peak_bytes(args: &[&str]) -> u64 {
    let (code, peak, err) = run_measured(args);
    assert_eq!(code, Some(0), "{args:?}: {err}");
    peak
}

/// Runs the binary with `args` from the repository root under `/usr/bin/time`; returns its
/// exit code, its peak resident bytes and its stderr (without the measurement line).
pub fn run_measured(args: &[&str]) -> (Option<i32>, u64, String) {
    const TAG: &str = "pfs-peak-kib ";
    let o = std::process::Command::new("/usr/bin/time")
        .args(["-f", &format!("{TAG}%M")])
        .arg(env!("CARGO_BIN_EXE_pixelflow-sim"))
        .current_dir(REPO)
        .args(args)
        .output()
        .expect("/usr/bin/time runs");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let (rest, kib) = err
        .rsplit_once(TAG)
        .unwrap_or_else(|| panic!("no peak in {err}"));
    let kib: u64 = kib
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("no peak in {err}"));
    // GNU time exits with the program's status; a signal's death shows as "Command exited".
    (o.status.code(), kib * 1024, rest.to_string())
}

mod architecture;
mod cli_check;
mod cli_compare;
mod cli_methods;
mod cli_render;
mod compare_ci;
mod export;
mod generate;
mod hard_cases;
mod interrupt;
mod models;
mod results;
mod simd_build;
mod sweep;
mod truth;
mod view;
