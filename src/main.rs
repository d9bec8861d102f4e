//! The `pixelflow-sim` command line: parses arguments and calls the library.
//!
//! The binary is thin: clap validates the arguments, the library does the work, and every
//! library error is printed once to stderr and mapped to the exit code of
//! [`pixelflow_sim::Error::exit_code`]: 0 success, 2 bad input or usage (clap's own usage errors
//! also exit 2), 1 a failure while running. The library draws nothing: the progress bar and the
//! `--trace` lines are this file's observer ([`Terminal`]).

use clap::{Parser, Subcommand};
use pixelflow_sim::error::EXIT_FAILURE;
use pixelflow_sim::experiment;
use pixelflow_sim::frame::FrameOptions;
use pixelflow_sim::jobs::bench::{bench_table, run_bench, BenchRequest};
use pixelflow_sim::jobs::render::{run_render, RenderEvent, RenderRequest};
use pixelflow_sim::jobs::solve::solve_to_file;
use pixelflow_sim::jobs::stats::{run_stats, StatsRequest};
use pixelflow_sim::jobs::TextureOptions;
use pixelflow_sim::progress::Observer;
use pixelflow_sim::Error;
use std::io::IsTerminal;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Renders radiosity solutions with C1 bicubic Hermite reconstruction (Bastos, Goslin, Zhang).
#[derive(Parser, Debug)]
#[command(name = "pixelflow-sim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Memory the job may use: bytes, or a number with K, M, G or T (binary units, `1.5G`), or
    /// `none`. Default: three quarters of this machine's physical memory. A job whose estimate
    /// is over it is refused before it allocates (exit 2, the estimate in the message); `check`
    /// reports the estimate against it.
    #[arg(long, global = true, value_name = "SIZE", value_parser = parse_memory_limit)]
    memory_limit: Option<u64>,
}

