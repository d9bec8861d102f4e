//! The render job: one frame, or every frame of the scene's camera path, to PNG (and EXR and
//! statistics JSON on request).
//!
//! `RenderPlan::new` resolves every option against the scene's defaults and checks it before
//! [`run_render`] solves anything; a walkthrough reuses one solution and one reconstruction for
//! all its frames, reports its progress as the stage `WALKTHROUGH_STAGE` and ends with a
//! [`WalkthroughSummary`]. Every file is written atomically.

use crate::rates::fps;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::commands::walkthrough::WalkthroughSummary;
use crate::context::Context;
use crate::context::Input;
use crate::context::TextureOptions;
use crate::prepare::prepare;
use crate::prepare::Prepared;
use base::error::{Error, Result};
use base::method::{Aa, Method};
use base::progress::Stage;
use engine::frame::{FrameContext, FrameOptions, FrameStats};
use imageio::exposure::{self, LuminanceSummary};
use imageio::OutputFormat;
use reconstruction::mesh::MeshStats;
use reconstruction::texture::{Placement, SizePolicy, TextureMemory};
use scene::{Camera, Scene};

/// What `pixelflow-sim render` was asked to do.
#[derive(Debug, Clone, Default)]
pub struct RenderRequest {
    /// Scene file or solution file.
    pub input: PathBuf,
    /// PNG to write (default `default_png_path`); walkthrough frames are numbered beside it.
    pub output: Option<PathBuf>,
    /// OpenEXR of the linear radiosity to write (single frames only).
    pub exr: Option<PathBuf>,
    /// Method name (default: the scene's `[render] method`).
    pub method: Option<String>,
    /// Image width (default: the scene's).
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    pub height: Option<u32>,
    /// Samples per pixel (default: the scene's).
    pub aa: Option<u32>,
    /// Virtual renderers.
    pub renderers: u32,
    /// Region side in pixels.
    pub region: u32,
    /// Where to write the statistics JSON (for a walkthrough, an object with the `summary` and
    /// the `frames`).
    pub stats: Option<PathBuf>,
    /// Render every frame of the scene's camera path.
    pub walkthrough: bool,
    /// The scene of a solution file, when it is no longer where the file says (`--scene`).
    pub scene: Option<PathBuf>,
    /// Texture sizes and the bicubic filter's parameters.
    pub texture: TextureOptions,
    /// The RRPs' derivative estimator by name (`--estimator`; default: the default estimator).
    pub estimator: Option<String>,
    /// Levels below the solver's leaves the RRPs and the mesh follow the spots' edges
    /// (`--sharp-levels`; default [`reconstruction::sharp::DEFAULT_LEVELS`], 0 = off).
    pub sharp_levels: Option<u32>,
    /// The scene's command-line options (`-D`, `--camera`, `--strict`).
    pub load: scene::LoadOptions,
    /// Exposure of the PNG in stops (`--exposure`; default: the scene's `[display] exposure`).
    pub exposure: Option<f64>,
    /// Choose the exposure from the first frame (`--auto-exposure`,
    /// [`imageio::exposure::auto_exposure`]); used for every frame of a walkthrough.
    pub auto_exposure: bool,
}

/// A render request resolved against its scene and checked: what will be drawn, how, and where
/// it goes.
#[derive(Debug, Clone)]
pub(crate) struct RenderPlan {
    /// The method, with the bicubic filter's parameters applied.
    pub method: Method,
    /// The frame options (checked).
    pub frame: FrameOptions,
    /// How textures are sized (checked against the scene's polygon count).
    pub texture_policy: SizePolicy,
    /// Where the texels sit (`--texel-placement` or the scene's).
    pub texture_placement: Placement,
    /// Each frame's camera and PNG path: one, or the whole camera path.
    pub frames: Vec<(Camera, PathBuf)>,
    /// The EXR to write (single frames only).
    pub exr: Option<PathBuf>,
    /// The statistics JSON to write.
    pub stats: Option<PathBuf>,
    /// Whether this is a walkthrough.
    pub walkthrough: bool,
}

