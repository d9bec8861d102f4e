//! The command line's arguments: every subcommand and option, with its help text, parsed and
//! range-checked by clap before the library sees it (an out-of-range value exits 2 with clap's
//! usage message). `commands.rs` turns them into the library's requests.
//!
//! Each subcommand's options are a struct of their own (`Command::Render(RenderArgs)`); the
//! doc comment of the `Command` variant is the subcommand's help text.

use std::path::PathBuf;

use app::context::TextureOptions;
use base::Error;
use clap::{Args, Parser, Subcommand};
use fixtures::generate;

/// Most frames a timing option (`--frames` of stats, bench, sweep, results, experiment)
/// accepts: hours of timing at the largest sizes, not days.
pub(crate) const MAX_TIMED_FRAMES: i64 = 100_000;

/// Most timing processes `--processes` accepts (each one loads the solution again).
pub(crate) const MAX_TIMING_PROCESSES: i64 = 1_000;

/// Renders radiosity solutions with C1 bicubic Hermite reconstruction (Bastos, Goslin, Zhang).
#[derive(Parser, Debug)]
#[command(
    name = "pixelflow-sim",
    version,
    about,
    after_help = "Environment: PIXELFLOW_SIM_LANES=portable|avx2|avx512|auto caps the SIMD build of the hot loops (default auto: the widest the CPU has); the images are the same."
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub command: Command,
    /// Memory the job may use: bytes, or a number with K, M, G or T (binary units, `1.5G`), or
    /// `none`. Default: the smallest of three quarters of this machine's physical memory,
    /// three quarters of its memory cgroup's limit and half of `ulimit -v`. A job whose estimate
    /// is over it is refused before it allocates (exit 2, the estimate in the message); `check`
    /// reports the estimate against it.
    #[arg(long, global = true, value_name = "SIZE", value_parser = parse_memory_limit)]
    pub memory_limit: Option<u64>,
}

fn parse_memory_limit(text: &str) -> Result<u64, String> {
    app::budget::parse_size(text)
}

