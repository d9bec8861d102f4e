//! The cli integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

/// The binary under test, run from the repository root (as a user runs it after cloning).
pub fn bin() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_pixelflow-sim"));
    c.current_dir(REPO);
    c
}

/// Peak resident bytes of the binary run with `args` from the repository root, measured by
/// `/usr/bin/time -f %M` (the run must succeed); `None` where that tool is missing.
pub fn peak_bytes(args: &[&str]) -> Option<u64> {
    if !std::path::Path::new("/usr/bin/time").exists() {
        return None;
    }
    let o = std::process::Command::new("/usr/bin/time")
        .args(["-f", "%M"])
        .arg(env!("CARGO_BIN_EXE_pixelflow-sim"))
        .current_dir(REPO)
        .args(args)
        .output()
        .expect("/usr/bin/time runs");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {err}");
    let kib: u64 = err
        .trim()
        .lines()
        .last()
        .and_then(|l| l.trim().parse().ok())
        .unwrap_or_else(|| panic!("no peak in {err}"));
    Some(kib * 1024)
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
