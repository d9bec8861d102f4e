//! The sweep job: speed against error. For one scene it varies what decides a method's cost and
//! error — the solution's sampling density (the solver's subdivision tolerance), and for the
//! texture methods the texture size — and measures, for every method at every point, at one image
//! size:
//!
//! - the warm frame time: each point's median of several frames after a warm-up, all points of
//!   one density interleaved, measured in several separate processes ([`crate::timing`]; or in
//!   repeats within this one), summarized by the median over them and a confidence interval of
//!   that median, with the machine's load while each process ran;
//! - the bytes of the representation that method must store (the RRPs' trees and samples, from
//!   which they are built; 12-bit textures with mip chains; the mesh's vertices and indices);
//! - the error against two references, each as perceptual distance, RMSE, maximum error and the
//!   Mach-band measure (`docs/metrics.md`): **reconstruction error**, against the same solution's
//!   exact value at every pixel (the `reference` method: it isolates the method), and **total
//!   error**, against a converged finer solution's exact value (the solver's own convergence);
//! - with a truth image ([`SweepRequest::truth_samples`]), the **error budget against physics**
//!   ([`crate::physics`]): each method's image against the independent path tracer's (**physics
//!   error**), each solution's exact image against it (**solution error**), and the tracer's own
//!   noise, taken out of both in quadrature. Physics error is what a user sees; it splits into
//!   the solution error (what the solver got wrong) and the reconstruction error (what the method
//!   added). Every such figure carries the jackknife replicates of its 95 % interval from the
//!   truth's independent parts, and the scene's own density is solved again with the next solver
//!   seed, so that a difference the pages call is one neither the truth's noise nor the solver's
//!   seed could make.
//!
//! Each point is flagged if it is on the Pareto front of total error against frame time, and of
//! total error against bytes, over all points of the sweep. A point leaves the time front only
//! when another is at most as wrong and faster beyond doubt: its interval wholly below.
//!
//! Invariants: every option is checked before the first solve; each density is solved once; the
//! errors and bytes are deterministic (only the times vary between runs).

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

mod report;

pub use report::{
    csv, table, Errors, RegionSplit, SeedCheck, SolutionLevel, SweepPoint, SweepReport,
    TextureLevel, Timing,
};

use crate::equal_error::{self, EqualError};
use crate::equal_views::{self, ViewCurve};
use crate::physics::{self, PhysicsErrors, TruthNoise, TruthReference};
use crate::timing::{self, LoadSample, TimingProcesses, CONFIDENCE};
use app::context::Context;
use app::context::Input;
use app::frames::frame_image;
use app::frames::render_frame_in;
use app::frames::render_frame_observed;
use app::memory;
use app::prepare::prepare;
use app::prepare::Prepared;
use app::rates::median;
use base::error::{Error, Result};
use base::method::{Method, Placement};
use base::progress::Labelled;
use base::quadtree::MAX_DEPTH;
use engine::frame::{FrameContext, FrameOptions, FrameStats};
use engine::shading::Shader;
use imageio::LinearImage;
use metric::regions::{RegionError, Regions, REGIONS};
use metric::{compare, Comparison, DEFAULT_PPD};
use reconstruction::texture::{SizePolicy, TextureMemory, TextureSet, GUTTER};
use scene::{Scene, MAX_IMAGE_DIM};

/// The methods a sweep measures when none are named.
pub const DEFAULT_METHODS: [&str; 5] = [
    "direct",
    "texture-nearest",
    "texture-bilinear",
    "texture-bicubic",
    "mesh",
];

/// Default tolerance factors of the density levels, coarse to fine.
pub const DEFAULT_DENSITIES: [f64; 4] = [4.0, 2.0, 1.0, 0.5];