#[derive(Subcommand, Debug)]
pub(crate) enum Command {
    /// Load and validate a scene file, print its warnings and a summary.
    ///
    /// Reads the TOML scene (and its OBJ/MTL includes), checks every value, and prints a table
    /// of polygons, materials, emitters, spot lights, bounds and the estimated memory of the
    /// radiosity solve. Warnings (such as non-planar quads that were split) go to stderr.
    /// Exit code 0 if the scene is valid, 2 if it is not (the message names file, line and key).
    Check(CheckArgs),
    /// Compute a scene's radiosity solution and save it.
    ///
    /// Progressive-refinement shooting with adaptive, unrestricted quadtrees (the `[radiosity]`
    /// settings of the scene). The solution file is versioned and checksummed and names the
    /// scene file, so `render <file>` can draw it without solving again.
    Solve(SolveArgs),
    /// Render a scene (solving it first) or a solution file.
    ///
    /// Reconstructs every polygon's radiosity as C1 bicubic patches and renders them the
    /// PixelFlow way: a region-by-region rasterizer writes each pixel's patch and (u, v) into a
    /// G-buffer, R virtual renderers are merged by depth, and a deferred pass evaluates every
    /// pixel's radiosity from its patch. Writes a PNG (exposure and sRGB from the scene's
    /// `[display]`), optionally the linear radiosity as OpenEXR and the statistics as JSON.
    /// With `--walkthrough`, renders every frame of the scene's camera path.
    Render(RenderArgs),
    /// The paper's Table 1 for a scene: triangles and vertices of the original, mesh and RAT
    /// models, model sizes, texture memory and count, RRP memory; with `--frames`, the frame
    /// times of mesh, texture-bilinear, texture-bicubic and direct measured in one run.
    ///
    /// Sizes are decimal MB; the byte accounting of each model is in `docs/performance.md`.
    Stats(StatsArgs),
    /// Rerun the paper's experiments: `fig5`, `fig6`, `table1`, or `all` (which also writes
    /// `docs/experiments.md` when given `--doc`).
    ///
    /// fig5: the two-spots plane in texture space, the oracle reference, the paper's depth-9
    /// reference, a depth-2 (5 x 5) quadtree, its bilinear and bicubic (RRP) resampling to 256 x 256
    /// and the direct method; fig6: the RRP resampled to an 8 x 8 texture (texels at centres, then
    /// at corners, then at centres clamped to the edge as the paper's hardware addressed
    /// textures) drawn with bilinear and Mitchell-Netravali filters, and direct; each with the
    /// perceptual distance to the reference beside the paper's numbers. table1: `stats` of the shipped scenes beside the paper's Table 1.
    Experiment(ExperimentArgs),
    /// Measure frame time: render the scene camera's view repeatedly at several sizes and print
    /// the medians of every stage and the deferred pass's throughput.
    ///
    /// Solving and reconstruction happen once, before timing. Give a solution file to skip the
    /// solve. Timings are wall-clock on this machine; compare methods and sizes measured in the
    /// same run.
    Bench(BenchArgs),
    /// Speed against error: solve the scene at several sampling densities and measure, for every
    /// method (and texture size), the warm frame time, the bytes it holds and its error against
    /// the same solution's exact image and against a converged finer solution's.
    ///
    /// Prints one row per point, flagging the Pareto fronts of total error against frame time and
    /// against memory; `--json` and `--csv` write every measure (perceptual distance, RMSE,
    /// maximum error, Mach-band measure against both references). Then, at the scene's own density,
    /// the texture memory each texture method needs to reach the direct method's reconstruction
    /// error (texture sides scaled by 1/8 to 16), beside the RRP bytes.
    Sweep(SweepArgs),
    /// The results page: every shipped scene's sweep (with the equal-error memory search),
    /// walkthrough frame rates of every method, and a gallery of small images by every method,
    /// written as Markdown (default `docs/results.md`) with the data, plots and images in
    /// `results/` beside it.
    Results(ResultsArgs),
    /// Generate a test scene (`generate building`): OBJ, MTL and a scene file that includes
    /// them, of any size, for measuring the solver and the renderers.
    #[command(subcommand)]
    Generate(Generate),
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
    Compare(CompareArgs),
    /// Path-trace a scene: the physical reference the radiosity solution is measured against.
    ///
    /// An independent Monte Carlo path tracer of the scene (one-sided Lambertian polygons, area
    /// emitters and spot lights; nothing of the solver). `-o out.exr` writes the mean radiosity
    /// B of every pixel (what `render --exr` writes) and `out.stderr.exr` its standard error per
    /// channel; `--json` writes every polygon's mean B over its area, its direct and indirect
    /// parts and their standard errors, sampled over the polygon itself, and prints them as a
    /// table. The same seed gives the same bytes for any `--threads` (docs/truth.md).
    Truth(TruthArgs),
    /// Export a solution to glTF 2.0: the original polygons with a lightmap atlas, or the
    /// adaptive mesh with vertex colours (`--mesh`).
    ///
    /// The lightmap: every polygon's radiosity texture (the texels `render --method
    /// texture-bilinear` draws, sized alike) packed into power-of-two pages with gutters that
    /// continue each polygon's RRP past its edges, addressed by texture coordinate set 1; the
    /// pages as sRGB PNG after the scene's exposure (used by the unlit materials) and as linear
    /// OpenEXR beside the file. The container follows the name: `.glb` (one file) or `.gltf`
    /// (its buffer and PNGs beside it). Prints the files, the atlas's packing and texel density.
    Export(ExportArgs),
    /// Walk through a scene or solution interactively, in a window drawn by the PixelFlow
    /// engine (the pixels `render` writes for the same camera).
    ///
    /// Keys: W/S forward and back, A/D sideways, Q/E down and up, arrows turn (fly) or circle
    /// the look-at point (orbit); Tab switches fly and orbit; M the next method, 1-5 direct,
    /// texture-nearest, texture-bilinear, texture-bicubic, mesh; R / Shift+R more or fewer
    /// renderers, G / Shift+G larger or smaller regions; P plays the scene's camera path; Home
    /// the scene's camera; Esc quits. The top line shows the frame rate and the frame's stage
    /// times. With `--script`, no window: the recorded actions are replayed and the last frame
    /// written to `--screenshot`.
    View(ViewArgs),
    /// One of the separate timing processes of `sweep` and `results`: times a sweep's points as
    /// its parent asks (a JSON request) and prints the times as JSON. Not for direct use.
    #[command(hide = true)]
    TimeWorker(TimeWorkerArgs),
}

