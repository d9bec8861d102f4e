//! The truth job: the independent path tracer ([`truth`]) on a scene, to files. The image of B
//! (what `render --exr` writes) and its per-pixel standard errors go to two OpenEXR files, the
//! per-polygon estimates (mean B, direct and indirect parts, standard errors, with each
//! polygon's object, material and area) to a JSON file; the three are replaced together or not
//! at all.
//!
//! With [`TruthRequest::compare_solver`] the job also solves the scene (or reads the solution
//! file given as input) and reports, beside every polygon's truth, the solver's mean over the
//! polygon as it is rendered (the expanded RRPs, integrated by the midpoint rule on a
//! [`SOLVER_QUADRATURE`]^2 grid in (u, v) weighted by the area element), the ratio of the two and
//! the difference in truth standard errors: the per-face measure of the solver's error.
//!
//! [`TruthPlan::new`] resolves and checks every option (sizes, samples, `--aa`, the error
//! target, output paths against the inputs, the memory estimate) before any sampling starts.
//! The files hold only what the seed determines, no timing, so the same request writes the same
//! bytes for any thread count; the run times come back in [`TruthOutcome`].

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec3, Vec3};
use serde::Serialize;

use crate::context::Context;
use base::error::{Error, Result};
use base::image::LinearImage;
use base::method::Aa;
use scene::Scene;
use truth::{PixelFilter, PolygonEstimate, TruthImage, TruthOptions};

/// What `pixelflow-sim truth` was asked to do.
#[derive(Debug, Clone, Default)]
pub struct TruthRequest {
    /// The scene's command-line options (`-D`, `--camera`, `--strict`).
    pub load: scene::LoadOptions,
    /// Scene file (or a solution file, whose scene is used).
    pub input: PathBuf,
    /// OpenEXR of the mean B per pixel (`-o`); the standard errors go beside it
    /// ([`stderr_path`]). `None`: no image.
    pub output: Option<PathBuf>,
    /// JSON of the per-polygon estimates (`--json`); `-`: none written, the caller prints the
    /// report. `None`: no per-polygon run.
    pub json: Option<PathBuf>,
    /// OpenEXR of the pixels near a shadow boundary (`--shadow-mask`, [`truth::shadows`]): 1
    /// within [`metric::edges::EDGE_RADIUS`] pixels of one, 0 elsewhere; for `compare --mask`.
    pub shadow_mask: Option<PathBuf>,
    /// Samples per pixel, at most (default 64).
    pub spp: Option<u32>,
    /// Image width (default: the scene's).
    pub width: Option<u32>,
    /// Image height (default: the scene's).
    pub height: Option<u32>,
    /// The renderer's sample pattern (1, 4 or 16) instead of the box filter.
    pub aa: Option<u32>,
    /// Seed of the random streams (default 1).
    pub seed: Option<u64>,
    /// Samples per polygon, at most (default 4,096).
    pub polygon_samples: Option<u64>,
    /// Strata per side of each polygon's (u, v) grid (default 4).
    pub strata: Option<u32>,
    /// Target relative standard error (stops early once met).
    pub max_error: Option<f64>,
    /// Most reflections per path (default: none, Russian roulette alone).
    pub max_bounces: Option<u32>,
    /// Also solve the scene (or read the input solution file) and report the solver's mean
    /// per polygon beside the truth (needs `json`).
    pub compare_solver: bool,
}

/// Cells per side of the (u, v) grid the solver's per-polygon mean is integrated on.
pub const SOLVER_QUADRATURE: u32 = 128;

/// The standard-error image written beside the image `output`: `out.exr` -> `out.stderr.exr`.
pub fn stderr_path(output: &Path) -> PathBuf {
    output.with_extension("stderr.exr")
}

/// A request resolved against its scene and checked.
#[derive(Debug, Clone)]
pub struct TruthPlan {
    /// The tracer's options.
    pub options: TruthOptions,
    /// The image, its standard errors (paths), if asked for.
    pub image: Option<(PathBuf, PathBuf)>,
    /// The per-polygon JSON, if asked for.
    pub json: Option<PathBuf>,
    /// The shadow-boundary mask, if asked for.
    pub shadow_mask: Option<PathBuf>,
}