/// What `pixelflow-sim sweep` was asked to do.
#[derive(Debug, Clone)]
pub struct SweepRequest {
    /// Scene file or solution file (a solution file's scene is solved again at each density).
    pub input: PathBuf,
    /// Method names (`reference` is the error reference, not a swept method).
    pub methods: Vec<String>,
    /// Image width and height.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Density levels: factors of the scene's `[radiosity] tolerance`, coarse to fine.
    pub densities: Vec<f64>,
    /// The converged reference's tolerance factor (its `max_depth` is one more than the scene's).
    pub reference_density: f64,
    /// Texture sizes per density: the quadtree-depth sizes halved 0, 1, ... levels - 1 times.
    pub texture_levels: u32,
    /// Frames timed per point and repeat (after one warm-up frame).
    pub frames: u32,
    /// Repeats of the timing within each process.
    pub repeats: u32,
    /// Separate processes each timing point is measured in ([`crate::timing`]); `None`: the
    /// repeats of this process alone (their spread is not a confidence interval of the time
    /// another run would measure).
    pub processes: Option<TimingProcesses>,
    /// Pixels per degree of the perceptual metric.
    pub ppd: f64,
    /// Also search the texture memory each texture method needs to reach the direct method's
    /// error ([`crate::equal_error`]), at the density level whose factor is nearest 1.
    pub equal_error: bool,
    /// Camera samples per pixel of the path-traced truth image the error budget is measured
    /// against ([`crate::physics`]); 0: no truth image, no budget.
    pub truth_samples: u32,
    /// How many levels below the solver's leaves every method (the RRPs, and so the textures;
    /// the mesh's vertices) follows the edges of the spot lights' light (`--sharp-levels`;
    /// `None`: the default, [`reconstruction::sharp::DEFAULT_LEVELS`]; 0: every method draws
    /// the spots' light from the solver's samples).
    pub sharp_levels: Option<u32>,
}

/// Samples per pixel of a sweep's truth image by default: its noise is then well under the
/// solution error it is measured against (`docs/sweep.md`).
pub const DEFAULT_TRUTH_SAMPLES: u32 = 1024;

impl SweepRequest {
    /// A request with the defaults: every method, 256 x 256, four densities, four texture sizes,
    /// 5 frames x 3 repeats, a truth image of [`DEFAULT_TRUTH_SAMPLES`].
    pub fn new(input: PathBuf) -> SweepRequest {
        SweepRequest {
            input,
            methods: DEFAULT_METHODS.iter().map(|s| s.to_string()).collect(),
            width: 256,
            height: 256,
            densities: DEFAULT_DENSITIES.to_vec(),
            reference_density: 0.25,
            texture_levels: 4,
            frames: 5,
            repeats: 3,
            processes: None,
            ppd: DEFAULT_PPD,
            equal_error: true,
            truth_samples: DEFAULT_TRUTH_SAMPLES,
            sharp_levels: None,
        }
    }
}

/// The Pareto flags of points `(cost, error)`: a point is on the front when no other point is at
/// most as costly and at most as wrong, and strictly better in one of the two. Ties (equal cost
/// and error) are all on the front.
pub(crate) fn pareto_front(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&(c, e)| {
            !points
                .iter()
                .any(|&(c2, e2)| c2 <= c && e2 <= e && (c2 < c || e2 < e))
        })
        .collect()
}

/// One candidate's image measured against each reference.
struct Measured {
    recon: Comparison,
    total: Comparison,
    physics: Option<PhysicsErrors>,
    regions: RegionSplit,
}

/// Which pixels of `p`'s view at `opts` show an emitting polygon: a frame whose shader is 1 on
/// every emitter and 0 elsewhere, a pixel counting when any of its samples shows one.
fn emitter_pixels(p: &Prepared, opts: &FrameOptions) -> Result<Vec<bool>> {
    let emits: Vec<bool> = (0..p.scene.polygons.len())
        .map(|i| p.scene.material_of(i).is_emitter())
        .collect();
    let f = |poly: u32, _: f32, _: f32| {
        if emits.get(poly as usize).copied().unwrap_or(false) {
            glam::Vec3::ONE
        } else {
            glam::Vec3::ZERO
        }
    };
    let mut ctx = FrameContext::new();
    let stats = ctx.render(
        &p.scene,
        &p.scene.camera,
        &Shader::Reference(&f),
        Method::Reference,
        opts,
    )?;
    Ok(ctx
        .into_frame(stats)
        .pixels
        .iter()
        .map(|c| c.x > 0.0)
        .collect())
}

/// One method at one texture size, at one density.
struct Candidate<'a> {
    method: Method,
    texture: Option<(TextureLevel, &'a TextureSet)>,
}

/// Checks every option of `req` (what [`run_sweep`] does before its first solve).
pub(crate) fn check_request(req: &SweepRequest) -> Result<()> {
    check(req).map(|_| ())
}

