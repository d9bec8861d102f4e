//! The bench job: frame times of one or more methods at several image sizes, measured in one run
//! with the methods interleaved per size so they see the same machine state. Solving and
//! reconstruction happen once, before timing; each size gets one warm-up frame, then the medians
//! of the measured frames are reported (wall-clock frame time, each stage, deferred-pass
//! throughput). Every row names the SIMD build it ran with, since the same binary times
//! differently under `PIXELFLOW_SIM_LANES`.

use crate::rates::{median, min_max};
use std::path::PathBuf;

use serde::Serialize;

use crate::context::Context;
use crate::context::Input;
use crate::context::TextureOptions;
use crate::frames::render_frame_in;
use crate::prepare::prepare;
use crate::prepare::Prepared;
use crate::rates::fps;
use base::error::{Error, Result};
use base::method::{Aa, Method};
use engine::frame::{FrameContext, FrameOptions, FrameStats};
use scene::MAX_IMAGE_DIM;

/// What one bench row times: a method, or the direct method reading fully expanded patches
/// instead of the compact RRPs (the baseline that shows what expanding on demand costs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Timed {
    /// A rendering method as `render` draws it.
    Method(Method),
    /// The direct method over [`reconstruction::Reconstruction`]'s stored patches.
    DirectExpanded,
}

/// The bench's name of [`Timed::DirectExpanded`].
pub(crate) const DIRECT_EXPANDED: &str = "direct-expanded";

impl Timed {
    /// The row's method name.
    pub fn name(&self) -> &'static str {
        match self {
            Timed::Method(m) => m.name(),
            Timed::DirectExpanded => DIRECT_EXPANDED,
        }
    }

    fn render(
        &self,
        ctx: &mut FrameContext,
        p: &Prepared,
        opts: &FrameOptions,
    ) -> Result<FrameStats> {
        match self {
            Timed::Method(m) => render_frame_in(ctx, p, *m, &p.scene.camera, opts),
            Timed::DirectExpanded => ctx.render(
                &p.scene,
                &p.scene.camera,
                &engine::shading::Shader::Patches(p.expanded()?.0),
                Method::Direct,
                opts,
            ),
        }
    }
}

/// What `pixelflow-sim bench` was asked to do.
#[derive(Debug, Clone)]
pub struct BenchRequest {
    /// The scene's command-line options (`-D`, `--camera`, `--strict`).
    pub load: scene::LoadOptions,
    /// Scene file or solution file.
    pub input: PathBuf,
    /// The scene of a solution file, when it is no longer where the file says (`--scene`).
    pub scene: Option<PathBuf>,
    /// Method names, each measured at every size.
    pub methods: Vec<String>,
    /// Texture sizes and the bicubic filter's parameters.
    pub texture: TextureOptions,
    /// Square image sides.
    pub sizes: Vec<u32>,
    /// Frames timed per size and method (after one warm-up frame).
    pub frames: u32,
    /// Samples per pixel.
    pub aa: u32,
    /// Virtual renderers.
    pub renderers: u32,
    /// Side of the screen regions in pixels (a multiple of 8).
    pub region: u32,
}

/// The result of a bench job: what was measured, and the rows.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// The input.
    pub input: String,
    /// Scene polygons.
    pub polygons: usize,
    /// Radiosity samples of the solution.
    pub samples: u64,
    /// RRP patches.
    pub patches: usize,
    /// Worker threads.
    pub threads: usize,
    /// One row per size and method, sizes outer, methods inner (the order measured).
    pub rows: Vec<BenchRow>,
}

/// Runs a bench job: load the input, check every option (methods, sizes, antialiasing,
/// renderers, texture options), then prepare once and measure.
pub fn run_bench(ctx: &Context<'_>, req: &BenchRequest) -> Result<BenchReport> {
    let input = Input::load_opts(&req.input, req.scene.as_deref(), &req.load)?;
    let methods = req
        .methods
        .iter()
        .map(|m| {
            if m == DIRECT_EXPANDED {
                Ok(Timed::DirectExpanded)
            } else {
                Ok(Timed::Method(req.texture.method(Method::parse(m)?)?))
            }
        })
        .collect::<Result<Vec<_>>>()?;
    let policy = req.texture.policy(&input.scene)?;
    let placement = req.texture.placement(&input.scene)?;
    for &s in &req.sizes {
        if s == 0 {
            return Err(Error::invalid_option("sizes", "0", "must be at least 1"));
        }
        if s > MAX_IMAGE_DIM {
            return Err(Error::limit("sizes", s.into(), MAX_IMAGE_DIM.into()));
        }
    }
    let base = FrameOptions {
        aa: Aa::new("aa", req.aa)?,
        renderers: req.renderers,
        region: req.region,
        anisotropy: req.texture.anisotropy(),
        ..ctx.frame_options(input.scene.width, input.scene.height)
    };
    base.validate()?;
    for &size in &req.sizes {
        crate::budget::check_frame(
            (size, size, base.region),
            base.aa.samples(),
            base.renderers,
            (false, false),
            ctx.memory_limit,
        )?;
    }
    let p = prepare(ctx, input, policy, placement)?;
    let mut rows = Vec::new();
    for &size in &req.sizes {
        for &m in &methods {
            rows.extend(bench(&p, m, &[(size, size)], req.frames, &base)?);
        }
    }
    Ok(BenchReport {
        input: req.input.display().to_string(),
        polygons: p.scene.polygons.len(),
        samples: p.solution.stats.vertices,
        patches: p.compact.leaf_count(),
        threads: rayon::current_num_threads(),
        rows,
    })
}