impl RenderPlan {
    /// Resolves `req` against `scene` and checks every option: method and bicubic parameters,
    /// image size, antialiasing, renderers, region, texture size or budget, texel placement,
    /// `--exr` with
    /// `--walkthrough`, and that a walkthrough has a camera path.
    pub(crate) fn new(ctx: &Context<'_>, req: &RenderRequest, scene: &Scene) -> Result<RenderPlan> {
        let method = match &req.method {
            Some(name) => Method::parse(name)?,
            None => scene.render.method,
        };
        let method = req.texture.method(method)?;
        let frame = FrameOptions {
            width: req.width.unwrap_or(scene.width),
            height: req.height.unwrap_or(scene.height),
            aa: match req.aa {
                Some(n) => Aa::new("aa", n)?,
                None => scene.render.aa_samples,
            },
            renderers: req.renderers,
            region: req.region,
            cull_back_faces: false,
            isa: ctx.isa,
            anisotropy: req.texture.anisotropy(),
        };
        frame.validate()?;
        crate::budget::check_frame_options(&frame, (true, req.exr.is_some()), ctx.memory_limit)?;
        let texture_policy = req.texture.policy(scene)?;
        let texture_placement = req.texture.placement(scene)?;
        if req.walkthrough && req.exr.is_some() {
            return Err(Error::invalid_option(
                "exr",
                req.exr
                    .as_deref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_default(),
                "writes one frame; it cannot be combined with `walkthrough`",
            ));
        }
        let png = match &req.output {
            Some(p) => p.clone(),
            None if req.walkthrough => walkthrough_folder(&default_png_path(req, method, &frame)),
            None => default_png_path(req, method, &frame),
        };
        let frames = if req.walkthrough {
            let path = scene.camera_path.as_ref().ok_or_else(|| {
                let how = if scene::is_model(&scene.source) {
                    ": a model has none; write a scene file that includes it ([[obj]] or \
                     [[gltf]]) and give it one (docs/tutorial.md)"
                } else {
                    ""
                };
                Error::invalid_option(
                    "walkthrough",
                    "",
                    format!("{} has no [camera_path]{how}", scene.source.display()),
                )
            })?;
            (0..path.frames)
                .map(|k| {
                    (
                        path.camera(scene.camera.projection, k),
                        walkthrough_frame_path(&png, k),
                    )
                })
                .collect()
        } else {
            vec![(scene.camera, png)]
        };
        Ok(RenderPlan {
            method,
            frame,
            texture_policy,
            texture_placement,
            frames,
            exr: req.exr.clone(),
            stats: req.stats.clone(),
            walkthrough: req.walkthrough,
        })
    }
}