fn check(req: &SweepRequest) -> Result<Vec<Method>> {
    let methods = req
        .methods
        .iter()
        .map(|m| Method::parse(m))
        .collect::<Result<Vec<_>>>()?;
    if methods.is_empty() {
        return Err(Error::invalid_option("methods", "", "names no method"));
    }
    if let Some(m) = methods.iter().find(|m| **m == Method::Reference) {
        return Err(Error::invalid_option(
            "methods",
            m.name(),
            "is the sweep's error reference, not a swept method",
        ));
    }
    for (name, v) in [("size", req.width), ("size", req.height)] {
        if v == 0 {
            return Err(Error::invalid_option(name, "0", "must be at least 1"));
        }
        if v > MAX_IMAGE_DIM {
            return Err(Error::limit(name, v.into(), MAX_IMAGE_DIM.into()));
        }
    }
    if req.densities.is_empty() {
        return Err(Error::invalid_option("densities", "", "names no level"));
    }
    for &d in req.densities.iter().chain([&req.reference_density]) {
        if !(d.is_finite() && d > 0.0) {
            return Err(Error::invalid_option(
                "densities",
                d.to_string(),
                "tolerance factors must be finite and > 0",
            ));
        }
    }
    for (name, v) in [
        ("texture-levels", req.texture_levels),
        ("frames", req.frames),
        ("repeats", req.repeats),
    ] {
        if v == 0 {
            return Err(Error::invalid_option(name, "0", "must be at least 1"));
        }
    }
    if req.processes.as_ref().is_some_and(|t| t.count == 0) {
        return Err(Error::invalid_option(
            "processes",
            "0",
            "names no timing process (leave them out to time in this process)",
        ));
    }
    if req.texture_levels > 12 {
        return Err(Error::limit(
            "texture-levels",
            req.texture_levels.into(),
            12,
        ));
    }
    if req.truth_samples > truth::MAX_SAMPLES_PER_PIXEL {
        return Err(Error::limit(
            "truth-samples",
            req.truth_samples.into(),
            truth::MAX_SAMPLES_PER_PIXEL.into(),
        ));
    }
    if !(req.ppd.is_finite() && req.ppd > 0.0) {
        return Err(Error::invalid_option(
            "ppd",
            req.ppd.to_string(),
            "must be finite and > 0",
        ));
    }
    Ok(methods)
}

/// The quadtree depth shift of density `factor`: `-round(log2 factor)` (factor 4: two levels
/// shallower, 1/2: one deeper).
pub fn depth_shift(factor: f64) -> i32 {
    (-factor.log2()).round() as i32
}

/// `scene` at density `factor`: its tolerance scaled by `factor` and its `max_depth` moved by
/// [`depth_shift`] (kept within `1..=MAX_DEPTH`); a coarser density (shift < 0) also lowers
/// `min_depth` by the same shift (down to 0), a finer one keeps it. All move together because
/// where the light is sharp the depth limit, not the tolerance, stops the subdivision, and on a
/// scene of many small polygons the minimum depth, not the tolerance, sets the sample count of
/// the coarse levels: scaling the tolerance alone left the error of such scenes where it was.
pub fn at_density(scene: &Scene, factor: f64) -> Scene {
    let mut s = scene.clone();
    let shift = depth_shift(factor) as i64;
    s.radiosity.tolerance *= factor;
    if shift < 0 {
        s.radiosity.min_depth = (s.radiosity.min_depth as i64 + shift).max(0) as u32;
    }
    let depth = s.radiosity.max_depth as i64 + shift;
    s.radiosity.max_depth =
        depth.clamp(s.radiosity.min_depth.max(1) as i64, MAX_DEPTH as i64) as u32;
    s
}

fn solve_at(ctx: &Context<'_>, input: &Input, scene: Scene) -> Result<Prepared> {
    let input = Input {
        path: input.path.clone(),
        scene,
        solution_file: None,
        estimator: input.estimator,
        sharp_levels: input.sharp_levels,
        input_limit: input.input_limit,
    };
    prepare(ctx, input, SizePolicy::FromDepth, Placement::Centre)
}