/// One row of `pixelflow-sim bench`: medians over the frames rendered at one size.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    /// Method.
    pub method: String,
    /// The SIMD build the frames ran with (`portable`, `avx2`, `avx512`: the CPU's widest,
    /// capped by `PIXELFLOW_SIM_LANES`), as [`lanes::Level::name`] names it.
    pub simd: &'static str,
    /// Image width and height.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub aa: u32,
    /// Frames measured (after one warm-up frame).
    pub frames: u32,
    /// Median wall-clock frame time, ms (see [`FrameStats::frame_ms`]).
    pub frame_ms: f64,
    /// Wall-clock time of the first frame in a new frame context (the warm-up frame), after
    /// [`FrameContext::reserve_scene`], ms.
    pub cold_frame_ms: f64,
    /// Time of [`FrameContext::reserve_scene`] in the new context (allocating and first touching
    /// the frame, the G-buffer pool and the primitive arrays), ms.
    pub reserve_ms: f64,
    /// Smallest and largest wall-clock frame time of the measured frames, ms.
    pub frame_ms_range: [f64; 2],
    /// Median sum of the stage times (composition overlaps rasterization), ms.
    pub stage_sum_ms: f64,
    /// Median geometry time, ms.
    pub geometry_ms: f64,
    /// Median raster time (binning, rasterization, patch-table fill), ms.
    pub raster_ms: f64,
    /// Median composition time (merge busy time per worker), ms.
    pub composition_ms: f64,
    /// Median deferred-shading time, ms.
    pub shading_ms: f64,
    /// Samples shaded per frame.
    pub samples_shaded: u64,
    /// Deferred pass throughput at the median shading time, Msample/s.
    pub shading_mpix_s: f64,
    /// Frames per second at the median wall-clock frame time.
    pub fps: f64,
}

/// Renders `frames` frames (after one warm-up) of the scene camera at each size and returns
/// the medians. Timing is wall-clock inside the frame's stages; the machine is whatever runs it.
pub fn bench(
    p: &Prepared,
    method: Timed,
    sizes: &[(u32, u32)],
    frames: u32,
    base: &FrameOptions,
) -> Result<Vec<BenchRow>> {
    let frames = frames.max(1);
    let mut rows = Vec::new();
    for &(w, h) in sizes {
        let opts = FrameOptions {
            width: w,
            height: h,
            ..base.clone()
        };
        // A new context, its frame and G-buffers reserved (timed apart), then its first frame
        // (the scene-dependent arrays allocated and first touched by it), then the warm frames
        // in the same context.
        let mut ctx = FrameContext::new();
        if let Timed::Method(m) = method {
            crate::frames::build_method_data(p, m)?;
        }
        let t = std::time::Instant::now();
        match method {
            Timed::Method(m) => crate::frames::reserve_frames(&mut ctx, p, m, &opts)?,
            Timed::DirectExpanded => ctx.reserve_scene(&opts, &p.scene)?,
        }
        let reserve_ms = t.elapsed().as_secs_f64() * 1e3;
        let cold_ms = method.render(&mut ctx, p, &opts)?.frame_ms;
        let mut stats = Vec::new();
        for _ in 0..frames {
            stats.push(method.render(&mut ctx, p, &opts)?);
        }
        let med = |f: fn(&FrameStats) -> f64| median(stats.iter().map(f).collect());
        let shading_ms = med(|s| s.shading_ms);
        let frame_ms = med(|s| s.frame_ms);
        let times: Vec<f64> = stats.iter().map(|s| s.frame_ms).collect();
        let samples = stats[0].pixels_shaded;
        rows.push(BenchRow {
            method: method.name().into(),
            simd: opts.isa.name(),
            width: w,
            height: h,
            aa: opts.aa.samples(),
            frames,
            frame_ms,
            cold_frame_ms: cold_ms,
            reserve_ms,
            frame_ms_range: min_max(&times),
            stage_sum_ms: med(|s| s.stage_sum_ms),
            geometry_ms: med(|s| s.geometry_ms),
            raster_ms: med(|s| s.raster_ms),
            composition_ms: med(|s| s.composition_ms),
            shading_ms,
            samples_shaded: samples,
            shading_mpix_s: if shading_ms > 0.0 {
                samples as f64 / shading_ms / 1e3
            } else {
                0.0
            },
            fps: fps(frame_ms),
        });
    }
    Ok(rows)
}

/// `simd build: avx2 (8 f32 lanes)`, the line naming the SIMD build of `rows` (every row of
/// one run has the same), with its newline; empty for no rows.
pub fn simd_line(rows: &[BenchRow]) -> String {
    let Some(level) = rows.first().and_then(|r| lanes::Level::named(r.simd)) else {
        return String::new();
    };
    format!("simd build: {}\n", level.describe())
}

/// The bench rows as a fixed-width table, after the line naming their SIMD build.
pub fn bench_table(rows: &[BenchRow]) -> String {
    let mut s = simd_line(rows);
    s.push_str(
        "method            size        aa  frame_ms  cold_ms reserve    fps  geometry  raster  compos.  shading  Msample/s\n",
    );
    for r in rows {
        s += &format!(
            "{:<17} {:>4}x{:<5} {:>3} {:>9.2} {:>8.2} {:>7.2} {:>6.1} {:>9.2} {:>7.2} {:>8.2} {:>8.2} {:>10.0}\n",
            r.method,
            r.width,
            r.height,
            r.aa,
            r.frame_ms,
            r.cold_frame_ms,
            r.reserve_ms,
            r.fps,
            r.geometry_ms,
            r.raster_ms,
            r.composition_ms,
            r.shading_ms,
            r.shading_mpix_s
        );
    }
    s
}
