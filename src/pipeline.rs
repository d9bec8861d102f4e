//! Pipeline: the stages glued into the jobs the command line runs. `solve` turns a scene into a
//! solution file; `render` takes a scene (and solves it) or a solution file (and loads its scene),
//! reconstructs the RRPs once, then renders one frame or a whole walkthrough with the chosen
//! method and writes PNG, EXR and statistics.
//!
//! Invariants: every file is written through [`crate::output::write_atomic`]; nothing here knows
//! how a stage works inside, only the order of the stages; a walkthrough reuses one solution and
//! one reconstruction for all its frames (it never solves twice). Each stage runs in the caller's
//! rayon pool, so the thread count is the caller's choice and the pixels do not depend on it.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Instant;

use glam::DVec3;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::image_out;
use crate::progress::Observer;
use crate::radiosity::{self, file as solution_file, Oracle, Solution, SolveOptions};
use crate::raster::{render_frame, render_frame_with, Frame, FrameOptions, FrameStats};
use crate::reconstruction::mesh::{MeshModel, MeshStats};
use crate::reconstruction::{Estimator, Reconstruction};
use crate::scene::{load_scene, Camera, Keyframe, Scene};
use crate::shading::Shader;
use crate::texture::{Filter, SizePolicy, TextureMemory, TextureSet};

/// The rendering methods. They share scene, solve, rasterization and composition; they differ
/// only in what the deferred pass evaluates (and, for the mesh, in what is rasterized).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// The PixelFlow path: bicubic RRP coefficients rasterized into region G-buffers and
    /// evaluated per pixel in the deferred pass.
    Direct,
    /// Radiosity textures (RAT) resampled from the RRPs, filtered on screen.
    Texture(Filter),
    /// The adaptively subdivided mesh (T-vertex fans), Gouraud shaded: the paper's "poly" model.
    Mesh,
    /// The solver's oracle at every visible sample: no reconstruction at all.
    Reference,
}

impl Method {
    /// Every implemented method's name.
    pub const NAMES: &'static [&'static str] = &[
        "direct",
        "texture-nearest",
        "texture-bilinear",
        "texture-bicubic",
        "mesh",
        "reference",
    ];

    /// Parses a method name (as on the command line and in `[render] method`);
    /// `texture-bicubic` is Mitchell–Netravali B = C = 1/3 (see [`Method::with_bicubic`]).
    pub fn parse(name: &str) -> Result<Method> {
        match name {
            "direct" => Ok(Method::Direct),
            "texture-nearest" => Ok(Method::Texture(Filter::Nearest)),
            "texture-bilinear" => Ok(Method::Texture(Filter::Bilinear)),
            "texture-bicubic" => Ok(Method::Texture(Filter::MITCHELL)),
            "mesh" => Ok(Method::Mesh),
            "reference" => Ok(Method::Reference),
            _ => Err(Error::Usage(format!(
                "method `{name}` is not available; implemented: {}",
                Method::NAMES.join(", ")
            ))),
        }
    }

    /// The method's name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Direct => "direct",
            Method::Texture(Filter::Nearest) => "texture-nearest",
            Method::Texture(Filter::Bilinear) => "texture-bilinear",
            Method::Texture(Filter::Bicubic { .. }) => "texture-bicubic",
            Method::Mesh => "mesh",
            Method::Reference => "reference",
        }
    }

    /// This method with the bicubic filter's (B, C) replaced, if it is `texture-bicubic`; an
    /// error for B or C outside [0, 1] or not finite (the Mitchell–Netravali family's useful
    /// range; Catmull-Rom is (0, 1/2)).
    pub fn with_bicubic(self, b: f32, c: f32) -> Result<Method> {
        for (name, x) in [("B", b), ("C", c)] {
            if !(0.0..=1.0).contains(&x) {
                return Err(Error::Usage(format!(
                    "--bicubic: {name} = {x} must be in [0, 1]"
                )));
            }
        }
        Ok(match self {
            Method::Texture(Filter::Bicubic { .. }) => Method::Texture(Filter::Bicubic { b, c }),
            m => m,
        })
    }
}

