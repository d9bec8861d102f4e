//! The command line's arguments: every subcommand and option, with its help text, parsed and
//! range-checked by clap before the library sees it (an out-of-range value exits 2 with clap's
//! usage message). `commands.rs` turns them into the library's requests.
//!
//! Each subcommand's options are a struct of their own (`Command::Render(RenderArgs)`); the
//! doc comment of the `Command` variant is the subcommand's help text. This module holds the
//! command list and the options several subcommands share (scene options, texture options,
//! value parsers); the subcommands' own structs are in `drawing` (check, solve, render, stats,
//! bench, view, export: one scene and its frames) and `studies` (experiment, sweep, results,
//! truth, compare, generate: measurements and their inputs).

use std::path::PathBuf;

use app::context::TextureOptions;
use base::Error;
use clap::{Args, Parser, Subcommand};
use fixtures::generate;

mod drawing;
mod studies;

pub(crate) use drawing::*;
pub(crate) use studies::*;

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