fn parse_memory_limit(text: &str) -> Result<u64, String> {
    pixelflow_sim::jobs::budget::parse_size(text)
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
    /// Compute a scene's radiosity solution and save it.
    ///
    /// Progressive-refinement shooting with adaptive, unrestricted quadtrees (the `[radiosity]`
    /// settings of the scene). The solution file is versioned and checksummed and names the
    /// scene file, so `render <file>` can draw it without solving again.
    Solve {
        /// The scene file.
        scene: PathBuf,
        /// Where to write the solution (written atomically).
        #[arg(short, long)]
        output: PathBuf,
        /// Worker threads (default: all cores). The solution is identical for any count.
        #[arg(long)]
        threads: Option<usize>,
        /// No progress bar.
        #[arg(short, long)]
        quiet: bool,
        /// Print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
        #[arg(long)]
        trace: bool,
    },
    /// Render a scene (solving it first) or a solution file.
    ///
    /// Reconstructs every polygon's radiosity as C1 bicubic patches and renders them the
    /// PixelFlow way: a region-by-region rasterizer writes each pixel's patch and (u, v) into a
    /// G-buffer, R virtual renderers are merged by depth, and a deferred pass evaluates every
    /// pixel's radiosity from its patch. Writes a PNG (exposure and sRGB from the scene's
    /// `[display]`), optionally the linear radiosity as OpenEXR and the statistics as JSON.
    /// With `--walkthrough`, renders every frame of the scene's camera path.
    Render {
        /// A scene file (`.toml`) or a solution file written by `solve`.
        input: PathBuf,
        /// PNG to write (default: `out/<scene>-<method>.png`).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Also write the linear radiosity of every pixel as OpenEXR.
        #[arg(long)]
        exr: Option<PathBuf>,
        /// Rendering method (default: the scene's `[render] method`).
        #[arg(long)]
        method: Option<String>,
        /// Image width (default: the scene's).
        #[arg(long)]
        width: Option<u32>,
        /// Image height (default: the scene's).
        #[arg(long)]
        height: Option<u32>,
        /// Samples per pixel: 1, 4 or 16 (default: the scene's `[render] aa`).
        #[arg(long)]
        aa: Option<u32>,
        /// Worker threads (default: all cores). The image is identical for any count.
        #[arg(long)]
        threads: Option<usize>,
        /// Virtual PixelFlow renderers merged by image composition. The image is identical for
        /// any count.
        #[arg(long, default_value_t = 1)]
        renderers: u32,
        /// Side of the screen regions in pixels (a multiple of 8).
        #[arg(long, default_value_t = 128)]
        region: u32,
        /// Write the frame statistics as JSON to this file (for a walkthrough: the summary and
        /// every frame).
        #[arg(long)]
        stats: Option<PathBuf>,
        /// Render every frame of the scene's `[camera_path]` (files `<output stem>-NNNN.png`) and
        /// print a frame-rate summary (fps min / median / max, median stage times).
        #[arg(long)]
        walkthrough: bool,
        #[command(flatten)]
        texture: TextureArgs,
        /// The RRPs' derivative estimator: `hyman` (default: Hyman-filtered central
        /// differences), `monotone` (Fritsch-Butland) or `plain` (central differences).
        #[arg(long)]
        estimator: Option<String>,
        /// Print the statistics.
        #[arg(short, long)]
        verbose: bool,
        /// No progress bar, no "wrote" lines, no walkthrough summary.
        #[arg(short, long)]
        quiet: bool,
        /// Print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
        #[arg(long)]
        trace: bool,
    },
    /// The paper's Table 1 for a scene: triangles and vertices of the original, mesh and RAT
    /// models, model sizes, texture memory and count, RRP memory; with `--frames`, the frame
    /// times of mesh, texture-bilinear, texture-bicubic and direct measured in one run.
    ///
    /// Sizes are decimal MB; the byte accounting of each model is in `docs/performance.md`.
    Stats {
        /// A scene file or a solution file.
        input: PathBuf,
        /// Frames timed per method (after one warm-up); 0 = sizes only.
        #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
        frames: u32,
        /// Frame width for the timings.
        #[arg(long, default_value_t = 1024)]
        width: u32,
        /// Frame height for the timings.
        #[arg(long, default_value_t = 1024)]
        height: u32,
        /// Samples per pixel: 1, 4 or 16.
        #[arg(long, default_value_t = 1)]
        aa: u32,
        #[command(flatten)]
        texture: TextureArgs,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Print JSON instead of the table.
        #[arg(long)]
        json: bool,
        /// When solving a scene, print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
        #[arg(long)]
        trace: bool,
    },
    /// Rerun the paper's experiments: `fig5`, `fig6`, `table1`, or `all` (which also writes
    /// `docs/experiments.md` when given `--doc`).
    ///
    /// fig5: the two-spots plane in texture space, the oracle reference, the paper's depth-9
    /// reference, a depth-2 (5 x 5) quadtree, its bilinear and bicubic (RRP) resampling to 256 x 256
    /// and the direct method; fig6: the RRP resampled to an 8 x 8 texture (texels at centres, then
    /// at corners) drawn with bilinear and Mitchell-Netravali filters, and direct; each with the perceptual distance to the reference
    /// beside the paper's numbers. table1: `stats` of the shipped scenes beside the paper's Table 1.
    Experiment {
        /// `fig5`, `fig6`, `table1` or `all`.
        which: String,
        /// Directory for the images (default: `out/experiments`).
        #[arg(long, default_value = "out/experiments")]
        out_dir: PathBuf,
        /// With `all`: write the Markdown report to this file (`docs/experiments.md`); image
        /// links are relative to its directory.
        #[arg(long)]
        doc: Option<PathBuf>,
        /// The texture-space scene of fig5 and fig6.
        #[arg(long, default_value = "scenes/two-spots.toml")]
        scene: PathBuf,
        /// Image side of fig5 and fig6.
        #[arg(long, default_value_t = 256)]
        size: u32,
        /// Pixels per degree of the perceptual metric.
        #[arg(long, default_value_t = pixelflow_sim::metric::DEFAULT_PPD)]
        ppd: f64,
        /// fig5, fig6: the RRPs' derivative estimator, `hyman` (default), `monotone` or
        /// `plain` (central differences).
        #[arg(long, default_value = "hyman")]
        estimator: String,
        /// table1: the scenes (default: the three shipped scenes).
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<PathBuf>,
        /// table1: frames timed per method at 1024 x 1024 (0 = sizes only).
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
        frames: u32,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Print JSON instead of tables.
        #[arg(long)]
        json: bool,
    },
    /// Measure frame time: render the scene camera's view repeatedly at several sizes and print
    /// the medians of every stage and the deferred pass's throughput.
    ///
    /// Solving and reconstruction happen once, before timing. Give a solution file to skip the
    /// solve. Timings are wall-clock on this machine; compare methods and sizes measured in the
    /// same run.
    Bench {
        /// A scene file or a solution file.
        input: PathBuf,
        /// Methods to measure, comma-separated (`direct`, `texture-bilinear`, ...), each at
        /// every size, interleaved per size so they see the same machine state.
        #[arg(long, value_delimiter = ',', default_values_t = [String::from("direct")])]
        methods: Vec<String>,
        #[command(flatten)]
        texture: TextureArgs,
        /// Square image sizes to measure, comma-separated.
        #[arg(long, value_delimiter = ',', default_values_t = [512u32, 1024, 2048])]
        sizes: Vec<u32>,
        /// Frames timed per size (after one warm-up frame).
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
        frames: u32,
        /// Samples per pixel: 1, 4 or 16.
        #[arg(long, default_value_t = 1)]
        aa: u32,
        /// Virtual PixelFlow renderers.
        #[arg(long, default_value_t = 1)]
        renderers: u32,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Print JSON instead of the table.
        #[arg(long)]
        json: bool,
        /// When solving a scene, print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
        #[arg(long)]
        trace: bool,
    },
    /// Speed against error: solve the scene at several sampling densities and measure, for every
    /// method (and texture size), the warm frame time, the bytes it holds and its error against
    /// the same solution's exact image and against a converged finer solution's.
    ///
    /// Prints one row per point, flagging the Pareto fronts of total error against frame time and
    /// against memory; `--json` and `--csv` write every measure (perceptual distance, RMSE,
    /// maximum error, Mach-band measure against both references). Then, at the scene's own density,
    /// the texture memory each texture method needs to reach the direct method's reconstruction
    /// error (texture sides scaled by 1/8 to 16), beside the RRP bytes.
    Sweep {
        /// A scene file or a solution file (its scene is solved again at every density).
        input: PathBuf,
        /// Methods, comma-separated (default: direct and every texture method, and mesh).
        #[arg(long, value_delimiter = ',', default_values_t = pixelflow_sim::jobs::sweep::DEFAULT_METHODS.map(String::from))]
        methods: Vec<String>,
        /// Image size, `WxH`.
        #[arg(long, default_value = "256x256", value_parser = parse_size)]
        size: (u32, u32),
        /// Density levels as factors of the scene's solver tolerance, coarse to fine.
        #[arg(long, value_delimiter = ',', default_values_t = pixelflow_sim::jobs::sweep::DEFAULT_DENSITIES)]
        densities: Vec<f64>,
        /// Tolerance factor of the converged reference solution (solved one level deeper).
        #[arg(long, default_value_t = 0.25)]
        reference_density: f64,
        /// Texture sizes per density: the quadtree-depth sizes halved 0 .. N-1 times.
        #[arg(long, default_value_t = 4)]
        texture_levels: u32,
        /// Frames timed per point and repeat (after a warm-up).
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
        frames: u32,
        /// Timing repeats (the spread is over repeats).
        #[arg(long, default_value_t = 3)]
        repeats: u32,
        /// Pixels per degree of the perceptual metric.
        #[arg(long, default_value_t = pixelflow_sim::metric::DEFAULT_PPD)]
        ppd: f64,
        /// Write every point as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Write every point as CSV to this file.
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Write the plots (error against frame time and against memory, PNG and SVG) into this
        /// directory.
        #[arg(long)]
        plots: Option<PathBuf>,
        /// Skip the equal-error memory search.
        #[arg(long)]
        no_equal_error: bool,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// No progress bar.
        #[arg(short, long)]
        quiet: bool,
        /// Print the solver's trace lines.
        #[arg(long)]
        trace: bool,
    },
    /// The results page: every shipped scene's sweep (with the equal-error memory search),
    /// walkthrough frame rates of every method, and a gallery of small images by every method,
    /// written as Markdown (default `docs/results.md`) with the data, plots and images in
    /// `results/` beside it.
    Results {
        /// The Markdown page to write.
        #[arg(long, default_value = "docs/results.md")]
        doc: PathBuf,
        /// Scene files, comma-separated (default: two-spots, cornell-box, gallery).
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<PathBuf>,
        /// Side of the sweeps' square images.
        #[arg(long, default_value_t = 256)]
        size: u32,
        /// Width of the gallery's images.
        #[arg(long, default_value_t = 192)]
        gallery_width: u32,
        /// Frames timed per sweep point and repeat.
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
        frames: u32,
        /// Sweep timing repeats.
        #[arg(long, default_value_t = 3)]
        repeats: u32,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// No progress bar.
        #[arg(short, long)]
        quiet: bool,
        /// Print the solver's trace lines.
        #[arg(long)]
        trace: bool,
    },
    /// Compare an image with a reference: the perceptual distance and error measures.
    ///
    /// Reads two images (OpenEXR, Radiance HDR, PFM, or PNG decoded from sRGB to linear) of the
    /// same size and prints the perceptual distance of docs/metrics.md (Rushmeier et al. model 1
    /// with the Mannos-Sakrison CSF), RMSE, PSNR, maximum absolute error, relative luminance
    /// error and the Mach-band measure, all on luminance. `b` is the reference.
    ///
    /// As a regression check (a CI comparing renders with committed golden images):
    /// `--tolerance default` compares pixel by pixel and lists the pixels that moved, `--diff`
    /// writes a difference image, `--max-distance` bounds the perceptual distance; exit 1 when a
    /// check fails, 0 when all pass.
    Compare {
        /// The image under test.
        a: PathBuf,
        /// The reference image.
        b: PathBuf,
        /// Pixels per degree of visual angle (viewing distance) for the contrast sensitivity.
        #[arg(long, default_value_t = pixelflow_sim::metric::DEFAULT_PPD)]
        ppd: f64,
        /// Print JSON instead of the table.
        #[arg(long)]
        json: bool,
        /// Regression check: compare pixel by pixel; a pixel differs when a channel moves by more
        /// than this times max(|reference|, --floor) (`default` = 2^-19, 16 f32 rounding steps).
        /// Lists the first differing pixels; exit 1 if any differ.
        #[arg(long, value_name = "REL|default", value_parser = parse_tolerance)]
        tolerance: Option<f32>,
        /// With --tolerance: the reference level under which the tolerance is absolute.
        #[arg(long, default_value_t = pixelflow_sim::metric::pixels::DEFAULT_FLOOR)]
        floor: f32,
        /// With --tolerance: write the difference image here (PNG scaled so the largest
        /// difference is white, or EXR with the raw |a - b|).
        #[arg(long, value_name = "PATH", requires = "tolerance")]
        diff: Option<PathBuf>,
        /// Fail (exit 1) when the perceptual distance is above this.
        #[arg(long, value_name = "D")]
        max_distance: Option<f64>,
    },
}