/// Command-line choices of the texture methods (all optional; the scene's `[render]` gives the
/// defaults).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TextureOptions {
    /// One texture side for every polygon (`--texture-size`, a power of two).
    pub size: Option<u32>,
    /// A texture memory budget in bytes at 12 bits per channel with mip chains
    /// (`--texture-budget`).
    pub budget: Option<u64>,
    /// The bicubic filter's (B, C) (`--bicubic B,C`; default Mitchell–Netravali 1/3, 1/3).
    pub bicubic: Option<(f32, f32)>,
}

impl TextureOptions {
    /// The size policy these options choose for `scene`: a size, a budget, or the scene's
    /// [`scene_texture_policy`]. Giving both a size and a budget is a usage error.
    pub fn policy(&self, scene: &Scene) -> Result<SizePolicy> {
        match (self.size, self.budget) {
            (Some(_), Some(_)) => Err(Error::Usage(
                "--texture-size and --texture-budget exclude each other".into(),
            )),
            (Some(n), None) => {
                TextureSet::sides(&[0], SizePolicy::Fixed(n))?;
                Ok(SizePolicy::Fixed(n))
            }
            (None, Some(b)) => Ok(SizePolicy::Budget(b)),
            (None, None) => Ok(scene_texture_policy(scene)),
        }
    }

    /// `method` with these options' bicubic parameters applied.
    pub fn method(&self, method: Method) -> Result<Method> {
        match self.bicubic {
            Some((b, c)) => method.with_bicubic(b, c),
            None => Ok(method),
        }
    }
}

/// Parses a byte count with an optional binary suffix: `1048576`, `512K`, `4M`, `1G` (K = 1024).
pub fn parse_bytes(text: &str) -> Result<u64> {
    let t = text.trim();
    let (num, mult) = match t.char_indices().last() {
        Some((i, 'K' | 'k')) => (&t[..i], 1u64 << 10),
        Some((i, 'M' | 'm')) => (&t[..i], 1 << 20),
        Some((i, 'G' | 'g')) => (&t[..i], 1 << 30),
        _ => (t, 1),
    };
    num.parse::<u64>()
        .ok()
        .and_then(|n| n.checked_mul(mult))
        .ok_or_else(|| {
            Error::Usage(format!(
                "`{text}` is not a byte count (an integer, optionally followed by K, M or G)"
            ))
        })
}

/// Parses `B,C` (two numbers) for `--bicubic`.
pub fn parse_bicubic(text: &str) -> Result<(f32, f32)> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    match parts.as_slice() {
        [b, c] => match (b.parse::<f32>(), c.parse::<f32>()) {
            (Ok(b), Ok(c)) => Ok((b, c)),
            _ => Err(Error::Usage(format!(
                "--bicubic {text}: B and C must be numbers"
            ))),
        },
        _ => Err(Error::Usage(format!(
            "--bicubic {text}: expected B,C (Mitchell-Netravali 0.333,0.333; Catmull-Rom 0,0.5)"
        ))),
    }
}

/// The texture size policy a scene asks for: `[render] texture_size` 0 means per polygon from
/// its quadtree depth, any other value one fixed size.
pub fn scene_texture_policy(scene: &Scene) -> SizePolicy {
    match scene.render.texture_size {
        0 => SizePolicy::FromDepth,
        n => SizePolicy::Fixed(n),
    }
}

/// A scene with its solution and reconstruction: everything a frame needs.
pub struct Prepared {
    /// The scene.
    pub scene: Scene,
    /// Its radiosity solution (solved now, or read from a file).
    pub solution: Solution,
    /// The RRPs of every polygon.
    pub reconstruction: Reconstruction,
    /// Time spent solving in this run (0 when read from a file), ms.
    pub solve_ms: f64,
    /// Time spent building the RRPs, ms.
    pub reconstruction_ms: f64,
    /// How the texture methods size their textures (default: [`scene_texture_policy`]). Set it
    /// before the first texture frame: the textures are built once, on first use.
    pub texture_policy: SizePolicy,
    textures: OnceLock<(TextureSet, f64)>,
    mesh: OnceLock<(MeshModel, f64)>,
}

impl Prepared {
    /// The radiosity textures under [`Prepared::texture_policy`], built on first use (a scene
    /// rendered only with the direct method never pays for them), with their build time in ms.
    pub fn textures(&self) -> Result<(&TextureSet, f64)> {
        if self.textures.get().is_none() {
            let t = Instant::now();
            let depths = TextureSet::depths(&self.solution.polygons);
            let set = TextureSet::build(&self.reconstruction, &depths, self.texture_policy)?;
            let _ = self.textures.set((set, t.elapsed().as_secs_f64() * 1e3));
        }
        let (set, ms) = self
            .textures
            .get()
            .ok_or_else(|| Error::Runtime("texture set missing after build".into()))?;
        Ok((set, *ms))
    }