/// Runs a sweep: check every option, solve the converged reference and each density once, and
/// measure every method (and texture size) at each density.
pub fn run_sweep(job: &Context<'_>, req: &SweepRequest) -> Result<SweepReport> {
    let sweep = Sweep::new(job, req)?;
    let truth = match req.truth_samples {
        0 => None,
        n => Some(physics::trace(
            job,
            &sweep.input.scene,
            &sweep.opts,
            n,
            req.ppd,
        )?),
    };
    let (total_ref, reference, regions) = sweep.converged_reference(truth.as_ref())?;
    // The equal-error search runs at the scene's own density (the factor nearest 1).
    let own = nearest_one(&req.densities);
    let mut equal = None;
    let mut views = Vec::new();
    let mut points = Vec::new();
    let mut densities = Vec::new();
    let mut load = Vec::new();
    let mut seed = None;
    let n = req.densities.len();
    for (level, &factor) in req.densities.iter().enumerate() {
        // Every stage of this density says which of the sweep's densities it belongs to.
        let label = Labelled::new(job.observer, format!("density {}/{n}", level + 1));
        let ctx = job.with_observer(&label);
        let p = solve_at(&ctx, &sweep.input, at_density(&sweep.input.scene, factor))?;
        let at = AtDensity {
            drawer: Drawer {
                sweep: &sweep,
                p: &p,
            },
            level,
            recon_ref: frame_image(render_frame_observed(
                &p,
                Method::Reference,
                &p.scene.camera,
                &sweep.opts,
                &label,
            )?)?,
        };
        densities.push(SolutionLevel::of(
            &p,
            &at.recon_ref,
            (truth.as_ref(), &regions),
            Some(&total_ref),
            req.ppd,
        )?);
        points.extend(at.measure(&total_ref, (truth.as_ref(), &regions), &mut load)?);
        if truth.is_some() && level == own {
            seed = Some(sweep.seed_check(factor, &at.recon_ref, truth.as_ref())?);
        }
        if req.equal_error && level == own {
            equal = at.equal_error()?;
            views = at.equal_views()?;
        }
    }
    mark_fronts(&mut points);
    Ok(SweepReport {
        scene: sweep.input.scene.source.display().to_string(),
        width: req.width,
        height: req.height,
        threads: rayon::current_num_threads(),
        sharp_levels: sweep.input.sharp_levels,
        densities,
        reference,
        truth: truth.map(|t| t.noise),
        solver_seed: seed,
        points,
        equal_error: equal,
        timing: sweep.timing(load),
        own_density: own,
        equal_views: views,
    })
}

/// The index of the factor nearest 1 (on a log scale), the first of equals; 0 for none.
fn nearest_one(densities: &[f64]) -> usize {
    (0..densities.len())
        .min_by(|&a, &b| {
            let d = |i: usize| densities[i].ln().abs();
            d(a).total_cmp(&d(b))
        })
        .unwrap_or(0)
}

/// The time-front flags of points `(interval, error)`: a point is on the front unless another
/// is at most as wrong and faster beyond doubt (its interval wholly below this one's), so a
/// claim that one method is faster is only made where the intervals do not overlap.
pub(crate) fn interval_front(points: &[([f64; 2], f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&([lo, _], e)| !points.iter().any(|&([_, hi2], e2)| e2 <= e && hi2 < lo))
        .collect()
}

/// Flags every point on the front of total error against frame time ([`interval_front`]), and
/// on the Pareto front of total error against bytes.
fn mark_fronts(points: &mut [SweepPoint]) {
    let by_time: Vec<([f64; 2], f64)> = points
        .iter()
        .map(|p| (p.frame_ms_interval, p.error_total))
        .collect();
    let by_bytes: Vec<(f64, f64)> = points
        .iter()
        .map(|p| (p.bytes as f64, p.error_total))
        .collect();
    for ((p, t), m) in points
        .iter_mut()
        .zip(interval_front(&by_time))
        .zip(pareto_front(&by_bytes))
    {
        p.pareto_time = t;
        p.pareto_memory = m;
    }
}

/// A sweep whose options are checked: its request, methods, input and frame options.
struct Sweep<'a> {
    job: &'a Context<'a>,
    req: &'a SweepRequest,
    methods: Vec<Method>,
    input: Input,
    opts: FrameOptions,
}