fn parse_tolerance(text: &str) -> Result<f32, String> {
    if text == "default" {
        return Ok(pixelflow_sim::metric::pixels::DEFAULT_TOLERANCE);
    }
    match text.parse::<f32>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err("must be a finite number >= 0, or `default`".into()),
    }
}

/// Options of the texture methods (ignored by the others).
#[derive(clap::Args, Debug, Clone)]
struct TextureArgs {
    /// Texture methods: one texture side for every polygon, a power of two (default: the
    /// scene's `[render] texture_size`; 0 there = per polygon from its quadtree depth).
    #[arg(long)]
    texture_size: Option<u32>,
    /// Texture methods: a texture memory budget (12 bits per channel, mip chains included),
    /// bytes with an optional K, M or G suffix; sides are halved uniformly until it fits.
    #[arg(long, value_parser = parse_bytes)]
    texture_budget: Option<u64>,
    /// `texture-bicubic`: the Mitchell–Netravali (B, C), default 0.333,0.333 (Catmull-Rom:
    /// 0,0.5).
    #[arg(long, value_name = "B,C", value_parser = parse_bicubic)]
    bicubic: Option<(f32, f32)>,
    /// Texture methods: where the texels sit, `centre` (texel i at u = (i + 0.5) / N) or
    /// `corner` (u = i / (N - 1): samples on the polygon's edges and corners) (default: the
    /// scene's `[render] texel_placement`, else centre).
    #[arg(long, value_name = "centre|corner")]
    texel_placement: Option<String>,
}