    /// The Gouraud mesh of the solution (T-vertex fans), built on first use, with its build
    /// time in ms.
    pub fn mesh(&self) -> Result<(&MeshModel, f64)> {
        if self.mesh.get().is_none() {
            let t = Instant::now();
            let mesh = MeshModel::build(&self.scene, &self.solution.polygons)?;
            let _ = self.mesh.set((mesh, t.elapsed().as_secs_f64() * 1e3));
        }
        let (mesh, ms) = self
            .mesh
            .get()
            .ok_or_else(|| Error::Runtime("mesh missing after build".into()))?;
        Ok((mesh, *ms))
    }
}

/// Whether `path` is a solution file (by its magic bytes) rather than a scene.
pub fn is_solution_file(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .map(|_| &magic == solution_file::MAGIC)
        .unwrap_or(false)
}

/// Loads a scene, or a solution file and the scene it names; solves a scene that has no
/// solution (reporting to `observer`); builds the reconstruction.
pub fn prepare(input: &Path, observer: &dyn Observer) -> Result<Prepared> {
    let (scene, solution, solve_ms) = if is_solution_file(input) {
        let scene_path = solution_file::read_scene_path(input)?;
        let scene = load_scene(&scene_path)?;
        let solution = solution_file::read_solution(input, &scene)?;
        (scene, solution, 0.0)
    } else {
        let scene = load_scene(input)?;
        let t = Instant::now();
        let solution = radiosity::solve(&scene, &SolveOptions { observer })?;
        (scene, solution, t.elapsed().as_secs_f64() * 1e3)
    };
    let t = Instant::now();
    let reconstruction = Reconstruction::build(&solution.polygons, Estimator::default())?;
    let reconstruction_ms = t.elapsed().as_secs_f64() * 1e3;
    Ok(Prepared {
        texture_policy: scene_texture_policy(&scene),
        scene,
        solution,
        reconstruction,
        solve_ms,
        reconstruction_ms,
        textures: OnceLock::new(),
        mesh: OnceLock::new(),
    })
}

/// [`prepare`], then the texture size policy `texture` chooses for the scene.
pub fn prepare_with(
    input: &Path,
    observer: &dyn Observer,
    texture: &TextureOptions,
) -> Result<Prepared> {
    let mut p = prepare(input, observer)?;
    p.texture_policy = texture.policy(&p.scene)?;
    Ok(p)
}

/// Solves `scene_path` (reporting to `observer`) and writes the solution to `out`.
pub fn solve_to_file(scene_path: &Path, out: &Path, observer: &dyn Observer) -> Result<Solution> {
    let scene = load_scene(scene_path)?;
    let solution = radiosity::solve(&scene, &SolveOptions { observer })?;
    solution_file::write_solution(out, &solution, Some(scene_path))?;
    Ok(solution)
}

/// Renders one frame of a prepared scene.
pub fn render(p: &Prepared, method: Method, camera: &Camera, opts: &FrameOptions) -> Result<Frame> {
    let mut frame = match method {
        Method::Direct => render_frame(&p.scene, camera, &p.reconstruction, opts)?,
        Method::Texture(filter) => {
            let (set, _) = p.textures()?;
            render_frame_with(&p.scene, camera, &Shader::Texture { set, filter }, opts)?
        }
        Method::Mesh => {
            let (mesh, _) = p.mesh()?;
            render_frame(&mesh.scene, camera, mesh, opts)?
        }
        Method::Reference => {
            let oracle = Oracle::new(&p.solution, &p.scene)?;
            let f = |poly: u32, u: f32, v: f32| oracle.radiosity(poly as usize, u as f64, v as f64);
            render_frame_with(&p.scene, camera, &Shader::Exact(&f), opts)?
        }
    };
    frame.stats.method = method.name().into();
    Ok(frame)
}

/// What `pixelflow-sim render` was asked to do.
#[derive(Debug, Clone, Default)]
pub struct RenderRequest {
    /// Scene file or solution file.
    pub input: PathBuf,
    /// PNG to write (default [`default_png_path`]); walkthrough frames are numbered beside it.
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
    /// Where to write the statistics JSON (an array of frames for a walkthrough).
    pub stats: Option<PathBuf>,
    /// Render every frame of the scene's camera path.
    pub walkthrough: bool,
    /// Texture sizes and the bicubic filter's parameters.
    pub texture: TextureOptions,
}

