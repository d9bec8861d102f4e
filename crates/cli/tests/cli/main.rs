//! The cli integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

/// The binary under test, run from the repository root (as a user runs it after cloning).
pub fn bin() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_pixelflow-sim"));
    c.current_dir(REPO);
    c
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