impl<'a> Sweep<'a> {
    /// Checks every option of `req`, loads its input and checks the frames against the memory
    /// limit: everything before the first solve.
    fn new(job: &'a Context<'a>, req: &'a SweepRequest) -> Result<Sweep<'a>> {
        let methods = check(req)?;
        let mut input = Input::load(&req.input)?;
        if let Some(levels) = req.sharp_levels {
            input.sharp_levels = app::commands::render::check_sharp_levels(levels)?;
        }
        let opts = job.frame_options(req.width, req.height);
        opts.validate()?;
        app::budget::check_frame_options(&opts, (false, false), job.memory_limit)?;
        Ok(Sweep {
            job,
            req,
            methods,
            input,
            opts,
        })
    }

    /// The summary of how the frame times were measured, with the load of every process.
    fn timing(&self, load: Vec<LoadSample>) -> Timing {
        let (processes, samples) = match &self.req.processes {
            Some(tp) => (tp.count, tp.count),
            None => (0, self.req.repeats),
        };
        Timing {
            processes,
            samples,
            coverage: timing::order_statistic(samples.max(1) as usize, CONFIDENCE).1,
            load,
        }
    }

    /// The converged solution's exact image (the total error's reference), its level (its
    /// exact image against `truth`) and the regions every point's error is split by (from that
    /// image and the pixels showing an emitter); the solution itself is dropped before the
    /// densities are solved.
    fn converged_reference(
        &self,
        truth: Option<&TruthReference>,
    ) -> Result<(LinearImage, SolutionLevel, Regions)> {
        let scene = at_density(&self.input.scene, self.req.reference_density);
        let (fine, exact) = self.solve_exact(scene, "converged reference")?;
        let (w, h) = (exact.width as usize, exact.height as usize);
        let emitters = emitter_pixels(&fine, &self.opts)?;
        let regions = Regions::classify(&emitters, &exact.luminance(), w, h);
        let level = SolutionLevel::of(&fine, &exact, (truth, &regions), None, self.req.ppd)?;
        Ok((exact, level, regions))
    }

    /// `scene` solved, and its exact image (the `reference` method), the progress labelled
    /// `what`.
    fn solve_exact(&self, scene: Scene, what: &str) -> Result<(Prepared, LinearImage)> {
        let label = Labelled::new(self.job.observer, what);
        let p = solve_at(&self.job.with_observer(&label), &self.input, scene)?;
        let exact = frame_image(render_frame_observed(
            &p,
            Method::Reference,
            &p.scene.camera,
            &self.opts,
            &label,
        )?)?;
        Ok((p, exact))
    }

    /// The solution at density `factor` solved again with the next solver seed, its exact image
    /// against that of the scene's seed (`exact`) and against `truth`.
    fn seed_check(
        &self,
        factor: f64,
        exact: &LinearImage,
        truth: Option<&TruthReference>,
    ) -> Result<SeedCheck> {
        let mut scene = at_density(&self.input.scene, factor);
        let first = scene.radiosity.seed;
        scene.radiosity.seed = first.wrapping_add(1);
        let (p, img) = self.solve_exact(scene, "another solver seed")?;
        Ok(SeedCheck {
            seeds: [first, p.scene.radiosity.seed],
            rays: p.solution.stats.rays_cast,
            same_image: img.pixels == exact.pixels,
            distance: compare(&img, exact, self.req.ppd)?.perceptual_distance,
            solution: truth.map(|t| t.errors(&img, self.req.ppd)).transpose()?,
        })
    }
}

/// One density level of a sweep: its solution (drawn by `drawer`) and that solution's exact
/// image (the reconstruction error's reference).
struct AtDensity<'a> {
    drawer: Drawer<'a>,
    level: usize,
    recon_ref: LinearImage,
}

/// What a timing worker is asked: the sweep's drawing options and one density's solution, in a
/// file. It draws the same candidates as the sweep measures, in the same order.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WorkerRequest {
    /// The scene file.
    pub scene: PathBuf,
    /// The density's tolerance factor ([`at_density`]).
    pub density: f64,
    /// The density's solution file.
    pub solution: PathBuf,
    /// Method names.
    pub methods: Vec<String>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Texture sizes ([`SweepRequest::texture_levels`]).
    pub texture_levels: u32,
    /// Frames per candidate and repeat.
    pub frames: u32,
    /// Repeats.
    pub repeats: u32,
    /// The sweep's sharp levels ([`SweepRequest::sharp_levels`]).
    pub sharp_levels: u32,
    /// Worker threads (the parent's).
    pub threads: usize,
}

impl timing::WorkerTask for WorkerRequest {
    const JOB: &'static str = "sweep";

    fn threads(&self) -> usize {
        self.threads
    }

    fn times(&self, job: &Context<'_>) -> Result<Vec<Vec<f64>>> {
        worker_times(job, self)
    }
}

/// A timing worker's sweep job: loads the solution a sweep wrote and times every candidate as
/// the sweep would; per candidate, the median frame time of each repeat.
fn worker_times(job: &Context<'_>, w: &WorkerRequest) -> Result<Vec<Vec<f64>>> {
    let req = SweepRequest {
        methods: w.methods.clone(),
        width: w.width,
        height: w.height,
        densities: vec![w.density],
        texture_levels: w.texture_levels,
        frames: w.frames,
        repeats: w.repeats,
        truth_samples: 0,
        equal_error: false,
        sharp_levels: Some(w.sharp_levels),
        ..SweepRequest::new(w.scene.clone())
    };
    let sweep = Sweep::new(job, &req)?;
    let input = Input {
        scene: at_density(&sweep.input.scene, w.density),
        solution_file: Some(w.solution.clone()),
        ..sweep.input.clone()
    };
    let p = prepare(job, input, SizePolicy::FromDepth, Placement::Centre)?;
    let drawer = Drawer {
        sweep: &sweep,
        p: &p,
    };
    let sets = drawer.texture_sets()?;
    let candidates = candidates(&sweep.methods, &sets);
    for c in &candidates {
        drawer.image(c)?; // warm-up, as the parent's error measurement is
    }
    drawer.times(&candidates)
}