#[derive(Args, Debug)]
pub(crate) struct ExportArgs {
    /// A scene file or a solution file (a scene is solved first).
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// The glTF to write: `.glb` or `.gltf`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The adaptive mesh with Gouraud vertex colours (COLOR_0) instead of the lightmap.
    #[arg(long)]
    pub mesh: bool,
    /// Largest atlas page side, a power of two from 64 to 16384; charts that do not fit one
    /// page go to more.
    #[arg(long, default_value_t = app::commands::export::DEFAULT_PAGE)]
    pub page_size: u32,
    /// Exposure in stops of the PNG pages and vertex colours (default: the scene's
    /// `[display] exposure`).
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f64>,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Worker threads (default: all cores). The files are identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct ViewArgs {
    /// A scene file or a solution file (a scene is solved first).
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// Window width.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Window height.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Virtual renderers at the start.
    #[arg(long, default_value_t = 1)]
    pub renderers: u32,
    /// Region side at the start, pixels.
    #[arg(long, default_value_t = 128)]
    pub region: u32,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// No window: replay this recorded session (`press ACTION`, `hold ACTION[,ACTION] SECONDS`,
    /// `wait SECONDS` per line; docs/viewer.md) at 60 steps a second, then draw one frame.
    #[arg(long, requires = "screenshot")]
    pub script: Option<PathBuf>,
    /// With `--script`: the PNG of the last frame (as `render` would write it).
    #[arg(long, requires = "script")]
    pub screenshot: Option<PathBuf>,
    /// With `--script`: frames drawn after the session, each as the window would show it
    /// (frame, sRGB, status line), timed; prints their median.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=10000))]
    pub frames: u32,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}

#[derive(Args, Debug)]
pub(crate) struct TimeWorkerArgs {
    /// The parent's request (JSON).
    pub request: String,
}

/// The scene's command-line options: values set over the scene file's, and strictness.
#[derive(Args, Debug, Clone, Default)]
pub(crate) struct SceneOptions {
    /// Set a scene value: a dotted key of the scene file and a TOML value
    /// (`-D camera.eye=[0,1,3]`, `-D image.width=800`, `-D radiosity.max_depth=8`,
    /// `-D display.exposure=1`); repeatable, later ones win. Checked like the file's own values.
    #[arg(short = 'D', value_name = "KEY=VALUE", value_parser = parse_define)]
    pub define: Vec<(String, String)>,
    /// The camera: eye and look-at point, six numbers `ex,ey,ez,lx,ly,lz` (short for
    /// `-D camera.eye=[ex,ey,ez] -D camera.look_at=[lx,ly,lz]`).
    #[arg(long, value_name = "EX,EY,EZ,LX,LY,LZ", value_parser = parse_camera, allow_hyphen_values = true)]
    pub camera: Option<[f64; 6]>,
    /// Refuse what is otherwise repaired with a warning (an OBJ material's `Kd` of 1 or more,
    /// clamped to 0.95 otherwise).
    #[arg(long)]
    pub strict: bool,
}

impl SceneOptions {
    /// The library's load options (the input cap is the run's: `Settings::load_options`).
    pub(crate) fn load_options(&self) -> scene::LoadOptions {
        let mut overrides = self.define.clone();
        if let Some(c) = self.camera {
            overrides.push((
                "camera.eye".into(),
                format!("[{}, {}, {}]", c[0], c[1], c[2]),
            ));
            overrides.push((
                "camera.look_at".into(),
                format!("[{}, {}, {}]", c[3], c[4], c[5]),
            ));
        }
        scene::LoadOptions {
            overrides,
            strict: self.strict,
            ..scene::LoadOptions::default()
        }
    }
}

fn parse_define(s: &str) -> Result<(String, String), String> {
    scene::overrides::parse(s).map_err(reason)
}

fn parse_camera(s: &str) -> Result<[f64; 6], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| "expected six numbers ex,ey,ez,lx,ly,lz".to_string())?;
    <[f64; 6]>::try_from(v.as_slice())
        .ok()
        .filter(|a| a.iter().all(|x| x.is_finite()))
        .ok_or_else(|| "expected six finite numbers ex,ey,ez,lx,ly,lz".to_string())
}