impl TextureArgs {
    fn options(&self) -> TextureOptions {
        TextureOptions {
            size: self.texture_size,
            budget: self.texture_budget,
            bicubic: self.bicubic,
            placement: self.texel_placement.clone(),
        }
    }
}

fn parse_bytes(s: &str) -> Result<u64, String> {
    pixelflow_sim::method::parse_bytes("--texture-budget", s).map_err(reason)
}

fn parse_bicubic(s: &str) -> Result<(f32, f32), String> {
    pixelflow_sim::method::parse_bicubic(s).map_err(reason)
}

/// The reason of an option error, for clap (which names the option and the value itself).
fn reason(e: Error) -> String {
    match e {
        Error::InvalidOption { reason, .. } => reason,
        e => e.to_string(),
    }
}

/// Parses `WxH` (both at least 1; the upper limit is checked by the job).
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| "expected WxH, for example 256x256".to_string())?;
    match (w.trim().parse::<u32>(), h.trim().parse::<u32>()) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => Ok((w, h)),
        _ => Err("expected WxH with two integers of at least 1".to_string()),
    }
}

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
    use pixelflow_sim::jobs::budget;
    let limit = cli.memory_limit.unwrap_or_else(budget::default_limit);
    budget::set_limit(limit);
    match cli.command {
        Command::Check { scene } => {
            let s = pixelflow_sim::scene::load_scene(&scene)?;
            for w in &s.warnings {
                note(&format!("warning: {w}"));
            }
            let summary = pixelflow_sim::report::summarize(&s);
            let budget = pixelflow_sim::report::budget_text(&s, limit)?;
            out(&format!("{summary}{budget}"))?;
            // Over the limit: the same refusal a solve or render of this scene would give.
            budget::check_solve(&s, limit)?;
            budget::check_frame(
                s.width,
                s.height,
                s.render.aa_samples,
                FrameOptions::new(s.width, s.height).renderers,
                (true, false),
                limit,
            )?;
        }
        Command::Solve {
            scene,
            output,
            threads,
            quiet,
            trace,
        } => {
            let observer = Terminal::new(!quiet, trace);
            let sol = in_pool(threads, || solve_to_file(&scene, &output, &observer))??;
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
                run_render(&req, &observer, &mut |event| match event {
                    RenderEvent::Warning(w) => observer.note(&format!("warning: {w}")),
                    RenderEvent::Wrote(path) if !quiet => {
                        // Above the walkthrough's bar, not into it.
                        observer.note(&format!("wrote {}", path.display()))
                    }
                    RenderEvent::Frame(report) if verbose && !stdout_closed => {
                        // A closed stdout stops the printing, not the render.
                        stdout_closed = out(&(report.to_json() + "\n")).is_err();
                    }
                    RenderEvent::Walkthrough(summary) if !quiet => observer.note(&summary.line()),
                    _ => {}
                })
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
                    ..FrameOptions::new(width, height)
                },
                texture: texture.options(),
            };
            let stats = run_stats(&req, &Terminal::new(false, trace))?;
            if json {
                out(&self::json(&stats)?)
            } else {
                out(&pixelflow_sim::report::model_stats_text(&stats))
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
            let results =
                experiment::run(&req, &mut |path| note(&format!("wrote {}", path.display())))?;
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
            };
            let report = run_bench(&req, &Terminal::new(false, trace))?;
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
            use pixelflow_sim::jobs::sweep;
            // Outputs checked before the sweep's minutes of work (the scene's includes are
            // checked too, through the scene the plan loads).
            let mut inputs = vec![input.clone()];
            if let Ok(i) = pixelflow_sim::jobs::Input::load(&input) {
                inputs.extend(i.scene.inputs);
            }
            let outputs: Vec<(&str, &std::path::Path)> = json
                .as_deref()
                .map(|p| ("--json", p))
                .into_iter()
                .chain(csv.as_deref().map(|p| ("--csv", p)))
                .collect();
            pixelflow_sim::output::check_outputs(&inputs, &outputs)?;
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
            let report = sweep::run_sweep(&req, &Terminal::new(!quiet, trace))?;
            if let Some(path) = &json {
                pixelflow_sim::output::write_atomic(path, self::json(&report)?.as_bytes())?;
                if !quiet {
                    note(&format!("wrote {}", path.display()));
                }
            }
            if let Some(path) = &csv {
                pixelflow_sim::output::write_atomic(path, sweep::csv(&report).as_bytes())?;
                if !quiet {
                    note(&format!("wrote {}", path.display()));
                }
            }
            if let Some(dir) = &plots {
                for path in pixelflow_sim::plot::sweep_plots(&report, dir)? {
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
            use pixelflow_sim::experiment::results;
            let mut req = results::ResultsRequest::new(doc);
            if !scenes.is_empty() {
                req.scenes = scenes;
            }
            req.sweep_size = size;
            req.gallery_width = gallery_width;
            req.frames = frames;
            req.repeats = repeats;
            let report = results::run_results(&req, &Terminal::new(!quiet, trace), &mut |p| {
                if !quiet {
                    note(&format!("wrote {}", p.display()))
                }
            })?;
            out(&format!(
                "{} scenes in {:.0} s on {}; wrote {}\n",
                report.scenes.len(),
                report.seconds,
                report.machine.line(),
                req.doc.display()
            ))
        })??,
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
            use pixelflow_sim::image::{read_image, write_exr, write_png};
            let mut failed = Vec::new();
            if let Some(tol) = tolerance {
                let (ia, ib) = (read_image(&a)?, read_image(&b)?);
                let d = pixelflow_sim::metric::pixels::diff(&ia, &ib, tol, floor)?;
                if let Some(path) = &diff {
                    pixelflow_sim::output::check_outputs(
                        &[a.clone(), b.clone()],
                        &[("--diff", path)],
                    )?;
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
                let c = pixelflow_sim::metric::compare_files(&a, &b, ppd)?;
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

/// The command line's [`Observer`]: a progress bar on stderr that appears once a stage has run
/// for a second, only if asked for and stderr is a terminal; with `--trace`, the library's trace
/// lines on stderr (printed above the bar when one is shown). Each stage gets its own bar (a
/// render's `solve`, then its `walkthrough`).
struct Terminal {
    bar: bool,
    trace: bool,
    /// How long a stage runs before its bar appears.
    delay: Duration,
    state: Mutex<BarState>,
}

/// The running stage: its name, its start and its bar, once shown.
#[derive(Default)]
struct BarState {
    stage: String,
    started: Option<Instant>,
    bar: Option<indicatif::ProgressBar>,
}

impl BarState {
    /// Forgets the stage and clears its bar.
    fn end(&mut self) {
        self.stage.clear();
        self.started = None;
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

impl Terminal {
    fn new(bar: bool, trace: bool) -> Self {
        Terminal {
            bar: bar && std::io::stderr().is_terminal(),
            trace,
            delay: Duration::from_secs(1),
            state: Mutex::default(),
        }
    }
}

impl Terminal {
    /// A line on standard error, printed above the bar when one is shown.
    fn note(&self, line: &str) {
        let st = self.state.lock().ok();
        match st.as_ref().and_then(|st| st.bar.as_ref()) {
            Some(bar) => bar.suspend(|| note(line)),
            None => note(line),
        }
    }
}

impl Observer for Terminal {
    fn progress(&self, stage: &str, fraction: f64) {
        if !self.bar {
            return;
        }
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        if st.started.is_some() && st.stage != stage {
            // A new stage without the last one's `finished`: its own bar all the same.
            st.end();
        }
        if st.started.is_none() {
            st.stage = stage.to_string();
        }
        let elapsed = st.started.get_or_insert_with(Instant::now).elapsed();
        if elapsed < self.delay {
            return;
        }
        let bar = st.bar.get_or_insert_with(|| {
            let b = indicatif::ProgressBar::new(1000)
                .with_prefix(stage.to_string())
                .with_elapsed(elapsed);
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{prefix} [{elapsed_precise}] {wide_bar} {percent}%",
            ) {
                b.set_style(style);
            }
            b
        });
        bar.set_position((fraction.clamp(0.0, 1.0) * 1000.0) as u64);
    }

    fn finished(&self, stage: &str) {
        if let Ok(mut st) = self.state.lock() {
            if st.stage == stage {
                st.end();
            }
        }
    }

    fn tracing(&self) -> bool {
        self.trace
    }

    fn trace(&self, line: &str) {
        self.note(line);
    }
}

/// Runs `f` in a rayon pool of `threads` workers (all cores when `None`).
/// Most worker threads `--threads` accepts: far above any machine this runs on, far below what
/// would exhaust the process's thread and stack limits.
const MAX_THREADS: usize = 1024;

/// Most frames a timing option (`--frames` of stats, bench, sweep, results, experiment)
/// accepts: hours of timing at the largest sizes, not days.
const MAX_TIMED_FRAMES: i64 = 100_000;

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

fn main() -> ExitCode {
    let cli = Cli::parse();
    // SIGINT / SIGTERM: remove the temporaries of outputs being written (after any batch of
    // renames in progress finishes) and exit, so an interrupted run leaves no hidden files and
    // never half of a run's outputs replaced. If the handler cannot be installed the run goes
    // on with the default signal behaviour.
    let _ = ctrlc::set_handler(|| {
        pixelflow_sim::output::remove_temporaries();
        note("interrupted");
        std::process::exit(EXIT_INTERRUPTED);
    });
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<StdoutClosed>() => ExitCode::SUCCESS,
        Err(e) => {
            note(&format!("error: {e:#}"));
            let code = e
                .downcast_ref::<pixelflow_sim::Error>()
                .map_or(EXIT_FAILURE, |e| e.exit_code());
            ExitCode::from(u8::try_from(code).unwrap_or(1))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A terminal that shows its bar at once.
    fn terminal() -> Terminal {
        Terminal {
            bar: true,
            trace: false,
            delay: Duration::ZERO,
            state: Mutex::default(),
        }
    }

    fn shown(t: &Terminal) -> Option<(String, u64)> {
        let st = t.state.lock().unwrap();
        st.bar.as_ref().map(|b| (b.prefix(), b.position()))
    }

    #[test]
    fn a_stage_after_a_finished_one_gets_a_new_bar() {
        let t = terminal();
        t.progress("solve", 0.0);
        t.progress("solve", 1.0);
        assert_eq!(shown(&t), Some(("solve".into(), 1000)));
        t.finished("solve");
        assert_eq!(shown(&t), None);
        t.progress("walkthrough", 0.0);
        assert_eq!(shown(&t), Some(("walkthrough".into(), 0)));
        t.progress("walkthrough", 0.5);
        assert_eq!(shown(&t), Some(("walkthrough".into(), 500)));
        t.finished("walkthrough");
        assert_eq!(shown(&t), None);
    }

    #[test]
    fn a_stage_without_finished_is_replaced_by_the_next() {
        let t = terminal();
        t.progress("solve", 0.7);
        t.progress("walkthrough", 0.25);
        assert_eq!(shown(&t), Some(("walkthrough".into(), 250)));
        // A late `finished` of the replaced stage leaves the running one alone.
        t.finished("solve");
        assert_eq!(shown(&t), Some(("walkthrough".into(), 250)));
    }
}