impl AtDensity<'_> {
    /// Every candidate's point: errors against both references and the truth (deterministic,
    /// drawing each once, which also warms it up), then the times (of this process, or of
    /// workers, adding their load to `load`), then the bytes.
    fn measure(
        &self,
        total_ref: &LinearImage,
        (truth, regions): (Option<&TruthReference>, &Regions),
        load: &mut Vec<LoadSample>,
    ) -> Result<Vec<SweepPoint>> {
        let sets = self.drawer.texture_sets()?;
        let candidates = candidates(&self.drawer.sweep.methods, &sets);
        let ppd = self.drawer.sweep.req.ppd;
        let exact_y = self.recon_ref.luminance();
        let mut errors = Vec::new();
        for c in &candidates {
            let img = self.drawer.image(c)?;
            errors.push(Measured {
                recon: compare(&img, &self.recon_ref, ppd)?,
                total: compare(&img, total_ref, ppd)?,
                physics: truth.map(|t| t.errors(&img, ppd)).transpose()?,
                regions: RegionSplit {
                    reconstruction: metric::regions::split(&img.luminance(), &exact_y, regions),
                    physics: truth.map(|t| t.region_errors(&img, regions)).transpose()?,
                },
            });
        }
        let samples = self.time(&candidates, load)?;
        candidates
            .iter()
            .zip(&errors)
            .zip(samples)
            .map(|((c, errors), samples)| self.point(c, errors, samples))
            .collect()
    }

    /// Each candidate's frame-time samples: its per-repeat medians in this process, or each
    /// worker's median (the solution written to a temporary file for them, removed after).
    fn time(
        &self,
        candidates: &[Candidate<'_>],
        load: &mut Vec<LoadSample>,
    ) -> Result<Vec<Vec<f64>>> {
        let (s, p) = (self.drawer.sweep, self.drawer.p);
        let Some(tp) = &s.req.processes else {
            return self.drawer.times(candidates);
        };
        let what = format!("density {}", self.level);
        let (samples, l) = timing::with_solution_file(p, &what.replace(' ', "-"), |file| {
            let request = WorkerRequest {
                scene: s.input.scene.source.clone(),
                density: s.req.densities[self.level],
                solution: file.to_path_buf(),
                methods: s.req.methods.clone(),
                width: s.req.width,
                height: s.req.height,
                texture_levels: s.req.texture_levels,
                frames: s.req.frames,
                repeats: s.req.repeats,
                sharp_levels: s.input.sharp_levels,
                threads: rayon::current_num_threads(),
            };
            timing::in_processes(tp, &request, candidates.len(), &what, s.job.observer)
        })?;
        load.extend(l);
        Ok(samples)
    }

    /// The point of `c` from its errors (against the same solution's and the converged exact
    /// image, and the truth) and its frame-time samples; on no front yet.
    fn point(&self, c: &Candidate<'_>, m: &Measured, samples: Vec<f64>) -> Result<SweepPoint> {
        let (rc, tc) = (&m.recon, &m.total);
        let p = self.drawer.p;
        let bytes = match (c.method, c.texture) {
            (_, Some((level, _))) => level.bytes,
            (Method::Mesh, _) => p.mesh()?.0.stats.bytes,
            _ => memory::rrp_stored_bytes(p),
        };
        let working_bytes =
            memory::working_bytes(p, c.method, c.texture.map(|(_, set)| &set.memory))?;
        let interval =
            timing::median_interval(&samples, CONFIDENCE).map_or([0.0; 2], |i| [i.lo, i.hi]);
        let (triangles, vertices) = match c.method {
            Method::Mesh => {
                let stats = p.mesh()?.0.stats;
                (stats.triangles, stats.vertices)
            }
            _ => app::commands::stats::rat_geometry(&p.scene),
        };
        Ok(SweepPoint {
            method: c.method.name().to_string(),
            density: self.level,
            tolerance: p.scene.radiosity.tolerance,
            samples: p.solution.stats.vertices,
            texture: c.texture.map(|(l, _)| l),
            frame_ms_interval: interval,
            frame_ms: median(samples),
            triangles,
            vertices,
            bytes,
            working_bytes,
            error_reconstruction: rc.perceptual_distance,
            error_total: tc.perceptual_distance,
            reconstruction: Errors::from(rc),
            total: Errors::from(tc),
            error_physics: m.physics.map(|e| e.perceptual),
            physics: m.physics,
            regions: m.regions,
            pareto_time: false,
            pareto_memory: false,
        })
    }

    /// The texture methods' equal-error curves across views, at the sweep's size and twice it.
    fn equal_views(&self) -> Result<Vec<ViewCurve>> {
        let s = self.drawer.sweep;
        let (w, h) = (s.req.width, s.req.height);
        let mut sizes = vec![(w, h)];
        if 2 * w.max(h) <= MAX_IMAGE_DIM {
            sizes.push((2 * w, 2 * h));
        }
        equal_views::across_views(
            self.drawer.p,
            &s.methods,
            &sizes,
            &s.opts,
            s.req.ppd,
            s.job.observer,
        )
    }

    /// The equal-error memory search at this density.
    fn equal_error(&self) -> Result<Option<EqualError>> {
        let s = self.drawer.sweep;
        equal_error::equal_error(
            self.drawer.p,
            self.level,
            &s.methods,
            &self.recon_ref,
            &s.opts,
            s.req.ppd,
            s.job.observer,
        )
    }
}

