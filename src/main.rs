//! The `pixelflow-sim` command line: parses arguments and calls the library.
//!
//! The binary is thin: clap validates the arguments, the library does the work, and every
//! library error is printed once to stderr and mapped to the exit code of
//! [`base::Error::exit_code`]: 0 success, 2 bad input or usage (clap's own usage errors
//! also exit 2), 1 a failure while running. The library draws nothing: the progress bar and the
//! `--trace` lines are the command line's observer ([`terminal::Terminal`]). Each subcommand is a
//! function of [`commands`], with its options from [`args`].

use base::error::EXIT_FAILURE;
use base::output::Outputs;
use clap::Parser;
use std::io::Write;
use std::process::ExitCode;

mod args;
mod commands;
mod terminal;
mod view;

use args::{Cli, Command, Generate};
use commands::Settings;

/// Standard output closed by the reader (`pixelflow-sim ... | head`): not a failure of the
/// job, which is done; the program ends quietly with exit code 0.
#[derive(Debug)]
struct StdoutClosed;

impl std::fmt::Display for StdoutClosed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("standard output closed")
    }
}

impl std::error::Error for StdoutClosed {}

/// Writes `text` to standard output; a closed pipe becomes [`StdoutClosed`].
fn out(text: &str) -> anyhow::Result<()> {
    let mut o = std::io::stdout().lock();
    match o.write_all(text.as_bytes()).and_then(|_| o.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(StdoutClosed.into()),
        Err(e) => Err(anyhow::anyhow!("writing to standard output: {e}")),
    }
}

/// A line on standard error (warnings, "wrote" lines); an unwritable stderr is ignored, as there
/// is nowhere left to report it.
fn note(text: &str) {
    let _ = writeln!(std::io::stderr().lock(), "{text}");
}

/// JSON of `value`, pretty, with a newline.
fn json<T: serde::Serialize>(value: &T) -> anyhow::Result<String> {
    Ok(serde_json::to_string_pretty(value)? + "\n")
}

/// Builds the shared settings (before any job, so a bad `PIXELFLOW_SIM_LANES` is refused by every
/// subcommand) and runs the subcommand.
fn run(cli: Cli, outputs: Outputs) -> anyhow::Result<()> {
    let settings = Settings::new(cli.memory_limit, outputs)?;
    match cli.command {
        Command::Check(args) => commands::check(&settings, args),
        Command::Solve(args) => commands::solve(&settings, args),
        Command::Render(args) => commands::render(&settings, args),
        Command::Stats(args) => commands::stats(&settings, args),
        Command::Experiment(args) => commands::experiment(&settings, args),
        Command::Bench(args) => commands::bench(&settings, args),
        Command::Sweep(args) => commands::sweep(&settings, args),
        Command::Results(args) => commands::results(&settings, args),
        Command::Generate(Generate::Building(args)) => commands::generate_building(&settings, args),
        Command::Compare(args) => commands::compare(&settings, args),
        Command::Truth(args) => commands::truth(&settings, args),
        Command::Export(args) => commands::export(&settings, args),
        Command::View(args) => view::view(&settings, args),
        Command::TimeWorker(args) => commands::time_worker(&settings, args),
    }
}

/// Exit code after SIGINT or SIGTERM (128 + SIGINT, the shell's convention for an interrupt).
const EXIT_INTERRUPTED: i32 = 130;

/// Fixes glibc's threshold for serving allocations by `mmap` at its starting 128 KiB. By default
/// glibc raises it to the size of each large block freed (up to 32 MiB), so later large
/// buffers come from the per-thread arenas and stay resident after they are freed: the Cornell
/// box solved under `--memory-limit 26M` peaked at 34.4-38.6 MiB resident with a 16.3 MiB heap,
/// and 30.1-30.3 MiB with the threshold fixed, at the same solve and frame times. The memory
/// guards count what the stages hold, so the allocator's slack is kept small instead.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn allocator_policy() {
    // SAFETY: `mallopt` only sets a parameter of the allocator, before any thread exists; a
    // refusal (return value 0) leaves glibc's default, which is also correct.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 * 1024);
    }
}

/// Other allocators keep their own policy.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn allocator_policy() {}

fn main() -> ExitCode {
    allocator_policy();
    let cli = Cli::parse();
    // SIGINT / SIGTERM: remove the temporaries of outputs being written (after any batch of
    // renames in progress finishes) and exit, so an interrupted run leaves no hidden files and
    // never half of a run's outputs replaced. If the handler cannot be installed the run goes
    // on with the default signal behaviour.
    let outputs = Outputs::new();
    let live = outputs.clone();
    let watch = outputs.clone();
    let _ = ctrlc::set_handler(move || {
        live.interrupt();
        note("interrupted");
        std::process::exit(EXIT_INTERRUPTED);
    });
    let result = run(cli, outputs);
    // A signal during the last batch of renames waits for it; the run must not then report
    // success while the handler is still on its way to exit.
    if watch.interrupted() {
        std::process::exit(EXIT_INTERRUPTED);
    }
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<StdoutClosed>() => ExitCode::SUCCESS,
        Err(mut e) => {
            spell_options(&mut e);
            note(&format!("error: {e:#}"));
            ExitCode::from(u8::try_from(exit_code(&e)).unwrap_or(1))
        }
    }
}

/// Names the library's options as the user typed them: a setting the library calls `aa` is
/// the flag `--aa`, `output` is `-o` (a flag's short form where it has one); names of no flag
/// (scene keys such as `render.aa`) stay as they are. The library never spells a flag, so this
/// table, made from the argument definitions, is the one place flags and settings meet.
fn spell_options(e: &mut anyhow::Error) {
    let Some(e) = e.downcast_mut::<base::Error>() else {
        return;
    };
    let mut flags = std::collections::HashMap::new();
    let mut stack = vec![<Cli as clap::CommandFactory>::command()];
    while let Some(c) = stack.pop() {
        for a in c.get_arguments() {
            let spelt = match (a.get_short(), a.get_long()) {
                (Some(s), _) => format!("-{s}"),
                (None, Some(l)) => format!("--{l}"),
                (None, None) => continue,
            };
            flags.insert(a.get_id().to_string(), spelt.clone());
            if let Some(l) = a.get_long() {
                flags.insert(l.to_string(), spelt);
            }
        }
        stack.extend(c.get_subcommands().cloned());
    }
    // A name may say in parentheses which of a flag's values it means (`doc (data)`): the
    // flag, then the rest. Other names with spaces (`generated polygons`) are not flags.
    e.name_options(|name| {
        flags.get(name).cloned().or_else(|| {
            let (head, rest) = name.split_once(" (")?;
            Some(format!("{} ({rest}", flags.get(head)?))
        })
    });
}

/// The exit code of a run that ended with `e`: the library error's own (2 for bad input), 1
/// for anything else.
fn exit_code(e: &anyhow::Error) -> i32 {
    e.downcast_ref::<base::Error>()
        .map_or(EXIT_FAILURE, |e| e.exit_code())
}