#[derive(Args, Debug)]
pub(crate) struct CheckArgs {
    /// The scene file (`scenes/cornell-box.toml`), a model (`room.obj`: a camera, material
    /// and light are chosen for it), or a solution file (`.pfsol`): then also where its solve's
    /// guards stopped refinement with the error test still failing.
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
}

#[derive(Args, Debug)]
pub(crate) struct SolveArgs {
    /// The scene file, or a model (`room.obj`).
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// Where to write the solution (written atomically).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Worker threads (default: all cores). The solution is identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct RenderArgs {
    /// A scene file (`.toml`), a model (`room.obj`, with its MTL: a camera framing it, a grey
    /// default material and, if nothing emits, a default light are chosen and said), or a
    /// solution file written by `solve`.
    pub input: PathBuf,
    /// The image to write; the format follows the name: `.png` (8-bit sRGB after the exposure),
    /// `.exr`, `.hdr` or `.pfm` (linear radiosity) (default: `out/<scene>-<method>.png`,
    /// followed by every option given that changes the method's pixels, e.g. `-640x480-aa4-t64`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    #[command(flatten)]
    pub options: SceneOptions,
    /// Exposure of the PNG in stops: radiosity times 2^N before sRGB (default: the scene's
    /// `[display] exposure`).
    #[arg(
        long,
        value_name = "N",
        allow_hyphen_values = true,
        conflicts_with = "auto_exposure"
    )]
    pub exposure: Option<f64>,
    /// Choose the exposure that maps the image's log-average luminance to middle grey (0.18);
    /// a walkthrough uses its first frame's.
    #[arg(long)]
    pub auto_exposure: bool,
    /// Also write the linear radiosity of every pixel as OpenEXR, named `.exr`.
    #[arg(long)]
    pub exr: Option<PathBuf>,
    /// Rendering method: `direct` (the RRPs per pixel, the PixelFlow path), `texture-nearest`,
    /// `texture-bilinear`, `texture-bicubic` (radiosity textures), `mesh` (the Gouraud mesh) or
    /// `reference` (the solution exact per pixel) (default: the scene's `[render] method`).
    #[arg(long)]
    pub method: Option<String>,
    /// Image width (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel: 1, 4 or 16 (default: the scene's `[render] aa`).
    #[arg(long)]
    pub aa: Option<u32>,
    /// Worker threads (default: all cores). The image is identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Virtual PixelFlow renderers merged by image composition. The image is identical for
    /// any count.
    #[arg(long, default_value_t = 1)]
    pub renderers: u32,
    /// Side of the screen regions in pixels (a multiple of 8).
    #[arg(long, default_value_t = 128)]
    pub region: u32,
    /// Write the frame statistics as JSON to this file (for a walkthrough: the summary and
    /// every frame).
    #[arg(long)]
    pub stats: Option<PathBuf>,
    /// Render every frame of the scene's `[camera_path]` (files `<output stem>-NNNN.png`; without
    /// `-o`, in their own folder `out/<scene>-<method>/`) and print a frame-rate summary (fps
    /// min / median / max, median stage times).
    #[arg(long)]
    pub walkthrough: bool,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// The RRPs' derivative estimator: `hyman` (default: Hyman-filtered central
    /// differences), `monotone` (Fritsch-Butland) or `plain` (central differences).
    #[arg(long)]
    pub estimator: Option<String>,
    /// How many levels below the solver's leaves the RRPs follow the edges of the spot lights'
    /// light (cone rims, hard shadows): 3 by default, 0 to reconstruct it from the samples like
    /// any other light (docs/seams.md).
    #[arg(long, value_name = "N")]
    pub sharp_levels: Option<u32>,
    /// Print the statistics.
    #[arg(short, long)]
    pub verbose: bool,
    /// No progress bar, no "wrote" lines, no walkthrough summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct StatsArgs {
    /// A scene file or a solution file.
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Frames timed per method (after one warm-up); 0 = sizes only.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Frame width for the timings.
    #[arg(long, default_value_t = 1024)]
    pub width: u32,
    /// Frame height for the timings.
    #[arg(long, default_value_t = 1024)]
    pub height: u32,
    /// Samples per pixel: 1, 4 or 16.
    #[arg(long, default_value_t = 1)]
    pub aa: u32,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// When solving a scene, print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct ExperimentArgs {
    /// `fig5`, `fig6`, `table1` or `all`.
    pub which: String,
    /// Directory for the images (default: `out/experiments`).
    #[arg(long, default_value = "out/experiments")]
    pub out_dir: PathBuf,
    /// With `all`: write the Markdown report to this file (`docs/experiments.md`); image
    /// links are relative to its directory.
    #[arg(long)]
    pub doc: Option<PathBuf>,
    /// The texture-space scene of fig5 and fig6 (default: the one fitted to the paper's
    /// distances; `scenes/two-spots.toml` and `scenes/two-spots-narrow.toml` are variants).
    #[arg(long, default_value = "scenes/two-spots-paper.toml")]
    pub scene: PathBuf,
    /// Image side of fig5 and fig6.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Pixels per degree of the perceptual metric.
    #[arg(long, default_value_t = metric::DEFAULT_PPD)]
    pub ppd: f64,
    /// fig5, fig6: the RRPs' derivative estimator, `hyman` (default), `monotone` or
    /// `plain` (central differences).
    #[arg(long, default_value = "hyman")]
    pub estimator: String,
    /// table1: the scenes (default: the three shipped scenes).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<PathBuf>,
    /// table1: frames timed per method at 1024 x 1024 (0 = sizes only).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
}