/// What a render job reports as it goes.
#[derive(Debug)]
pub enum RenderEvent<'a> {
    /// A scene warning (a non-planar quad split, ...).
    Warning(&'a str),
    /// A file was written.
    Wrote(&'a Path),
    /// A frame was rendered.
    Frame(&'a RenderReport),
}

/// Runs a render job: prepare once, render one frame or every walkthrough frame, write PNG,
/// EXR and statistics. A scene is solved reporting to `observer`.
pub fn run_render(
    req: &RenderRequest,
    observer: &dyn Observer,
    on: &mut dyn FnMut(RenderEvent<'_>),
) -> Result<()> {
    let p = prepare_with(&req.input, observer, &req.texture)?;
    let scene = &p.scene;
    for w in &scene.warnings {
        on(RenderEvent::Warning(w));
    }
    let method = req.texture.method(Method::parse(
        req.method.as_deref().unwrap_or(&scene.render.method),
    )?)?;
    let opts = FrameOptions {
        width: req.width.unwrap_or(scene.width),
        height: req.height.unwrap_or(scene.height),
        aa: req.aa.unwrap_or(scene.render.aa_samples),
        renderers: req.renderers,
        region: req.region,
        cull_back_faces: false,
    };
    opts.validate()?;
    if req.walkthrough && req.exr.is_some() {
        return Err(Error::Usage(
            "--exr writes one frame; it cannot be combined with --walkthrough".into(),
        ));
    }
    let png = req
        .output
        .clone()
        .unwrap_or_else(|| default_png_path(&req.input, method));
    let frames: Vec<(Camera, PathBuf)> = if req.walkthrough {
        let path = scene.camera_path.as_ref().ok_or_else(|| {
            Error::Usage(format!(
                "--walkthrough: {} has no [camera_path]",
                scene.source.display()
            ))
        })?;
        (0..path.frames)
            .map(|k| {
                (
                    path_camera(scene, &path.keyframes, k, path.frames),
                    walkthrough_frame_path(&png, k),
                )
            })
            .collect()
    } else {
        vec![(scene.camera, png)]
    };
    let mut reports = Vec::new();
    for (camera, png) in &frames {
        let frame = render(&p, method, camera, &opts)?;
        image_out::write_png(png, &frame, scene.display.exposure)?;
        on(RenderEvent::Wrote(png));
        if let Some(exr) = &req.exr {
            image_out::write_exr(exr, &frame)?;
            on(RenderEvent::Wrote(exr));
        }
        let report = RenderReport::new(&p, method, &frame);
        on(RenderEvent::Frame(&report));
        reports.push(report);
    }
    if let Some(path) = &req.stats {
        let json = if req.walkthrough {
            serde_json::to_string_pretty(&reports)
        } else {
            serde_json::to_string_pretty(&reports[0])
        }
        .map_err(|e| Error::Runtime(format!("statistics to JSON: {e}")))?;
        crate::output::write_atomic(path, json.as_bytes())?;
        on(RenderEvent::Wrote(path));
    }
    Ok(())
}

/// The statistics written by `--stats`: the frame's counters and stage times, plus the
/// one-off costs that are not part of `frame_ms`.
#[derive(Debug, Clone, Serialize)]
pub struct RenderReport {
    /// The frame's counters and stage times.
    #[serde(flatten)]
    pub frame: FrameStats,
    /// Solve time in this run (0 when the solution was read from a file), ms.
    pub solve_ms: f64,
    /// RRP construction time, ms.
    pub reconstruction_ms: f64,
    /// RRP patches stored.
    pub patches: u64,
    /// Radiosity samples in the solution.
    pub samples: u64,
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
}

impl RenderReport {
    /// The report of `frame` rendered from `p`.
    pub fn new(p: &Prepared, method: Method, frame: &Frame) -> RenderReport {
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
            frame: frame.stats.clone(),
            solve_ms: p.solve_ms,
            reconstruction_ms: p.reconstruction_ms,
            patches: p.reconstruction.stats().patches as u64,
            samples: p.solution.stats.vertices,
        }
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|_| "{}".into())
    }
}

/// The camera of frame `k` of `n` along the scene's camera path: keyframes evenly spaced in
/// time, Catmull-Rom interpolation of eye and look-at (so the motion is C1 through keyframes),
/// linear interpolation of up; the projection is the scene camera's.
pub fn path_camera(scene: &Scene, keyframes: &[Keyframe], k: u32, n: u32) -> Camera {
    let segs = keyframes.len().saturating_sub(1).max(1);
    let t = if n <= 1 {
        0.0
    } else {
        k as f64 / (n - 1) as f64 * segs as f64
    };
    let i = (t.floor() as usize).min(segs - 1);
    let f = t - i as f64;
    let at = |j: isize| keyframes[j.clamp(0, keyframes.len() as isize - 1) as usize];
    let (k0, k1, k2, k3) = (
        at(i as isize - 1),
        at(i as isize),
        at(i as isize + 1),
        at(i as isize + 2),
    );
    let cr = |p0: DVec3, p1: DVec3, p2: DVec3, p3: DVec3| {
        let (f2, f3) = (f * f, f * f * f);
        0.5 * ((2.0 * p1)
            + (p2 - p0) * f
            + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f2
            + (3.0 * p1 - p0 - 3.0 * p2 + p3) * f3)
    };
    let eye = cr(k0.eye, k1.eye, k2.eye, k3.eye);
    let mut look_at = cr(k0.look_at, k1.look_at, k2.look_at, k3.look_at);
    if (look_at - eye).length_squared() < 1e-18 {
        // Documented fallback: a spline that brings eye and target together keeps the keyframe
        // direction instead of producing an undefined view.
        look_at = eye + (k1.look_at - k1.eye);
    }
    let up = k1.up.lerp(k2.up, f);
    Camera {
        eye,
        look_at,
        up: if up.length_squared() > 0.0 { up } else { k1.up },
        projection: scene.camera.projection,
    }
}

/// Where output goes when the user names no file: `out/<scene stem>-<method>.png`.
pub fn default_png_path(input: &Path, method: Method) -> PathBuf {
    let stem = input
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".into());
    PathBuf::from("out").join(format!("{stem}-{}.png", method.name()))
}

/// The frame file name of walkthrough frame `k`: `<png stem>-NNNN.png` beside `png`.
pub fn walkthrough_frame_path(png: &Path, k: u32) -> PathBuf {
    let stem = png
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".into());
    png.with_file_name(format!("{stem}-{k:04}.png"))
}

/// One row of `pixelflow-sim bench`: medians over the frames rendered at one size.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    /// Method.
    pub method: String,
    /// Image width and height.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub aa: u32,
    /// Frames measured (after one warm-up frame).
    pub frames: u32,
    /// Median `frame_ms` (geometry + raster + composition + shading).
    pub frame_ms: f64,
    /// Median geometry time, ms.
    pub geometry_ms: f64,
    /// Median raster time (binning, rasterization, patch-table fill), ms.
    pub raster_ms: f64,
    /// Median compositor busy time, ms.
    pub composition_ms: f64,
    /// Median deferred-shading time, ms.
    pub shading_ms: f64,
    /// Samples shaded per frame.
    pub samples_shaded: u64,
    /// Deferred pass throughput at the median shading time, Msample/s.
    pub shading_mpix_s: f64,
    /// Frames per second at the median frame time.
    pub fps: f64,
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        xs[n / 2]
    } else {
        0.5 * (xs[n / 2 - 1] + xs[n / 2])
    }
}

