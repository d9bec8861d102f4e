//! The `pixelflow-sim` command line: parses arguments and calls the library.

use clap::Parser;

/// Renders radiosity solutions with C1 bicubic Hermite reconstruction (Bastos, Goslin, Zhang).
#[derive(Parser, Debug)]
#[command(name = "pixelflow-sim", version, about)]
struct Cli {}

fn main() {
    let _cli = Cli::parse();
}
