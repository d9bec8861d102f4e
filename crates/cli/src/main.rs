//! The `pixelflow-sim` command line: parses arguments and calls the library.
//!
//! The binary is thin: clap validates the arguments, the library does the work, and every
//! library error is printed once to stderr and mapped to the exit code of
//! [`base::Error::exit_code`]: 0 success, 2 bad input or usage (clap's own usage errors
//! also exit 2), 1 a failure while running. The library draws nothing: the progress bar and the
//! `--trace` lines are this file's observer ([`Terminal`]).

use base::error::EXIT_FAILURE;
use base::Error;
use clap::Parser;
use engine::frame::FrameOptions;
use lab::experiment;
use lab::jobs::bench::{bench_table, run_bench, BenchRequest};
use lab::jobs::render::{run_render, RenderEvent, RenderRequest};
use lab::jobs::solve::solve_to_file;
use lab::jobs::stats::{run_stats, StatsRequest};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

mod args;
mod terminal;

use args::{Cli, Command, Generate};
use terminal::Terminal;

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

fn run(cli: Cli) -> anyhow::Result<()> {
    use lab::jobs::budget;
    let limit = cli.memory_limit.unwrap_or_else(budget::default_limit);
    // PIXELFLOW_SIM_LANES caps the instruction set (portable, avx2, avx512, auto), to time the
    // builds against each other; the images are the same.
    let mut isa = lanes::Isa::detect();
    if let Some(v) = std::env::var_os(LANES_ENV) {
        let v = v.to_string_lossy();
        let cap = lanes::Level::parse_cap(&v).map_err(|reason| base::Error::InvalidOption {
            option: LANES_ENV.to_string(),
            value: v.to_string(),
            reason,
        })?;
        if let Some(cap) = cap {
            isa = isa.capped(cap);
        }
    }
    fn context(
        observer: &dyn base::progress::Observer,
        limit: u64,
        isa: lanes::Isa,
    ) -> lab::jobs::Context<'_> {
        lab::jobs::Context::new(observer)
            .with_memory_limit(limit)
            .with_isa(isa)
    }
    match cli.command {
        Command::Check { scene } => {
            let s = scene::load_scene(&scene)?;
            for w in &s.warnings {
                note(&format!("warning: {w}"));
            }
            let summary = lab::report::summarize(&s);
            let b = budget::scene_budget(&s)?;
            let text = lab::report::budget_text(&s, &b, limit);
            out(&format!("{summary}{text}"))?;
            // Over the limit: the same refusal a solve or render of this scene would give.
            b.check(limit)?;
        }
        Command::Solve {
            scene,
            output,
            threads,
            quiet,
            trace,
        } => {
            let observer = Terminal::new(!quiet, trace);
            let sol = in_pool(threads, || {
                solve_to_file(&context(&observer, limit, isa), &scene, &output)
            })??;
            if !quiet {
                let s = &sol.stats;
                note(&format!(
                    "solved {} in {:.0} ms: {} elements, {} samples ({} T-vertices), {} shots, unshot {:.3}%; wrote {}",
                    scene.display(),
                    s.solve_ms,
                    s.elements,
                    s.vertices,
                    s.t_vertices,
                    s.shots,
                    100.0 * s.unshot_fraction,
                    output.display()
                ));
            }
        }
        Command::Render {
            input,
            output,
            exr,
            method,
            width,
            height,
            aa,
            threads,
            renderers,
            region,
            stats,
            walkthrough,
            texture,
            estimator,
            verbose,
            quiet,
            trace,
        } => {
            let req = RenderRequest {
                input,
                output,
                exr,
                method,
                width,
                height,
                aa,
                renderers,
                region,
                stats,
                walkthrough,
                texture: texture.options(),
                estimator,
            };
            let observer = Terminal::new(!quiet, trace);
            let mut stdout_closed = false;
            in_pool(threads, || {
                run_render(
                    &context(&observer, limit, isa),
                    &req,
                    &mut |event| match event {
                        RenderEvent::Warning(w) => observer.note(&format!("warning: {w}")),
                        RenderEvent::Wrote(path) if !quiet => {
                            // Above the walkthrough's bar, not into it.
                            observer.note(&format!("wrote {}", path.display()))
                        }
                        RenderEvent::Frame(report) if verbose && !stdout_closed => {
                            // A closed stdout stops the printing, not the render.
                            stdout_closed = out(&(report.to_json() + "\n")).is_err();
                        }
                        RenderEvent::Walkthrough(summary) if !quiet => {
                            observer.note(&summary.line())
                        }
                        _ => {}
                    },
                )
            })??;
        }
        Command::Stats {
            input,
            frames,
            width,
            height,
            aa,
            texture,
            threads,
            json,
            trace,
        } => in_pool(threads, || -> anyhow::Result<()> {
            let req = StatsRequest {
                input,
                frames,
                frame: FrameOptions {
                    aa,
                    isa,
                    ..FrameOptions::new(width, height)
                },
                texture: texture.options(),
            };
            let stats = run_stats(&context(&Terminal::new(false, trace), limit, isa), &req)?;
            if json {
                out(&self::json(&stats)?)
            } else {
                out(&lab::report::model_stats_text(&stats))
            }
        })??,
        Command::Experiment {
            which,
            out_dir,
            doc,
            scene,
            size,
            ppd,
            estimator,
            scenes,
            frames,
            threads,
            json,
        } => in_pool(threads, || -> anyhow::Result<()> {
            let req = experiment::Request {
                which: experiment::Which::parse(&which)?,
                figures: experiment::FigureOptions {
                    size,
                    ppd,
                    estimator: experiment::parse_estimator(&estimator)?,
                    out_dir: Some(out_dir),
                    ..experiment::FigureOptions::paper(&scene)
                },
                scenes: if scenes.is_empty() {
                    experiment::SHIPPED_SCENES
                        .iter()
                        .map(PathBuf::from)
                        .collect()
                } else {
                    scenes
                },
                frames,
                doc,
            };
            let results = experiment::run(
                &context(&base::progress::SILENT, limit, isa),
                &req,
                &mut |path| note(&format!("wrote {}", path.display())),
            )?;
            if json {
                out(&self::json(&results)?)
            } else {
                out(&experiment::results_text(&results))
            }
        })??,
        Command::Bench {
            input,
            methods,
            texture,
            sizes,
            frames,
            aa,
            renderers,
            region,
            threads,
            json,
            trace,
        } => in_pool(threads, || -> anyhow::Result<()> {
            let req = BenchRequest {
                input,
                methods,
                texture: texture.options(),
                sizes,
                frames,
                aa,
                renderers,
                region,
            };
            let report = run_bench(&context(&Terminal::new(false, trace), limit, isa), &req)?;
            if json {
                out(&self::json(&report.rows)?)
            } else {
                out(&format!(
                    "{}: {} polygons, {} samples, {} RRP patches, {} threads\n{}",
                    report.input,
                    report.polygons,
                    report.samples,
                    report.patches,
                    report.threads,
                    bench_table(&report.rows)
                ))
            }
        })??,
        Command::Sweep {
            input,
            methods,
            size,
            densities,
            reference_density,
            texture_levels,
            frames,
            repeats,
            ppd,
            json,
            csv,
            plots,
            no_equal_error,
            threads,
            quiet,
            trace,
        } => in_pool(threads, || -> anyhow::Result<()> {
            use lab::jobs::sweep;
            // Outputs checked before the sweep's minutes of work (the scene's includes are
            // checked too, through the scene the plan loads).
            let mut inputs = vec![input.clone()];
            if let Ok(i) = lab::jobs::Input::load(&input) {
                inputs.extend(i.scene.inputs);
            }
            let outputs: Vec<(&str, &std::path::Path)> = json
                .as_deref()
                .map(|p| ("--json", p))
                .into_iter()
                .chain(csv.as_deref().map(|p| ("--csv", p)))
                .collect();
            base::output::check_outputs(&inputs, &outputs)?;
            let req = sweep::SweepRequest {
                input,
                methods,
                width: size.0,
                height: size.1,
                densities,
                reference_density,
                texture_levels,
                frames,
                repeats,
                ppd,
                equal_error: !no_equal_error,
            };
            let report =
                sweep::run_sweep(&context(&Terminal::new(!quiet, trace), limit, isa), &req)?;
            if let Some(path) = &json {
                base::output::write_atomic(path, self::json(&report)?.as_bytes())?;
                if !quiet {
                    note(&format!("wrote {}", path.display()));
                }
            }
            if let Some(path) = &csv {
                base::output::write_atomic(path, sweep::csv(&report).as_bytes())?;
                if !quiet {
                    note(&format!("wrote {}", path.display()));
                }
            }
            if let Some(dir) = &plots {
                for path in lab::plot::sweep_plots(&report, dir)? {
                    if !quiet {
                        note(&format!("wrote {}", path.display()));
                    }
                }
            }
            out(&sweep::table(&report))
        })??,
        Command::Results {
            doc,
            scenes,
            size,
            gallery_width,
            frames,
            repeats,
            threads,
            quiet,
            trace,
        } => in_pool(threads, || -> anyhow::Result<()> {
            use lab::experiment::results;
            let mut req = results::ResultsRequest::new(doc);
            if !scenes.is_empty() {
                req.scenes = scenes;
            }
            req.sweep_size = size;
            req.gallery_width = gallery_width;
            req.frames = frames;
            req.repeats = repeats;
            let report = results::run_results(
                &context(&Terminal::new(!quiet, trace), limit, isa),
                &req,
                &mut |p| {
                    if !quiet {
                        note(&format!("wrote {}", p.display()))
                    }
                },
            )?;
            out(&format!(
                "{} scenes in {:.0} s on {}; wrote {}\n",
                report.scenes.len(),
                report.seconds,
                report.machine.line(),
                req.doc.display()
            ))
        })??,
        Command::Generate {
            scene:
                Generate::Building {
                    rooms_x,
                    rooms_z,
                    floors,
                    cut,
                    lights,
                    furniture,
                    seed,
                    output,
                },
        } => {
            use lab::generate::{write_building, BuildingOptions};
            let options = BuildingOptions {
                rooms_x,
                rooms_z,
                floors,
                cut,
                lights,
                furniture,
                seed,
            };
            let written = write_building(&options, &output)?;
            let p = &written.paths;
            for path in [&p.scene, &p.obj, &p.mtl] {
                note(&format!("wrote {}", path.display()));
            }
            out(&format!("{}\n", written.building.summary))?;
        }
        Command::Compare {
            a,
            b,
            ppd,
            json,
            tolerance,
            floor,
            diff,
            max_distance,
        } => {
            use lab::image::{read_image, write_exr, write_png};
            let mut failed = Vec::new();
            if let Some(tol) = tolerance {
                let (ia, ib) = (read_image(&a)?, read_image(&b)?);
                let d = metric::pixels::diff(&ia, &ib, tol, floor)?;
                if let Some(path) = &diff {
                    base::output::check_outputs(&[a.clone(), b.clone()], &[("--diff", path)])?;
                    let exr = path
                        .extension()
                        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
                    if exr {
                        write_exr(path, d.image.view())?;
                    } else {
                        write_png(path, d.normalized_image().view(), 0.0)?;
                    }
                }
                if json {
                    out(&self::json(&d)?)?;
                } else {
                    out(&(d.summary() + "\n"))?;
                }
                if d.differing > 0 {
                    failed.push(format!("{} pixels differ", d.differing));
                }
            }
            if tolerance.is_none() || max_distance.is_some() {
                let c = lab::jobs::compare::compare_files(&a, &b, ppd)?;
                if json {
                    out(&self::json(&c)?)?;
                } else {
                    out(&c.table())?;
                }
                if let Some(m) = max_distance {
                    if c.perceptual_distance > m {
                        failed.push(format!(
                            "perceptual distance {:.6} above --max-distance {m}",
                            c.perceptual_distance
                        ));
                    }
                }
            }
            if !failed.is_empty() {
                return Err(Error::Runtime(format!(
                    "{} differs from {}: {}",
                    a.display(),
                    b.display(),
                    failed.join("; ")
                ))
                .into());
            }
        }
    }
    Ok(())
}