#[derive(Args, Debug)]
pub(crate) struct BenchArgs {
    /// A scene file or a solution file.
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// The scene of a solution file, when it is no longer where the file says.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Methods to measure, comma-separated (`direct`, `texture-bilinear`, ...), each at
    /// every size, interleaved per size so they see the same machine state.
    #[arg(long, value_delimiter = ',', default_values_t = [String::from("direct")])]
    pub methods: Vec<String>,
    #[command(flatten)]
    pub texture: TextureArgs,
    /// Square image sizes to measure, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [512u32, 1024, 2048])]
    pub sizes: Vec<u32>,
    /// Frames timed per size (after one warm-up frame).
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Samples per pixel: 1, 4 or 16.
    #[arg(long, default_value_t = 1)]
    pub aa: u32,
    /// Virtual PixelFlow renderers.
    #[arg(long, default_value_t = 1)]
    pub renderers: u32,
    /// Side of the screen regions in pixels (a multiple of 8).
    #[arg(long, default_value_t = 128)]
    pub region: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// When solving a scene, print the solver's trace lines (phase times, shots, vertices, unshot) to stderr.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct SweepArgs {
    /// A scene file or a solution file (its scene is solved again at every density).
    pub input: PathBuf,
    /// Methods, comma-separated (default: direct and every texture method, and mesh).
    #[arg(long, value_delimiter = ',', default_values_t = study::sweep::DEFAULT_METHODS.map(String::from))]
    pub methods: Vec<String>,
    /// Image size, `WxH`.
    #[arg(long, default_value = "256x256", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Density levels as factors f of the scene's solver tolerance, coarse to fine; each also
    /// moves radiosity.max_depth by -round(log2 f) levels (and, for f > 1, min_depth likewise,
    /// down to 0).
    #[arg(long, value_delimiter = ',', default_values_t = study::sweep::DEFAULT_DENSITIES)]
    pub densities: Vec<f64>,
    /// Tolerance factor of the converged reference solution (its depth limit moved likewise:
    /// two levels deeper at 1/4).
    #[arg(long, default_value_t = 0.25)]
    pub reference_density: f64,
    /// Texture sizes per density: the quadtree-depth sizes halved 0 .. N-1 times.
    #[arg(long, default_value_t = 4)]
    pub texture_levels: u32,
    /// Frames timed per point and repeat (after a warm-up).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Timing repeats within each timing process.
    #[arg(long, default_value_t = 1)]
    pub repeats: u32,
    /// Separate processes each point is timed in (its time: the median over them, with a 95 %
    /// confidence interval from 6 on); 0: the repeats of this process alone.
    #[arg(long, default_value_t = study::timing::DEFAULT_PROCESSES, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMING_PROCESSES))]
    pub processes: u32,
    /// Pixels per degree of the perceptual metric.
    #[arg(long, default_value_t = metric::DEFAULT_PPD)]
    pub ppd: f64,
    /// Every point as JSON: to FILE, or to standard output instead of the table when no FILE
    /// (or `-`) is given.
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// Write every point as CSV to this file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Write the plots (error against frame time and against memory, PNG and SVG) into this
    /// directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Skip the equal-error memory search.
    #[arg(long)]
    pub no_equal_error: bool,
    /// Samples per pixel of the path-traced truth image the error budget is measured against
    /// (physics error, solution error, the truth's noise); 0: no truth image.
    #[arg(long, default_value_t = study::sweep::DEFAULT_TRUTH_SAMPLES)]
    pub truth_samples: u32,
    /// How many levels below the solver's leaves the direct and texture methods follow the
    /// edges of the spot lights' light: 3 by default; 0 draws the spots' light from the
    /// solver's samples for every method, as the mesh draws it (the same data for all methods:
    /// docs/sweep.md).
    #[arg(long, value_name = "N")]
    pub sharp_levels: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct ResultsArgs {
    /// The Markdown page to write (no default: in a checkout, `docs/results.md` is the committed
    /// page, replaced only when asked for by name).
    #[arg(long)]
    pub doc: PathBuf,
    /// Scene files, comma-separated (default: two-spots, cornell-box, gallery).
    #[arg(long, value_delimiter = ',')]
    pub scenes: Vec<PathBuf>,
    /// Side of the sweeps' square images.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Width of the gallery's images.
    #[arg(long, default_value_t = 192)]
    pub gallery_width: u32,
    /// Frames timed per sweep point and repeat.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMED_FRAMES))]
    pub frames: u32,
    /// Sweep timing repeats within each timing process.
    #[arg(long, default_value_t = 1)]
    pub repeats: u32,
    /// Separate processes each sweep point is timed in (the median over them, with a 95 %
    /// confidence interval from 6 on); 0: the repeats of this process alone.
    #[arg(long, default_value_t = study::timing::DEFAULT_PROCESSES, value_parser = clap::value_parser!(u32).range(0..=MAX_TIMING_PROCESSES))]
    pub processes: u32,
    /// Samples per pixel of each sweep's path-traced truth image (the error budget); 0: none.
    #[arg(long, default_value_t = study::sweep::DEFAULT_TRUTH_SAMPLES)]
    pub truth_samples: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print the solver's trace lines.
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct TruthArgs {
    /// A scene file (`.toml`), or a solution file (its scene is traced).
    pub input: PathBuf,
    #[command(flatten)]
    pub options: SceneOptions,
    /// OpenEXR of the mean radiosity per pixel; the standard errors go to `<stem>.stderr.exr`
    /// beside it.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// JSON of every polygon's estimates (mean B, direct, indirect, standard errors, object,
    /// material, area): to FILE (and printed as a table), or to standard output instead of the
    /// table when no FILE (or `-`) is given.
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// OpenEXR mask of the pixels within 2 of a shadow boundary (1, else 0), for `compare
    /// --mask`: where, at a pixel's centre, the share of the direct light that arrives unblocked
    /// changes between lit, penumbra and umbra on one face (docs/truth.md).
    #[arg(long, value_name = "FILE")]
    pub shadow_mask: Option<PathBuf>,
    /// Camera samples per pixel, at most (default 64).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Image width (default: the scene's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Sample the renderer's `--aa` positions (1, 4 or 16) instead of the whole pixel box.
    #[arg(long)]
    pub aa: Option<u32>,
    /// Seed of the random streams.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Samples per polygon, at most (default 4096).
    #[arg(long, value_name = "N")]
    pub polygon_samples: Option<u64>,
    /// Strata per side of each polygon's (u, v) grid (default 4: 16 cells).
    #[arg(long)]
    pub strata: Option<u32>,
    /// Stop once the relative standard error is at most this: every polygon's (against its
    /// luminance), and the image's root-mean-square over the pixels (against its mean).
    #[arg(long, value_name = "X")]
    pub max_error: Option<f64>,
    /// Most reflections a path follows (default: no limit; Russian roulette ends paths).
    #[arg(long)]
    pub max_bounces: Option<u32>,
    /// Also solve the scene (or read the solution file given as input) and report each
    /// polygon's solver mean beside the truth: ratio and distance in standard errors (JSON
    /// `solver`, `solver_ratio`, `solver_z`; a column of the table). Needs --json.
    #[arg(long)]
    pub compare_solver: bool,
    /// Worker threads (default: all cores). The results are identical for any count.
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar, no "wrote" lines, no table.
    #[arg(short, long)]
    pub quiet: bool,
    /// Print a line per pass (samples so far, error reached).
    #[arg(long)]
    pub trace: bool,
}

#[derive(Args, Debug)]
pub(crate) struct CompareArgs {
    /// The image under test.
    pub a: PathBuf,
    /// The reference image.
    pub b: PathBuf,
    /// Pixels per degree of visual angle (viewing distance) for the contrast sensitivity.
    #[arg(long, default_value_t = metric::DEFAULT_PPD)]
    pub ppd: f64,
    /// The visual angle the image's width spans, in degrees, instead of --ppd (ppd = width /
    /// DEG): every resolution of one picture is then seen alike, for thresholds that hold at
    /// any image size.
    #[arg(long, value_name = "DEG", conflicts_with = "ppd")]
    pub view_degrees: Option<f64>,
    /// JSON instead of the table: to FILE, or to standard output when no FILE (or `-`) is
    /// given (the same `--json [FILE]` in every command).
    #[arg(long, value_name = "FILE", num_args = 0..=1, default_missing_value = "-")]
    pub json: Option<PathBuf>,
    /// Regression check: compare pixel by pixel; a pixel differs when a channel moves by more
    /// than this times max(|reference|, --floor) (`default` = 2^-19, 16 f32 rounding steps).
    /// Lists the first differing pixels; exit 1 if more than --fail-percent of them differ.
    #[arg(long, value_name = "REL|default", value_parser = parse_tolerance)]
    pub tolerance: Option<f32>,
    /// With --tolerance: fail (exit 1) only when more than P % of the pixels differ (0, the
    /// default: any differing pixel fails).
    #[arg(long, value_name = "P", default_value_t = 0.0, requires = "tolerance")]
    pub fail_percent: f64,
    /// With --tolerance: the reference level under which the tolerance is absolute.
    #[arg(long, default_value_t = metric::pixels::DEFAULT_FLOOR)]
    pub floor: f32,
    /// With --tolerance: write the difference image here (PNG scaled so the largest
    /// difference is white, or EXR with the raw |a - b|).
    #[arg(long, value_name = "PATH", requires = "tolerance")]
    pub diff: Option<PathBuf>,
    /// Fail (exit 1) when the perceptual distance is above this (an L2 norm over the pixels:
    /// it grows with the image size; see --max-distance-per-pixel).
    #[arg(long, value_name = "D")]
    pub max_distance: Option<f64>,
    /// Fail (exit 1) when the perceptual distance per pixel (distance / sqrt(width x height))
    /// is above this; with --view-degrees the same for any image size.
    #[arg(long, value_name = "D")]
    pub max_distance_per_pixel: Option<f64>,
    /// Compare a PNG (sRGB, after the render's exposure) with a linear float image (EXR, HDR,
    /// PFM) by decoding the PNG to linear; without it such a pair is refused.
    #[arg(long)]
    pub convert: bool,
    /// Also split the luminance error at a mask image of the same size (pixels above one half
    /// are in it), e.g. `truth --shadow-mask`: RMSE inside and outside and their ratio.
    #[arg(long, value_name = "FILE")]
    pub mask: Option<PathBuf>,
    /// With --mask: a second, independent estimate of the reference (`truth` at another
    /// `--seed`); the split is then also given free of the references' noise, from the product
    /// of the two differences (docs/metrics.md).
    #[arg(long, value_name = "FILE")]
    pub second_reference: Option<PathBuf>,
}

/// The scenes `generate` makes.
#[derive(Subcommand, Debug)]
pub(crate) enum Generate {
    /// A building: a grid of closed rooms on one or more storeys, doorways between all
    /// neighbours on a storey, one or two emissive ceiling panels and up to four boxes or
    /// pillars per room.
    ///
    /// Writes `<name>.toml` and `<name>/<name>.obj` and `.mtl` beside it (atomically, all three
    /// together) and prints the polygon count: cut^2 (14 rooms + 12 doorways) + rooms (lights +
    /// 5 furniture). The same options give the same bytes. Exit code 2 for a bad option or over
    /// 1,000,000 polygons.
    Building(BuildingArgs),
}

#[derive(Args, Debug)]
pub(crate) struct BuildingArgs {
    /// Rooms along x on each storey.
    #[arg(long, value_name = "N")]
    pub rooms_x: u32,
    /// Rooms along z on each storey.
    #[arg(long, value_name = "M")]
    pub rooms_z: u32,
    /// Storeys (not connected to each other).
    #[arg(long, value_name = "F", default_value_t = generate::DEFAULT_FLOORS)]
    pub floors: u32,
    /// Cut every wall, floor, ceiling and doorway cell into K x K quads.
    #[arg(long, value_name = "K", default_value_t = generate::DEFAULT_CUT)]
    pub cut: u32,
    /// Emissive ceiling panels per room, 1 or 2.
    #[arg(long, default_value_t = generate::DEFAULT_LIGHTS)]
    pub lights: u32,
    /// Boxes or pillars per room, 0 to 4.
    #[arg(long, default_value_t = generate::DEFAULT_FURNITURE)]
    pub furniture: u32,
    /// Seed of the furniture's sizes and places.
    #[arg(long, default_value_t = generate::DEFAULT_SEED)]
    pub seed: u64,
    /// The scene file to write (`scenes/building.toml`), or a directory (the scene is then
    /// `<dir>/building.toml`).
    #[arg(short, long)]
    pub output: PathBuf,
}

fn parse_tolerance(text: &str) -> Result<f32, String> {
    if text == "default" {
        return Ok(metric::pixels::DEFAULT_TOLERANCE);
    }
    match text.parse::<f32>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err("must be a finite number >= 0, or `default`".into()),
    }
}

/// Options of the texture methods (ignored by the others).
#[derive(clap::Args, Debug, Clone)]
pub(crate) struct TextureArgs {
    /// Texture methods: one texture side for every polygon, a power of two: the side along the
    /// polygon's longer axis, the other in the ratio of the quad's sides (texels about square
    /// in the scene; triangles square) (default: the scene's `[render] texture_size`; 0 there
    /// = per polygon from its quadtree depth).
    #[arg(long)]
    texture_size: Option<u32>,
    /// Texture methods: a texture memory budget (12 bits per channel, mip chains included):
    /// bytes, or a number (decimals allowed) with K, M, G or T, with or without B (`2MB`,
    /// `1.5M`); sides are halved uniformly until it fits.
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
    /// Texture methods: most lookups a texture read takes along its footprint's longer axis,
    /// 1 (isotropic, the paper's hardware; default) to 16 (anisotropic filtering: sharper at
    /// grazing views, slower there).
    #[arg(long, value_name = "N")]
    anisotropy: Option<u32>,
}

impl TextureArgs {
    pub(crate) fn options(&self) -> TextureOptions {
        TextureOptions {
            size: self.texture_size,
            budget: self.texture_budget,
            bicubic: self.bicubic,
            placement: self.texel_placement.clone(),
            anisotropy: self.anisotropy,
        }
    }
}

fn parse_bytes(s: &str) -> Result<u64, String> {
    base::method::parse_bytes("--texture-budget", s).map_err(reason)
}

fn parse_bicubic(s: &str) -> Result<(f32, f32), String> {
    base::method::parse_bicubic(s).map_err(reason)
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
