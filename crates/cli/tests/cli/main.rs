//! The cli integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

/// The binary under test, run from the repository root (as a user runs it after cloning).
pub fn bin() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_pixelflow-sim"));
    c.current_dir(REPO);
    c
}

/// Peak resident bytes of the binary run with `args` from the repository root (the run must
/// succeed), from the kernel's own count for that one child (`wait4`'s `ru_maxrss`), so tests
/// running side by side do not see each other's memory.
pub fn peak_bytes(args: &[&str]) -> u64 {
    let (code, peak, err) = run_measured(args);
    assert_eq!(code, Some(0), "{args:?}: {err}");
    peak
}

/// Runs the binary with `args` from the repository root; returns its exit code, its peak
/// resident bytes and its stderr.
// The child is reaped by `wait4`, which the lint cannot see.
#[allow(clippy::zombie_processes)]
pub fn run_measured(args: &[&str]) -> (Option<i32>, u64, String) {
    use std::io::Read;
    let mut child = bin()
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let mut err = String::new();
    child
        .stderr
        .take()
        .expect("stderr is piped")
        .read_to_string(&mut err)
        .expect("stderr reads");
    let mut status = 0;
    // SAFETY: an all-zero rusage is a valid value of that plain C struct.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let pid = child.id() as libc::pid_t;
    // SAFETY: `pid` is this process's own unwaited child; `status` and `usage` are valid for
    // writes. The child is reaped here, so `child` is never waited on again.
    let r = unsafe { libc::wait4(pid, &mut status, 0, &mut usage) };
    assert_eq!(r, pid, "wait4 failed");
    let code = libc::WIFEXITED(status).then(|| libc::WEXITSTATUS(status));
    // Linux reports ru_maxrss in KiB.
    (code, usage.ru_maxrss as u64 * 1024, err)
}

mod architecture;
mod cli_check;
mod cli_compare;
mod cli_methods;
mod cli_render;
mod generate;
mod hard_cases;
mod interrupt;
mod results;
mod sweep;
mod truth;