impl TruthPlan {
    /// Resolves `req` against `scene` and checks it: at least one output, `-o` an `.exr`, at
    /// least 2 samples per pixel (a standard error needs two), every option in range, no output
    /// replacing an input or another output, and the memory estimate under the job's limit.
    pub fn new(ctx: &Context<'_>, req: &TruthRequest, scene: &Scene) -> Result<TruthPlan> {
        if req.output.is_none() && req.json.is_none() && req.shadow_mask.is_none() {
            return Err(Error::invalid_option(
                "output",
                "",
                "give `output` out.exr for the image, `json` out.json for the polygons, \
                 `shadow-mask` mask.exr for the shadow boundaries, or any of them",
            ));
        }
        if req.compare_solver && req.json.is_none() {
            return Err(Error::invalid_option(
                "compare-solver",
                "",
                "compares per polygon: give `json` out.json too",
            ));
        }
        let defaults = TruthOptions::new(scene);
        let options = TruthOptions {
            seed: req.seed.unwrap_or(defaults.seed),
            width: req.width.unwrap_or(scene.width),
            height: req.height.unwrap_or(scene.height),
            samples_per_pixel: req.spp.unwrap_or(defaults.samples_per_pixel),
            filter: PixelFilter::from_aa(req.aa.map(|n| Aa::new("aa", n)).transpose()?),
            samples_per_polygon: req.polygon_samples.unwrap_or(defaults.samples_per_polygon),
            strata: req.strata.unwrap_or(defaults.strata),
            max_error: req.max_error,
            max_bounces: req.max_bounces,
        };
        options.validate()?;
        if req.output.is_some() && options.samples_per_pixel < 2 {
            return Err(Error::invalid_option(
                "spp",
                options.samples_per_pixel.to_string(),
                "a pixel's standard error needs at least 2 samples",
            ));
        }
        for (option, out) in [("output", &req.output), ("shadow-mask", &req.shadow_mask)] {
            let Some(out) = out else { continue };
            let exr = out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
            if !exr {
                return Err(Error::invalid_option(
                    option,
                    out.display().to_string(),
                    "the truth's images are OpenEXR: name it .exr",
                ));
            }
        }
        let image = req.output.as_ref().map(|o| (o.clone(), stderr_path(o)));
        let plan = TruthPlan {
            options,
            image,
            json: req.json.clone(),
            shadow_mask: req.shadow_mask.clone(),
        };
        plan.check_outputs(req, scene)?;
        plan.memory(scene).check(ctx.memory_limit)?;
        Ok(plan)
    }

    fn check_outputs(&self, req: &TruthRequest, scene: &Scene) -> Result<()> {
        let mut inputs = scene.inputs.clone();
        inputs.push(req.input.clone());
        let mut outputs: Vec<(&str, &Path)> = Vec::new();
        if let Some((mean, se)) = &self.image {
            outputs.push(("output", mean));
            outputs.push(("-o (its standard errors)", se));
        }
        let file = self.json.as_deref().filter(|j| *j != Path::new("-"));
        outputs.extend(file.map(|j| ("json", j)));
        outputs.extend(self.shadow_mask.as_deref().map(|m| ("shadow-mask", m)));
        base::output::check_outputs(&inputs, &outputs)?;
        if let Some(j) = file {
            crate::commands::render::check_extension(
                "json",
                j,
                "json",
                "JSON (every polygon's estimates)",
            )?;
        }
        Ok(())
    }

    /// What the run holds at most: the BVH and the per-polygon sums, the per-pixel sums and
    /// the two images and their encodings, the per-cell sums of a polygon pass.
    fn memory(&self, scene: &Scene) -> crate::budget::Estimate {
        let mut e = crate::budget::Estimate::new(
            "the truth run",
            "lower `width` / `height` or `strata`, or raise `memory-limit`",
        );
        let polygons = scene.polygons.len() as u64;
        e.add("scene and BVH", polygons.saturating_mul(600));
        let pixels = self.options.width as u64 * self.options.height as u64;
        if self.image.is_some() {
            e.add("pixel sums and images", pixels.saturating_mul(56 + 4 * 12));
        }
        if self.shadow_mask.is_some() {
            e.add("shadow map and mask", pixels.saturating_mul(80));
        }
        if self.json.is_some() {
            let cells = (self.options.strata * self.options.strata) as u64;
            e.add("polygon sums", polygons.saturating_mul(cells * 160 + 400));
        }
        e
    }
}