/// Draws one density's candidates: the sweep's options and the density's prepared solution.
struct Drawer<'a> {
    sweep: &'a Sweep<'a>,
    p: &'a Prepared,
}

impl Drawer<'_> {
    /// Texture sets: for each placement, the quadtree-depth sides halved k times (a budget
    /// equal to that memory selects exactly that scale); none without a texture method.
    fn texture_sets(&self) -> Result<Vec<(TextureLevel, TextureSet)>> {
        let p = self.p;
        let extents = p.texture_extents()?;
        let full = TextureSet::sizes(&extents, SizePolicy::FromDepth)?;
        let mut sets = Vec::new();
        if !self
            .sweep
            .methods
            .iter()
            .any(|m| matches!(m, Method::Texture(_)))
        {
            return Ok(sets);
        }
        for placement in [Placement::Centre, Placement::Corner] {
            for k in 0..self.sweep.req.texture_levels {
                let sizes: Vec<(u32, u32)> = full
                    .iter()
                    .map(|&(w, h)| ((w >> k).max(1), (h >> k).max(1)))
                    .collect();
                let mem = TextureMemory::of_sizes(&sizes, GUTTER);
                let set = TextureSet::build(
                    p.expanded()?.0,
                    &extents,
                    SizePolicy::Budget(memory::texture_bytes(&mem)),
                    placement,
                )?;
                let level = TextureLevel {
                    halvings: k,
                    placement: placement.name(),
                    texels: set.memory.texels,
                    bytes: memory::texture_bytes(&set.memory),
                };
                sets.push((level, set));
            }
        }
        Ok(sets)
    }

    /// One frame of `c` in `ctx`.
    fn draw_in(&self, ctx: &mut FrameContext, c: &Candidate<'_>) -> Result<FrameStats> {
        let (p, opts) = (self.p, &self.sweep.opts);
        match (c.method, c.texture) {
            (Method::Texture(filter), Some((_, set))) => ctx.render(
                &p.scene,
                &p.scene.camera,
                &Shader::Texture {
                    set,
                    filter,
                    anisotropy: 1,
                },
                c.method,
                opts,
            ),
            _ => render_frame_in(ctx, p, c.method, &p.scene.camera, opts),
        }
    }

    /// The image of `c`, drawn in a frame context of its own.
    fn image(&self, c: &Candidate<'_>) -> Result<LinearImage> {
        let mut ctx = FrameContext::new();
        let stats = self.draw_in(&mut ctx, c)?;
        frame_image(ctx.into_frame(stats))
    }

    /// Each candidate's median frame time per repeat: every candidate once per repeat,
    /// interleaved, `frames` frames each, all in one frame context.
    fn times(&self, candidates: &[Candidate<'_>]) -> Result<Vec<Vec<f64>>> {
        let req = self.sweep.req;
        let mut per_repeat = vec![Vec::new(); candidates.len()];
        let mut ctx = FrameContext::new();
        for _ in 0..req.repeats {
            for (i, c) in candidates.iter().enumerate() {
                let mut ms = Vec::new();
                for _ in 0..req.frames {
                    ms.push(self.draw_in(&mut ctx, c)?.frame_ms);
                }
                per_repeat[i].push(median(ms));
            }
        }
        Ok(per_repeat)
    }
}