/// Runs `f` in a rayon pool of `threads` workers (all cores when `None`).
/// Most worker threads `--threads` accepts: far above any machine this runs on, far below what
/// would exhaust the process's thread and stack limits.
const MAX_THREADS: usize = 1024;

fn in_pool<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> anyhow::Result<T> {
    match threads {
        None => Ok(f()),
        Some(0) => Err(Error::invalid_option("--threads", "0", "needs at least one thread").into()),
        Some(n) if n > MAX_THREADS => Err(Error::invalid_option(
            "--threads",
            n.to_string(),
            format!("at most {MAX_THREADS} worker threads"),
        )
        .into()),
        Some(n) => {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| Error::Runtime(format!("cannot start {n} threads: {e}")))?;
            Ok(pool.install(f))
        }
    }
}

/// Exit code after SIGINT or SIGTERM (128 + SIGINT, the shell's convention for an interrupt).
const EXIT_INTERRUPTED: i32 = 130;

/// The environment variable that caps the lane build.
const LANES_ENV: &str = "PIXELFLOW_SIM_LANES";

fn main() -> ExitCode {
    let cli = Cli::parse();
    // SIGINT / SIGTERM: remove the temporaries of outputs being written (after any batch of
    // renames in progress finishes) and exit, so an interrupted run leaves no hidden files and
    // never half of a run's outputs replaced. If the handler cannot be installed the run goes
    // on with the default signal behaviour.
    let _ = ctrlc::set_handler(|| {
        base::output::remove_temporaries();
        note("interrupted");
        std::process::exit(EXIT_INTERRUPTED);
    });
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<StdoutClosed>() => ExitCode::SUCCESS,
        Err(e) => {
            note(&format!("error: {e:#}"));
            let code = e
                .downcast_ref::<base::Error>()
                .map_or(EXIT_FAILURE, |e| e.exit_code());
            ExitCode::from(u8::try_from(code).unwrap_or(1))
        }
    }
}
