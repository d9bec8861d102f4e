//! The `pixelflow-sim` command line: parses arguments and calls the library.
//!
//! The binary is thin: clap validates the arguments, the library does the work, and every
//! library error is printed once to stderr and mapped to the exit code of
//! [`pixelflow_sim::Error::exit_code`]: 0 success, 2 bad input or usage (clap's own usage errors
//! also exit 2), 1 a failure while running.

use anyhow::Context;
use clap::{Parser, Subcommand};
use pixelflow_sim::error::EXIT_FAILURE;
use std::path::PathBuf;
use std::process::ExitCode;

/// Renders radiosity solutions with C1 bicubic Hermite reconstruction (Bastos, Goslin, Zhang).
#[derive(Parser, Debug)]
#[command(name = "pixelflow-sim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Load and validate a scene file, print its warnings and a summary.
    ///
    /// Reads the TOML scene (and its OBJ/MTL includes), checks every value, and prints a table
    /// of polygons, materials, emitters, spot lights, bounds and the estimated memory of the
    /// radiosity solve. Warnings (such as non-planar quads that were split) go to stderr.
    /// Exit code 0 if the scene is valid, 2 if it is not (the message names file, line and key).
    Check {
        /// The scene file (`scenes/cornell-box.toml`).
        scene: PathBuf,
    },
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Check { scene } => {
            let s = pixelflow_sim::scene::load_scene(&scene)?;
            for w in &s.warnings {
                eprintln!("warning: {w}");
            }
            let summary = pixelflow_sim::report::summarize(&s);
            use std::io::Write;
            let mut out = std::io::stdout().lock();
            write!(out, "{summary}")
                .and_then(|_| out.flush())
                .context("writing the summary to stdout")?;
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            let code = e
                .downcast_ref::<pixelflow_sim::Error>()
                .map_or(EXIT_FAILURE, |e| e.exit_code());
            ExitCode::from(u8::try_from(code).unwrap_or(1))
        }
    }
}