/// Renders `frames` frames (after one warm-up) of the scene camera at each size and returns
/// the medians. Timing is wall-clock inside the frame's stages; the machine is whatever runs it.
pub fn bench(
    p: &Prepared,
    method: Method,
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
        render(p, method, &p.scene.camera, &opts)?;
        let mut stats = Vec::new();
        for _ in 0..frames {
            stats.push(render(p, method, &p.scene.camera, &opts)?.stats);
        }
        let med = |f: fn(&FrameStats) -> f64| median(stats.iter().map(f).collect());
        let shading_ms = med(|s| s.shading_ms);
        let frame_ms = med(|s| s.frame_ms);
        let samples = stats[0].pixels_shaded;
        rows.push(BenchRow {
            method: method.name().into(),
            width: w,
            height: h,
            aa: opts.aa,
            frames,
            frame_ms,
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
            fps: if frame_ms > 0.0 { 1e3 / frame_ms } else { 0.0 },
        });
    }
    Ok(rows)
}

/// The bench rows as a fixed-width table.
pub fn bench_table(rows: &[BenchRow]) -> String {
    let mut s = String::from(
        "method            size        aa  frame_ms    fps  geometry  raster  compos.  shading  Msample/s\n",
    );
    for r in rows {
        s += &format!(
            "{:<17} {:>4}x{:<5} {:>3} {:>9.2} {:>6.1} {:>9.2} {:>7.2} {:>8.2} {:>8.2} {:>10.0}\n",
            r.method,
            r.width,
            r.height,
            r.aa,
            r.frame_ms,
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

/// The paper's Table 1 for one scene: sizes of the original, mesh ("poly") and RAT models, the
/// RRP memory, and optionally frame rates of each method measured in one run.
#[derive(Debug, Clone, Serialize)]
pub struct ModelStats {
    /// Scene file.
    pub scene: String,
    /// Original model: triangles (2 per quad) and distinct corner positions.
    pub original: MeshStats,
    /// Mesh model: the adaptive quadtrees triangulated with T-vertex fans.
    pub mesh: MeshStats,
    /// RAT model triangles (the original triangles: textures replace the subdivision).
    pub rat_triangles: u64,
    /// RAT model vertices: corners are not shared between polygons, since each carries its own
    /// texture coordinates (4 per quad, 3 per triangle).
    pub rat_vertices: u64,
    /// RAT model geometry size: `rat_vertices` x (12 B position + 8 B texture coordinates) +
    /// `rat_triangles` x 12 B indices.
    pub rat_bytes: u64,
    /// Texture memory and texture count under the job's size policy.
    pub texture_memory: TextureMemory,
    /// RRP storage, bytes (patches + locate trees, [`crate::reconstruction::ReconstructionStats`]).
    pub rrp_bytes: u64,
    /// RRP patches.
    pub rrp_patches: u64,
    /// Radiosity samples of the solution.
    pub samples: u64,
    /// Frame times per method (medians), if frames were measured.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<BenchRow>,
}

/// Bytes per RAT vertex in [`ModelStats::rat_bytes`]: position (3 x f32) + (u, v) (2 x f32).
pub const RAT_BYTES_PER_VERTEX: u64 = 20;

/// The methods `stats --frames` measures, in the paper's Table 1 order plus the direct method.
pub const STATS_METHODS: [Method; 4] = [
    Method::Mesh,
    Method::Texture(Filter::Bilinear),
    Method::Texture(Filter::MITCHELL),
    Method::Direct,
];

/// Table 1 for a prepared scene; with `frames > 0`, each of [`STATS_METHODS`] is rendered
/// `frames` times (after a warm-up) at `opts`'s size and the medians are reported. The bicubic
/// filter is `bicubic`'s (Mitchell–Netravali unless given).
pub fn model_stats(
    p: &Prepared,
    frames: u32,
    opts: &FrameOptions,
    bicubic: Filter,
) -> Result<ModelStats> {
    let (mesh, _) = p.mesh()?;
    let (textures, _) = p.textures()?;
    let original = MeshStats::original(&p.scene);
    let (rat_triangles, rat_vertices) =
        p.scene
            .polygons
            .iter()
            .fold((0, 0), |(t, v), poly| match poly.shape {
                crate::scene::Shape::Triangle => (t + 1, v + 3),
                crate::scene::Shape::Quad => (t + 2, v + 4),
            });
    let rs = p.reconstruction.stats();
    let mut rows = Vec::new();
    if frames > 0 {
        for m in STATS_METHODS {
            let m = match m {
                Method::Texture(Filter::Bicubic { .. }) => Method::Texture(bicubic),
                m => m,
            };
            rows.extend(bench(p, m, &[(opts.width, opts.height)], frames, opts)?);
        }
    }
    Ok(ModelStats {
        scene: p.scene.source.display().to_string(),
        original,
        mesh: mesh.stats,
        rat_triangles,
        rat_vertices,
        rat_bytes: rat_vertices * RAT_BYTES_PER_VERTEX + rat_triangles * 12,
        texture_memory: textures.memory,
        rrp_bytes: rs.bytes as u64,
        rrp_patches: rs.patches as u64,
        samples: p.solution.stats.vertices,
        frames: rows,
    })
}