/// What a render job reports as it goes.
#[derive(Debug)]
pub enum RenderEvent<'a> {
    /// A warning: the scene's (a non-planar quad split, ...), or a frame with no polygon in
    /// view (`empty_view_warning`).
    Warning(&'a str),
    /// A note: how many repairs of the scene's input changed nothing the image shows, or where
    /// the solve stopped refining with its error test still failing.
    Note(&'a str),
    /// A file was written.
    Wrote(&'a Path),
    /// A frame was rendered.
    Frame(&'a RenderReport),
    /// A walkthrough ended: its summary (the last event of a walkthrough).
    Walkthrough(&'a WalkthroughSummary),
    /// The luminance summary of the image (of a walkthrough's first frame), after its file
    /// was written.
    Luminance(&'a Path, &'a LuminanceSummary),
}

/// The progress stage of a walkthrough's frames: fraction `k / n` after frame `k` of `n`.
pub(crate) const WALKTHROUGH_STAGE: &str = "walkthrough";

/// The `--stats` JSON of a walkthrough.
#[derive(Debug, Clone, Serialize)]
pub(crate) struct WalkthroughReport<'a> {
    /// Frame rates and medians over the frames.
    pub summary: &'a WalkthroughSummary,
    /// Every frame's report, in path order.
    pub frames: &'a [RenderReport],
}

/// The `--sharp-levels` value, checked: at most 16 (the lattice's depth; a deeper split has no
/// lattice points).
pub fn check_sharp_levels(levels: u32) -> Result<u32> {
    if levels > base::quadtree::MAX_DEPTH {
        return Err(Error::invalid_option(
            "sharp-levels",
            levels.to_string(),
            "expected 0 (off) to 16",
        ));
    }
    Ok(levels)
}

/// Checks a render's outputs before any work: none may replace an input, another output or
/// anything but a regular file; then the formats follow the names (`-o` PNG, EXR, HDR or PFM,
/// `--exr` EXR), and `--exposure` is in range.
fn check_render_outputs(req: &RenderRequest, plan: &RenderPlan, scene: &Scene) -> Result<()> {
    // No output may replace an input, another output or anything but a regular file.
    let mut inputs = scene.inputs.clone();
    inputs.push(req.input.clone());
    let mut outputs: Vec<(&str, &Path)> = plan
        .frames
        .iter()
        .map(|(_, png)| ("output", png.as_path()))
        .collect();
    outputs.extend(plan.exr.as_deref().map(|e| ("exr", e)));
    outputs.extend(plan.stats.as_deref().map(|s| ("stats", s)));
    base::output::check_outputs(&inputs, &outputs)?;
    // Then the format follows the name (after the data-loss checks, whose messages say more).
    if let Some(o) = &req.output {
        if OutputFormat::of(o).is_none() {
            return Err(Error::invalid_option(
                "output",
                o.display().to_string(),
                "must end in .png (8-bit sRGB after the exposure), .exr, .hdr or .pfm (linear \
                 radiosity): the format follows the name",
            ));
        }
    }
    if let Some(e) = req.exposure {
        if !e.is_finite() || e.abs() > exposure::MAX_AUTO_STOPS {
            return Err(Error::invalid_option(
                "exposure",
                e.to_string(),
                format!("stops, from -{0} to {0}", exposure::MAX_AUTO_STOPS),
            ));
        }
    }
    if let Some(e) = &req.exr {
        let what = "an OpenEXR file (linear float); the sRGB image goes to -o";
        check_extension("exr", e, "exr", what)?;
    }
    if let Some(s) = &req.stats {
        check_extension("stats", s, "json", "JSON (the frame statistics)")?;
    }
    Ok(())
}

/// Whether the exposure is chosen from the first frame: `--auto-exposure`, or a bare model
/// (which has no `[display]` to set it in) when neither `--exposure` nor `-D display.exposure`
/// gives one.
fn wants_auto_exposure(req: &RenderRequest, scene: &Scene) -> bool {
    let set_by_d = req
        .load
        .overrides
        .iter()
        .any(|(k, _)| k == "display.exposure");
    req.auto_exposure || (req.exposure.is_none() && scene::is_model(&scene.source) && !set_by_d)
}

/// The luminance summary of a frame shown with `exposure` stops (`stats`: its counters).
fn luminance_of(
    view: base::image::ImageView<'_>,
    stats: &FrameStats,
    frame: &FrameOptions,
    scene: &Scene,
    exposure: f64,
) -> LuminanceSummary {
    let samples = frame.width as f64 * frame.height as f64 * frame.aa.samples() as f64;
    let covered = stats.pixels_shaded as f64 / samples.max(1.0);
    let background = base::image::luminance(scene.display.background.as_vec3());
    exposure::summarize(view, exposure, covered, background)
}

/// The first steps of a render job: load the input, plan and check every option and output,
/// say the scene's warnings and notes, then solve (or read) and prepare once, saying what the
/// solve warns of.
fn prepared_for_render(
    ctx: &Context<'_>,
    req: &RenderRequest,
    on: &mut dyn FnMut(RenderEvent<'_>),
) -> Result<(Prepared, RenderPlan)> {
    let mut input = Input::load_opts(&req.input, req.scene.as_deref(), &req.load)?;
    let plan = RenderPlan::new(ctx, req, &input.scene)?;
    if let Some(name) = &req.estimator {
        input.estimator = reconstruction::Estimator::parse_option("estimator", name)?;
    }
    if let Some(levels) = req.sharp_levels {
        input.sharp_levels = check_sharp_levels(levels)?;
    }
    check_render_outputs(req, &plan, &input.scene)?;
    for w in &input.scene.warnings {
        on(RenderEvent::Warning(w));
    }
    if let Some(n) = crate::context::notes_line(&input.scene) {
        on(RenderEvent::Note(&n));
    }
    let p = prepare(ctx, input, plan.texture_policy, plan.texture_placement)?;
    // Where the solve stopped refining with its error test failing: a property of the solution
    // (its `max_depth`), said by `solve` as a warning and here as a note.
    if let Some(w) = p.solution.stats.guard_stops.warning(&p.scene) {
        on(RenderEvent::Note(&w));
    }
    let convergence = p.scene.radiosity.convergence;
    for w in p.solution.stats.light_warnings(convergence) {
        on(RenderEvent::Warning(&w));
    }
    Ok((p, plan))
}

/// Runs a render job: load the input, plan and check every option, then prepare once and
/// render one frame or every walkthrough frame, writing PNG, EXR and statistics.
pub fn run_render(
    ctx: &Context<'_>,
    req: &RenderRequest,
    on: &mut dyn FnMut(RenderEvent<'_>),
) -> Result<()> {
    let (p, plan) = prepared_for_render(ctx, req, on)?;
    let mut exposure = req.exposure.unwrap_or(p.scene.display.exposure);
    let auto_exposure = wants_auto_exposure(req, &p.scene);
    let n = plan.frames.len();
    // The walkthrough's own stage, after the solve's: it ends (also on an error) when dropped.
    let mut stage = plan
        .walkthrough
        .then(|| Stage::start(ctx.observer, WALKTHROUGH_STAGE));
    let mut reports = Vec::new();
    let mut summary_of_first: Option<(PathBuf, LuminanceSummary)> = None;
    // A single frame's PNG, EXR and statistics are one batch: all replaced or none
    // (base::output). A walkthrough's frames are written as they are drawn.
    let mut batch = ctx.outputs.batch();
    let mut staged: Vec<&Path> = Vec::new();
    let files = ctx.outputs.clone();
    // One frame context for every frame: a walkthrough's frames reuse its buffers, and the
    // frame and G-buffers are reserved before the first frame (timed apart), as a display
    // system allocates its framebuffers before it draws.
    let observer = ctx.observer;
    let mut ctx = FrameContext::new();
    crate::frames::build_method_data(&p, plan.method)?;
    let t = std::time::Instant::now();
    crate::frames::reserve_frames(&mut ctx, &p, plan.method, &plan.frame)?;
    let reserve_ms = t.elapsed().as_secs_f64() * 1e3;
    for (k, (camera, png)) in plan.frames.iter().enumerate() {
        let stats = crate::frames::render_frame_in_observed(
            &mut ctx,
            &p,
            plan.method,
            camera,
            &plan.frame,
            observer,
        )?;
        // A valid scene can still put nothing in view (every polygon behind the camera or
        // outside its frustum): the image is drawn, but never silently as the background alone.
        if stats.pixels_shaded == 0 {
            on(RenderEvent::Warning(&empty_view_warning(
                &req.input,
                plan.walkthrough.then_some(k),
            )));
        }
        if k == 0 && auto_exposure {
            exposure = exposure::auto_exposure(ctx.view());
        }
        let format = OutputFormat::of(png).unwrap_or(OutputFormat::Png);
        let bytes = format.encode(ctx.view(), exposure)?;
        if k == 0 {
            let l = luminance_of(ctx.view(), &stats, &plan.frame, &p.scene, exposure);
            summary_of_first = Some((png.clone(), l));
        }
        if plan.walkthrough {
            files.write_atomic(png, &bytes)?;
            on(RenderEvent::Wrote(png));
        } else {
            batch.stage(png, &bytes)?;
            staged.push(png);
        }
        if let Some(exr) = &plan.exr {
            batch.stage(exr, &imageio::encode_exr(ctx.view())?)?;
            staged.push(exr);
        }
        let mut report = RenderReport::new(&p, plan.method, stats, plan.frame.isa);
        report.reserve_ms = reserve_ms;
        on(RenderEvent::Frame(&report));
        reports.push(report);
        if let Some(stage) = &mut stage {
            stage.advance((k + 1) as f64 / n as f64);
        }
    }
    drop(stage);
    let summary = plan.walkthrough.then(|| {
        let frames: Vec<FrameStats> = reports.iter().map(|r| r.frame.clone()).collect();
        WalkthroughSummary::new(&frames)
    });
    if let Some(path) = &plan.stats {
        batch.stage(path, stats_json(summary.as_ref(), &reports)?.as_bytes())?;
        staged.push(path);
    }
    batch.commit()?;
    for path in staged {
        on(RenderEvent::Wrote(path));
    }
    if let Some((path, l)) = &summary_of_first {
        on(RenderEvent::Luminance(path, l));
        if let Some(w) = exposure::exposure_warning(l, auto_exposure) {
            on(RenderEvent::Warning(&w));
        }
    }
    if let Some(summary) = &summary {
        on(RenderEvent::Walkthrough(summary));
    }
    Ok(())
}

/// The `--stats` JSON: a walkthrough's summary and frames, or the single frame's report.
fn stats_json(summary: Option<&WalkthroughSummary>, reports: &[RenderReport]) -> Result<String> {
    match summary {
        Some(summary) => serde_json::to_string_pretty(&WalkthroughReport {
            summary,
            frames: reports,
        }),
        None => serde_json::to_string_pretty(&reports[0]),
    }
    .map_err(|e| Error::internal(format!("statistics to JSON: {e}")))
}

/// The warning of a frame in which no polygon is in view, so every pixel is the background:
/// names the input and, in a walkthrough, the frame.
pub(crate) fn empty_view_warning(input: &Path, walkthrough_frame: Option<usize>) -> String {
    let frame = walkthrough_frame.map_or(String::new(), |k| format!(" (frame {k})"));
    format!(
        "{}{frame}: no polygon is in view (all behind the camera or outside its field of view): \
         the image is only the background",
        input.display()
    )
}

/// The statistics written by `--stats`: the frame's counters and stage times, plus the
/// one-off costs that are not part of `frame_ms`.
#[derive(Debug, Clone, Serialize)]
pub struct RenderReport {
    /// The frame's counters and stage times.
    #[serde(flatten)]
    pub frame: FrameStats,
    /// Frames per second of this frame, `1000 / frame_ms` (the wall-clock frame time).
    pub fps: f64,
    /// Solve time in this run (0 when the solution was read from a file), ms.
    pub solve_ms: f64,
    /// RRP construction time, ms.
    pub reconstruction_ms: f64,
    /// Time to allocate and first touch the frame context's frame and G-buffers, once per job
    /// before the first frame (`FrameContext::reserve`), ms.
    pub reserve_ms: f64,
    /// RRP patches stored.
    pub patches: u64,
    /// Radiosity samples in the solution.
    pub samples: u64,
    /// Where the solve's guards stopped refinement with the error test still failing.
    pub guard_stops: crate::commands::stats::GuardReport,
    /// Texture memory and count (texture methods only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture_memory: Option<TextureMemory>,
    /// Time to resample the textures from the RRPs, once per job (texture methods only), ms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub texture_build_ms: Option<f64>,
    /// The mesh's triangles, vertices and size (mesh method only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshStats>,
    /// Time to triangulate the mesh, once per job (mesh method only), ms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh_build_ms: Option<f64>,
    /// The SIMD build the frame ran with (`portable`, `avx2`, `avx512`; [`lanes::Level::name`]).
    pub simd: &'static str,
}

impl RenderReport {
    /// The report of a frame rendered from `p` with the instruction set `isa`, with its
    /// statistics `frame`.
    pub fn new(p: &Prepared, method: Method, frame: FrameStats, isa: lanes::Isa) -> RenderReport {
        let tex = match method {
            Method::Texture(_) => p.textures().ok(),
            _ => None,
        };
        let mesh = match method {
            Method::Mesh => p.mesh().ok(),
            _ => None,
        };
        RenderReport {
            mesh: mesh.map(|(m, _)| m.stats),
            mesh_build_ms: mesh.map(|(_, ms)| ms),
            texture_memory: tex.map(|(set, _)| set.memory),
            texture_build_ms: tex.map(|(_, ms)| ms),
            fps: fps(frame.frame_ms),
            frame,
            solve_ms: p.solve_ms,
            reconstruction_ms: p.reconstruction_ms,
            reserve_ms: 0.0,
            patches: p.compact.leaf_count() as u64,
            samples: p.solution.stats.vertices,
            guard_stops: crate::commands::stats::GuardReport::of(
                &p.solution.stats.guard_stops,
                &p.scene,
            ),
            simd: isa.name(),
        }
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|_| "{}".into())
    }
}

/// Refuses an output whose name does not end in `.ext` (any case): the bytes written are that
/// format's, so a file named otherwise would lie about its contents.
pub fn check_extension(option: &str, path: &Path, ext: &str, what: &str) -> Result<()> {
    let ok = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(ext));
    if ok {
        return Ok(());
    }
    Err(Error::invalid_option(
        option,
        path.display().to_string(),
        format!("must end in .{ext}: it is written as {what}"),
    ))
}

/// Where output goes when the user names no file: `out/<scene stem>-<method>.png`, with every
/// option given that changes the pixels of this method appended (`-640x480`, `-aa4`, `-t64` or
/// `-b2097152` for the texture size or budget, `-bc0,0.5`, `-corner`, `-plain`, `-sharp0`), so
/// renders of one scene with different options do not overwrite each other; `-ev1.5` or
/// `-autoexp` for the exposure, and `-D` with a 6-digit digest of the `-D` and `--camera`
/// overrides. Renderers, regions and threads change no pixel and no name.
pub(crate) fn default_png_path(
    req: &RenderRequest,
    method: Method,
    frame: &FrameOptions,
) -> PathBuf {
    let stem = req
        .input
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".into());
    let mut name = format!("{stem}-{}", method.name());
    if req.width.is_some() || req.height.is_some() {
        name += &format!("-{}x{}", frame.width, frame.height);
    }
    if let Some(aa) = req.aa {
        name += &format!("-aa{aa}");
    }
    if let Method::Texture(filter) = method {
        let t = &req.texture;
        if let Some(n) = t.size {
            name += &format!("-t{n}");
        }
        if let Some(b) = t.budget {
            name += &format!("-b{b}");
        }
        if let (Some((b, c)), base::method::Filter::Bicubic { .. }) = (t.bicubic, filter) {
            name += &format!("-bc{b},{c}");
        }
        if let Some(p) = &t.placement {
            name += &format!("-{p}");
        }
    }
    if matches!(method, Method::Direct | Method::Texture(_)) {
        if let Some(e) = &req.estimator {
            name += &format!("-{e}");
        }
        if let Some(s) = req.sharp_levels {
            name += &format!("-sharp{s}");
        }
    }
    if let Some(e) = req.exposure.filter(|_| !req.auto_exposure) {
        name += &format!("-ev{e}");
    }
    if req.auto_exposure {
        name += "-autoexp";
    }
    if !req.load.overrides.is_empty() {
        // The overrides (camera, image, settings) as a short digest: FNV-1a of their text.
        let text: Vec<String> = req
            .load
            .overrides
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        let mut h = radiosity::Fnv::default();
        h.bytes(text.join("\n").as_bytes());
        name += &format!("-D{:06x}", h.0 & 0xff_ffff);
    }
    PathBuf::from("out").join(name + ".png")
}

/// A walkthrough's frames without a name given: in their own folder, named like the default
/// PNG (`out/<name>/<name>-NNNN.png` for `out/<name>.png`), not among everything else in
/// `out/`.
fn walkthrough_folder(png: &Path) -> PathBuf {
    match (png.file_stem(), png.file_name()) {
        (Some(stem), Some(name)) => png.with_file_name(stem).join(name),
        _ => png.to_path_buf(),
    }
}

/// The frame file name of walkthrough frame `k`: `<stem>-NNNN.<ext>` beside `png` (the
/// format of the name given).
pub(crate) fn walkthrough_frame_path(png: &Path, k: u32) -> PathBuf {
    let stem = png
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".into());
    let ext = png
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_else(|| "png".into());
    png.with_file_name(format!("{stem}-{k:04}.{ext}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use base::method::Filter;
    use base::progress::{Event, Recorder};

    /// A directory of this test process for `name`'s files.
    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir()
            .join(format!("pfs-render-{}", std::process::id()))
            .join(name);
        std::fs::create_dir_all(&d).expect("temporary directory");
        d
    }

    /// The two-spots scene with a `frames`-frame camera path, written into `dir`.
    fn walk_scene(dir: &Path, frames: u32) -> PathBuf {
        let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/two-spots.toml");
        let text = std::fs::read_to_string(scene).expect("two-spots scene")
            + &format!(
                "\n[camera_path]\nframes = {frames}\nkeyframes = [\n\
                 {{ eye = [0.3, 0.5, 2.0], look_at = [0.3, 0.5, 0.0], up = [0.0, 1.0, 0.0] }},\n\
                 {{ eye = [0.7, 0.5, 2.0], look_at = [0.7, 0.5, 0.0], up = [0.0, 1.0, 0.0] }},\n]\n"
            );
        let path = dir.join("walk.toml");
        std::fs::write(&path, text).expect("scene written");
        path
    }

    fn request(input: PathBuf, output: PathBuf) -> RenderRequest {
        RenderRequest {
            input,
            output: Some(output),
            width: Some(16),
            height: Some(16),
            renderers: 1,
            region: 128,
            walkthrough: true,
            ..RenderRequest::default()
        }
    }

    /// Default names carry the options that change this method's pixels, and only those.
    #[test]
    fn default_names_carry_the_options_that_change_pixels() {
        let name = |req: &RenderRequest, m: Method| {
            let frame = FrameOptions::new(req.width.unwrap_or(8), req.height.unwrap_or(8));
            default_png_path(req, m, &frame)
        };
        let mut req = RenderRequest {
            input: PathBuf::from("scenes/x.toml"),
            renderers: 3,
            ..RenderRequest::default()
        };
        assert_eq!(name(&req, Method::Direct), Path::new("out/x-direct.png"));
        // A walkthrough without a name: its own folder.
        assert_eq!(
            walkthrough_frame_path(&walkthrough_folder(Path::new("out/x-direct.png")), 7),
            Path::new("out/x-direct/x-direct-0007.png")
        );
        req.width = Some(64);
        req.height = Some(32);
        req.aa = Some(4);
        req.texture.size = Some(64);
        req.texture.bicubic = Some((0.0, 0.5));
        assert_eq!(
            name(&req, Method::Direct),
            Path::new("out/x-direct-64x32-aa4.png")
        );
        assert_eq!(
            name(&req, Method::Texture(Filter::MITCHELL)),
            Path::new("out/x-texture-bicubic-64x32-aa4-t64-bc0,0.5.png")
        );
        assert_eq!(
            name(&req, Method::Texture(Filter::Bilinear)),
            Path::new("out/x-texture-bilinear-64x32-aa4-t64.png")
        );
        req.estimator = Some("plain".into());
        assert_eq!(
            name(&req, Method::Mesh),
            Path::new("out/x-mesh-64x32-aa4.png")
        );
        assert_eq!(
            name(&req, Method::Direct),
            Path::new("out/x-direct-64x32-aa4-plain.png")
        );
    }

    /// The fractions of the walkthrough stage and whether it finished after them.
    fn walkthrough_events(r: &Recorder) -> (Vec<f64>, usize) {
        let mut fractions = Vec::new();
        let mut finished = 0;
        for e in r.events() {
            match e {
                Event::Progress(s, f) if s == WALKTHROUGH_STAGE => {
                    assert_eq!(finished, 0, "progress after finished");
                    fractions.push(f);
                }
                Event::Finished(s) if s == WALKTHROUGH_STAGE => finished += 1,
                _ => {}
            }
        }
        (fractions, finished)
    }

    #[test]
    fn a_walkthrough_reports_its_own_stage_up_to_one_then_finishes() {
        let dir = tmp("stage");
        let r = Recorder::default();
        let mut summaries = Vec::new();
        let mut frames = 0;
        let req = request(walk_scene(&dir, 4), dir.join("w.png"));
        run_render(&Context::new(&r), &req, &mut |e| match e {
            RenderEvent::Frame(_) => frames += 1,
            RenderEvent::Walkthrough(s) => summaries.push(s.clone()),
            _ => {}
        })
        .expect("walkthrough renders");
        let (fractions, finished) = walkthrough_events(&r);
        assert_eq!(fractions, [0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(finished, 1);
        // The solve's stage ended before the walkthrough's began.
        let events = r.events();
        let solve_end = events
            .iter()
            .position(|e| matches!(e, Event::Finished(s) if s == "solve"))
            .expect("the scene was solved");
        let walk_start = events
            .iter()
            .position(|e| matches!(e, Event::Progress(s, _) if s == WALKTHROUGH_STAGE))
            .expect("the walkthrough started");
        assert!(solve_end < walk_start, "{events:?}");
        assert_eq!(frames, 4);
        assert_eq!(summaries.len(), 1);
        assert_eq!(summaries[0].frames, 4);
    }

    #[test]
    fn a_failing_walkthrough_still_finishes_its_stage() {
        // The frames' directory is one the file system refuses files in (Linux's /proc, even
        // for root), which no check before the work can see: the first PNG cannot be written.
        if !Path::new("/proc/self").exists() {
            return;
        }
        let dir = tmp("fail");
        let r = Recorder::default();
        let req = request(
            walk_scene(&dir, 3),
            Path::new("/proc/pixelflow-sim-walk/w.png").to_path_buf(),
        );
        assert!(run_render(&Context::new(&r), &req, &mut |_| {}).is_err());
        let (fractions, finished) = walkthrough_events(&r);
        assert_eq!(fractions, [0.0]);
        assert_eq!(finished, 1);
    }

    #[test]
    fn a_single_frame_reports_no_walkthrough_stage() {
        let dir = tmp("single");
        let r = Recorder::default();
        let req = RenderRequest {
            walkthrough: false,
            ..request(walk_scene(&dir, 2), dir.join("one.png"))
        };
        let mut summary = false;
        run_render(&Context::new(&r), &req, &mut |e| {
            summary |= matches!(e, RenderEvent::Walkthrough(_));
        })
        .expect("frame renders");
        assert_eq!(walkthrough_events(&r), (vec![], 0));
        assert!(!summary);
    }
}