/// Every method of `methods` at one density: a texture method once per texture set, any other
/// once.
fn candidates<'s>(
    methods: &[Method],
    sets: &'s [(TextureLevel, TextureSet)],
) -> Vec<Candidate<'s>> {
    let mut candidates = Vec::new();
    for &m in methods {
        match m {
            Method::Texture(_) => {
                for (level, set) in sets {
                    candidates.push(Candidate {
                        method: m,
                        texture: Some((*level, set)),
                    });
                }
            }
            _ => candidates.push(Candidate {
                method: m,
                texture: None,
            }),
        }
    }
    candidates
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn densities_move_the_depth_limit_with_the_tolerance() {
        assert_eq!(
            [4.0, 2.0, 1.0, 0.5, 0.25].map(depth_shift),
            [-2, -1, 0, 1, 2]
        );
        // Factors between powers of two round to the nearest level (log2 3 = 1.58).
        assert_eq!([3.0, 1.3, 0.7].map(depth_shift), [-2, 0, 1]);
        let mut scene = scene::Scene::new(
            fixtures::closed_form::camera(),
            8,
            8,
            Vec::new(),
            Vec::new(),
        );
        scene.radiosity.tolerance = 0.01;
        scene.radiosity.min_depth = 2;
        scene.radiosity.max_depth = 7;
        let at = |f: f64| {
            let s = at_density(&scene, f);
            (
                s.radiosity.tolerance,
                s.radiosity.min_depth,
                s.radiosity.max_depth,
            )
        };
        // Coarser: both depths one level up per halving of the density; finer: the minimum kept.
        assert_eq!(at(2.0), (0.02, 1, 6));
        assert_eq!(at(4.0), (0.04, 0, 5));
        assert_eq!(at(0.25), (0.0025, 2, 9));
        // The minimum stops at 0, the limit at 1 below and the quadtree's limit above.
        assert_eq!(at(1024.0), (10.24, 0, 1));
        assert_eq!(at(1.0 / 1024.0).2, MAX_DEPTH);
    }

    #[test]
    fn pareto_front_by_hand() {
        // (cost, error): b dominates d; a and c trade; e ties a exactly.
        let pts = [(1.0, 5.0), (2.0, 2.0), (4.0, 1.0), (3.0, 3.0), (1.0, 5.0)];
        assert_eq!(pareto_front(&pts), [true, true, true, false, true]);
        assert_eq!(pareto_front(&[]), Vec::<bool>::new());
        // Equal cost, larger error: dominated.
        assert_eq!(pareto_front(&[(1.0, 1.0), (1.0, 2.0)]), [true, false]);
    }

    #[test]
    fn the_time_front_needs_intervals_apart() {
        // a: fast and wrong; b: overlaps c and is as wrong, so c stays; d: as wrong as b and
        // wholly slower than b, so it leaves; e: the most accurate, slow, stays.
        let pts = [
            ([1.0, 2.0], 5.0),
            ([3.0, 5.0], 2.0),
            ([4.0, 6.0], 2.0),
            ([5.5, 7.0], 2.0),
            ([9.0, 9.5], 1.0),
        ];
        assert_eq!(interval_front(&pts), [true, true, true, false, true]);
        // Points with zero-width intervals follow the plain Pareto rule, ties kept.
        let plain = [([1.0, 1.0], 1.0), ([1.0, 1.0], 1.0), ([2.0, 2.0], 1.0)];
        assert_eq!(interval_front(&plain), [true, true, false]);
    }

    #[test]
    fn bad_options_are_refused() {
        let base = SweepRequest::new(PathBuf::from("none.toml"));
        type Edit = fn(&mut SweepRequest);
        let cases: [(&str, Edit); 7] = [
            ("method", |r| r.methods = vec!["phong".into()]),
            ("methods", |r| r.methods = vec!["reference".into()]),
            ("methods", |r| r.methods.clear()),
            ("size", |r| r.width = 0),
            ("densities", |r| r.densities = vec![1.0, -2.0]),
            ("frames", |r| r.frames = 0),
            ("texture-levels", |r| r.texture_levels = 40),
        ];
        for (option, edit) in cases {
            let mut r = base.clone();
            edit(&mut r);
            match check(&r).unwrap_err() {
                Error::InvalidOption { option: o, .. } | Error::ResourceLimit { what: o, .. } => {
                    assert_eq!(o, option)
                }
                e => panic!("{e:?}"),
            }
        }
    }
}