/// What a truth job reports as it goes.
#[derive(Debug)]
pub enum TruthEvent<'a> {
    /// A warning of the scene's (a non-planar quad split, ...).
    Warning(&'a str),
    /// A file was written.
    Wrote(&'a Path),
}

/// What a truth run computed, with its run times (which the files leave out).
#[derive(Debug, Clone)]
pub struct TruthOutcome {
    /// The image, and the seconds it took.
    pub image: Option<(TruthImage, f64)>,
    /// The per-polygon report, and the seconds it took.
    pub polygons: Option<(PolygonReport, f64)>,
    /// Pixels on a shadow boundary and pixels near one (the mask's), and the seconds the map
    /// took.
    pub shadows: Option<(usize, usize, f64)>,
}

/// Runs a truth job: load, plan and check, then the image and the polygons, then all files in
/// one batch.
pub fn run_truth(
    ctx: &Context<'_>,
    req: &TruthRequest,
    on: &mut dyn FnMut(TruthEvent<'_>),
) -> Result<TruthOutcome> {
    let input = crate::context::Input::load_opts(&req.input, None, &req.load)?;
    let plan = TruthPlan::new(ctx, req, &input.scene)?;
    for w in &input.scene.warnings {
        on(TruthEvent::Warning(w));
    }
    let scene = &input.scene.clone();
    let solver = if req.compare_solver {
        crate::budget::check_solve(scene, ctx.memory_limit)?;
        let policy = crate::context::scene_texture_policy(scene);
        let placement = scene.render.texel_placement;
        let prepared = crate::prepare::prepare(ctx, input, policy, placement)?;
        let solution = radiosity::face_means(&prepared.solution, &prepared.scene)?;
        Some((solver_means(&prepared)?, solution))
    } else {
        None
    };
    let mut batch = ctx.outputs.batch();
    let mut staged: Vec<&Path> = Vec::new();
    let mut outcome = TruthOutcome {
        image: None,
        polygons: None,
        shadows: None,
    };
    if let Some((mean, se)) = &plan.image {
        let t = Instant::now();
        let img = truth::render(scene, &plan.options, ctx.observer)?;
        let seconds = t.elapsed().as_secs_f64();
        batch.stage(mean, &imageio::encode_exr(img.mean.view())?)?;
        batch.stage(se, &imageio::encode_exr(img.stderr.view())?)?;
        staged.extend([mean.as_path(), se.as_path()]);
        outcome.image = Some((img, seconds));
    }
    if let Some(path) = &plan.json {
        let t = Instant::now();
        let est = truth::polygons(scene, &plan.options, ctx.observer)?;
        let seconds = t.elapsed().as_secs_f64();
        let mut report = PolygonReport::new(&req.input, scene, &plan.options, &est);
        if let Some((means, solution)) = &solver {
            report.add_solver(means, solution);
        }
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| Error::internal(format!("truth report to JSON: {e}")))?;
        if path != Path::new("-") {
            batch.stage(path, (json + "\n").as_bytes())?;
            staged.push(path);
        }
        outcome.polygons = Some((report, seconds));
    }
    if let Some(path) = &plan.shadow_mask {
        let t = Instant::now();
        let (on_boundary, mask) = shadow_mask(scene, &plan.options)?;
        let near = mask.pixels.iter().filter(|p| p.x > 0.0).count();
        batch.stage(path, &imageio::encode_exr(mask.view())?)?;
        staged.push(path);
        outcome.shadows = Some((on_boundary, near, t.elapsed().as_secs_f64()));
    }
    batch.commit()?;
    for path in staged {
        on(TruthEvent::Wrote(path));
    }
    Ok(outcome)
}

/// The shadow boundaries of the camera's view ([`truth::shadow_map`]) at the run's image size,
/// and the mask of the pixels within [`metric::edges::EDGE_RADIUS`] of them (1, else 0): the
/// pixels `compare --mask` splits an image's error at.
fn shadow_mask(scene: &Scene, options: &TruthOptions) -> Result<(usize, LinearImage)> {
    let map = truth::shadow_map(scene, options.width, options.height)?;
    let (w, h) = (options.width as usize, options.height as usize);
    let near = metric::edges::dilate(&map.boundary, w, h, metric::edges::EDGE_RADIUS);
    let pixels = near
        .iter()
        .map(|&n| Vec3::splat(if n { 1.0 } else { 0.0 }))
        .collect();
    let mask = LinearImage {
        width: options.width,
        height: options.height,
        pixels,
    };
    Ok((map.boundary_pixels(), mask))
}

/// The `--json` file: the run's settings and every polygon's estimates.
#[derive(Debug, Clone, Serialize)]
pub struct PolygonReport {
    /// The input as given.
    pub scene: String,
    /// The seed.
    pub seed: u64,
    /// Samples per polygon, at most.
    pub samples_per_polygon: u64,
    /// Strata per side of each polygon's (u, v) grid.
    pub strata: u32,
    /// The relative error target, if any.
    pub max_error: Option<f64>,
    /// The bounce limit, if any.
    pub max_bounces: Option<u32>,
    /// Every polygon, in scene order.
    pub polygons: Vec<PolygonRow>,
}

/// One polygon's estimates (linear RGB, W/m^2; `_se` the standard error of the value before it).
#[derive(Debug, Clone, Serialize)]
pub struct PolygonRow {
    /// Index in the scene.
    pub polygon: u32,
    /// The inline polygon's or OBJ group's name.
    pub object: String,
    /// The material's name.
    pub material: String,
    /// Area, square scene units.
    pub area: f64,
    /// Samples taken on it.
    pub samples: u64,
    /// Exitance E (exact).
    pub emission: [f64; 3],
    /// Mean radiosity B = E + direct + indirect over the polygon.
    pub radiosity: [f64; 3],
    /// Its standard error.
    pub radiosity_se: [f64; 3],
    /// Reflected light that came straight from emitters and spots.
    pub direct: [f64; 3],
    /// Its standard error.
    pub direct_se: [f64; 3],
    /// Reflected light that was reflected before.
    pub indirect: [f64; 3],
    /// Its standard error.
    pub indirect_se: [f64; 3],
    /// The solver's mean radiosity over the polygon (with `--compare-solver`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solver: Option<[f64; 3]>,
    /// `solver / radiosity` per channel (with `--compare-solver`; 1 where both are 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solver_ratio: Option<[f64; 3]>,
    /// `(solver - radiosity) / radiosity_se` per channel: how many truth standard errors apart
    /// (with `--compare-solver`; 0 where the standard error is 0 and they agree).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solver_z: Option<[f64; 3]>,
    /// The solution's own mean over the polygon, before reconstruction: its samples integrated
    /// over its quadtree's leaves (`radiosity::face_means`; with `--compare-solver`). Against
    /// `radiosity` it is the solution's error; against `solver`, the reconstruction's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solution: Option<[f64; 3]>,
    /// The part of `solution` that came straight from emitters and spots (emission included).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub solution_direct: Option<[f64; 3]>,
}

impl PolygonReport {
    /// The report of estimates `est` of `scene` (read from `input`) made with `opts`.
    pub fn new(
        input: &Path,
        scene: &Scene,
        opts: &TruthOptions,
        est: &[PolygonEstimate],
    ) -> PolygonReport {
        let a = |v: DVec3| v.to_array();
        let polygons = est
            .iter()
            .map(|e| {
                let p = &scene.polygons[e.polygon as usize];
                PolygonRow {
                    polygon: e.polygon,
                    object: scene
                        .objects
                        .get(p.object as usize)
                        .cloned()
                        .unwrap_or_default(),
                    material: scene.materials[p.material as usize].name.clone(),
                    area: p.area,
                    samples: e.samples,
                    emission: a(e.emission),
                    radiosity: a(e.radiosity),
                    radiosity_se: a(e.radiosity_se),
                    direct: a(e.direct),
                    direct_se: a(e.direct_se),
                    indirect: a(e.indirect),
                    indirect_se: a(e.indirect_se),
                    solver: None,
                    solver_ratio: None,
                    solver_z: None,
                    solution: None,
                    solution_direct: None,
                }
            })
            .collect();
        PolygonReport {
            scene: input.display().to_string(),
            seed: opts.seed,
            samples_per_polygon: opts.samples_per_polygon,
            strata: opts.strata,
            max_error: opts.max_error,
            max_bounces: opts.max_bounces,
            polygons,
        }
    }

    /// Adds the solver's means as rendered (one per polygon, in order), their ratios to the
    /// truth and their distances in truth standard errors, and the solution's own means.
    pub fn add_solver(&mut self, means: &[DVec3], solution: &[radiosity::FaceMean]) {
        for (r, f) in self.polygons.iter_mut().zip(solution) {
            r.solution = Some(f.total.to_array());
            r.solution_direct = Some(f.direct.to_array());
        }
        for (r, m) in self.polygons.iter_mut().zip(means) {
            let (mut ratio, mut z) = ([1.0; 3], [0.0; 3]);
            for c in 0..3 {
                let (s, t, se) = (m[c], r.radiosity[c], r.radiosity_se[c]);
                if s != t {
                    ratio[c] = s / t;
                    z[c] = (s - t) / se;
                }
            }
            r.solver = Some(m.to_array());
            r.solver_ratio = Some(ratio);
            r.solver_z = Some(z);
        }
    }

    /// The largest relative standard error of any polygon's radiosity in any channel (over
    /// the channels whose value is positive).
    pub fn largest_relative_error(&self) -> f64 {
        self.polygons
            .iter()
            .flat_map(|r| (0..3).map(move |c| (r.radiosity[c], r.radiosity_se[c])))
            .filter(|(b, _)| *b > 0.0)
            .map(|(b, se)| se / b)
            .fold(0.0, f64::max)
    }

    /// A text table: per polygon its object, B, relative standard error, direct and indirect
    /// parts (RGB), and with the solver's means their luminance ratio to the truth.
    pub fn table(&self) -> String {
        let rgb = |v: [f64; 3]| format!("{:.4} {:.4} {:.4}", v[0], v[1], v[2]);
        let lum = |v: [f64; 3]| base::image::luminance(glam::Vec3::from(v.map(|x| x as f32)));
        let solver = self.polygons.iter().any(|r| r.solver.is_some());
        let width = self
            .polygons
            .iter()
            .map(|r| r.object.len())
            .fold(6, usize::max);
        let mut s = format!(
            "{:>4}  {:<width$} {:<26} {:>6}  {:<26} {:<26}{}\n",
            "poly",
            "object",
            "B (r g b)",
            "SE %",
            "direct",
            "indirect",
            if solver {
                "  solver/truth  solution/truth"
            } else {
                ""
            }
        );
        for r in &self.polygons {
            let rel = (0..3)
                .filter(|&c| r.radiosity[c] > 0.0)
                .map(|c| r.radiosity_se[c] / r.radiosity[c])
                .fold(0.0, f64::max);
            // A face that receives no light (a piece buried under a face over it) has no
            // ratio: "-", not the NaN of 0 / 0.
            let of = |m: [f64; 3], w: usize| {
                let t = lum(r.radiosity);
                if t > 0.0 {
                    format!("  {:>w$.4}", lum(m) / t)
                } else {
                    format!("  {:>w$}", "-")
                }
            };
            let ratio = r.solver.map(|m| of(m, 12)).unwrap_or_default()
                + &r.solution.map(|m| of(m, 14)).unwrap_or_default();
            s += &format!(
                "{:>4}  {:<width$} {:<26} {:>6.3}  {:<26} {:<26}{ratio}\n",
                r.polygon,
                r.object,
                rgb(r.radiosity),
                100.0 * rel,
                rgb(r.direct),
                rgb(r.indirect)
            );
        }
        s
    }
}

/// The solver's mean radiosity over every polygon as rendered: the expanded RRPs at the
/// centres of a [`SOLVER_QUADRATURE`]^2 grid in (u, v), weighted by the area element (the
/// midpoint rule of (1/A) * integral of B dA), polygons in parallel, each summed in grid order.
fn solver_means(p: &crate::prepare::Prepared) -> Result<Vec<DVec3>> {
    use rayon::prelude::*;
    let (rrps, _) = p.expanded()?;
    let n = SOLVER_QUADRATURE;
    Ok((0..p.scene.polygons.len())
        .into_par_iter()
        .map(|i| {
            let poly = &p.scene.polygons[i];
            let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
            for j in 0..n {
                for k in 0..n {
                    let u = (k as f64 + 0.5) / n as f64;
                    let v = (j as f64 + 0.5) / n as f64;
                    let w = poly.area_element(u, v);
                    sum += w * rrps.eval(i as u32, u as f32, v as f32).as_dvec3();
                    weight += w;
                }
            }
            sum / weight
        })
        .collect())
}
