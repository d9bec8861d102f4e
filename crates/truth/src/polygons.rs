//! Per-polygon truth: the area average of B over every polygon, with its direct and indirect
//! parts and their standard errors, estimated from points sampled over the polygon itself, so
//! the estimate depends on no camera and a whole solution can be compared face by face.
//!
//! The estimator. A polygon's (u, v) square is cut into `strata x strata` cells; each round puts
//! two independent points in every cell, (u, v) uniform in the cell, and scores each point
//! x = P(u, v) with f = J(u, v) / A * rho H(x), one path sample of the reflected radiosity
//! weighted by the area element J over the polygon's area A (the bilinear map is not
//! area-preserving in general, and a collapsed-quad triangle has J = 2A(1 - v)). Then
//! mean(f) estimates (1/A) * integral of rho H dA, and B = E + mean(f) (E is constant over a
//! polygon, so it carries no noise). Every cell has the same number of samples, so the mean over
//! all samples is the stratified estimate, and its variance is estimated from the pairs: each
//! pair (f1, f2) of a cell gives (f1 - f2)^2 / 2, an unbiased estimate of the cell's variance,
//! and with N samples in all and D the sum of those halves of squared differences,
//! Var(mean) = 2 D / N^2. This keeps the gain of stratification (the spread of B over the
//! polygon does not count as noise) and stays an unbiased variance estimate.
//!
//! Rounds run in passes of [`PASS_PAIRS`] pairs per cell, the (polygon, cell) items in
//! parallel; sample s of polygon p always uses the stream `seed_of(&[seed, POLYGON, p, s])`, and
//! the items' sums are reduced per polygon in cell order, so the estimates are the same bits for
//! any thread count. With a target ([`crate::TruthOptions::max_error`]) a polygon stops once its
//! luminance standard error is at most the target times the larger of its luminance and a floor
//! of [`ERROR_FLOOR`] times the brightest polygon's reflected luminance (so a polygon that is
//! nearly black does not run to the sample limit), after at least [`MIN_PAIRS_FOR_TARGET`] pairs
//! per cell; the decision depends only on the estimates, never on timing.

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use crate::tracer::Tracer;
use crate::{luminance, stream, TruthOptions};
use base::error::Result;
use base::progress::{Observer, Stage};
use base::rng::{seed_of, Rng};
use scene::Scene;

/// The progress stage of [`polygons`].
pub const POLYGON_STAGE: &str = "truth polygons";

/// Pairs per cell in one pass.
pub const PASS_PAIRS: u64 = 4;

/// Pairs per cell before an error target may stop a polygon.
pub const MIN_PAIRS_FOR_TARGET: u64 = 8;

/// The error target's floor, relative to the brightest polygon's reflected luminance.
pub const ERROR_FLOOR: f64 = 0.01;

/// A polygon's truth: the area average of its radiosity and of its parts, each with the
/// standard error of its estimate (per channel, W/m^2).
#[derive(Debug, Clone, PartialEq)]
pub struct PolygonEstimate {
    /// Index of the polygon in the scene.
    pub polygon: u32,
    /// Samples taken on it.
    pub samples: u64,
    /// Its exitance E (exact).
    pub emission: DVec3,
    /// Mean radiosity B = E + direct + indirect.
    pub radiosity: DVec3,
    /// Standard error of `radiosity`.
    pub radiosity_se: DVec3,
    /// Mean reflected light that came straight from an emitter or a spot light.
    pub direct: DVec3,
    /// Standard error of `direct`.
    pub direct_se: DVec3,
    /// Mean reflected light that was reflected at least once before.
    pub indirect: DVec3,
    /// Standard error of `indirect`.
    pub indirect_se: DVec3,
}

/// Sums over samples of the three scored quantities (reflected, direct, indirect), and of the
/// pairs' halved squared differences (per quantity and channel, and of the reflected
/// luminance).
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    sum: [DVec3; 3],
    dev: [DVec3; 3],
    lum_dev: f64,
}

impl Sums {
    fn add(&mut self, o: &Sums) {
        for q in 0..3 {
            self.sum[q] += o.sum[q];
            self.dev[q] += o.dev[q];
        }
        self.lum_dev += o.lum_dev;
    }

    /// Standard error of the mean reflected luminance after `n` samples.
    fn luminance_se(&self, n: u64) -> f64 {
        (2.0 * self.lum_dev).sqrt() / n as f64
    }

    /// Mean and standard error of quantity `q` after `n` samples.
    fn estimate(&self, q: usize, n: u64) -> (DVec3, DVec3) {
        let n = n as f64;
        (self.sum[q] / n, (2.0 * self.dev[q]).map(f64::sqrt) / n)
    }
}

/// One polygon's progress.
#[derive(Debug, Clone, Default)]
struct PolygonRun {
    /// Pairs taken in each cell.
    pairs: u64,
    sums: Sums,
    /// Whether it has stopped (sample limit or error target met).
    done: bool,
}

/// Estimates every polygon's mean radiosity, its direct and indirect parts and their standard
/// errors (see the module docs), with `opts`' seed, samples per polygon, strata, error target and
/// bounce limit, in the caller's rayon pool, reporting the stage [`POLYGON_STAGE`] to `observer`.
/// The estimates are in polygon order.
pub fn polygons(
    scene: &Scene,
    opts: &TruthOptions,
    observer: &dyn Observer,
) -> Result<Vec<PolygonEstimate>> {
    opts.validate()?;
    let tracer = Tracer::new(scene, opts.max_bounces);
    let cells = (opts.strata * opts.strata) as u64;
    let max_pairs = opts.samples_per_polygon.div_ceil(2 * cells);
    let mut runs = vec![PolygonRun::default(); scene.polygons.len()];
    let mut stage = Stage::start(observer, POLYGON_STAGE);
    let start = Instant::now();
    let sampler = Sampler {
        scene,
        tracer: &tracer,
        seed: opts.seed,
        strata: opts.strata,
    };
    loop {
        let active: Vec<u32> = (0..runs.len() as u32)
            .filter(|&p| !runs[p as usize].done)
            .collect();
        let Some(&first) = active.first() else { break };
        // Every active polygon has taken the same passes, so they share the pair range.
        let from = runs[first as usize].pairs;
        let k = PASS_PAIRS.min(max_pairs - from);
        let items: Vec<Sums> = (0..active.len() * cells as usize)
            .into_par_iter()
            .map(|i| {
                let p = active[i / cells as usize];
                sampler.cell(p, (i % cells as usize) as u32, from, k)
            })
            .collect();
        for (a, &p) in active.iter().enumerate() {
            let run = &mut runs[p as usize];
            for cell in &items[a * cells as usize..(a + 1) * cells as usize] {
                run.sums.add(cell);
            }
            run.pairs += k;
        }
        mark_done(scene, &mut runs, max_pairs, cells, opts.max_error);
        let fraction = progress(&runs, max_pairs);
        stage.advance(fraction);
        stage.remaining(
            "sampling",
            start.elapsed().as_secs_f64() * (1.0 / fraction - 1.0),
        );
        if observer.tracing() {
            let left = runs.iter().filter(|r| !r.done).count();
            observer.trace(&format!(
                "{POLYGON_STAGE}: {} samples per polygon, {left} polygons running, {:.1} s",
                2 * cells * (from + k),
                start.elapsed().as_secs_f64()
            ));
        }
    }
    drop(stage);
    Ok(runs
        .iter()
        .enumerate()
        .map(|(p, run)| estimate(scene, p, run, cells))
        .collect())
}

/// What one (polygon, cell) item needs to sample.
struct Sampler<'a> {
    scene: &'a Scene,
    tracer: &'a Tracer<'a>,
    seed: u64,
    strata: u32,
}

impl Sampler<'_> {
    /// The sums of pairs `from..from + k` of cell `cell` of polygon `p`.
    fn cell(&self, p: u32, cell: u32, from: u64, k: u64) -> Sums {
        let cells = (self.strata * self.strata) as u64;
        let poly = &self.scene.polygons[p as usize];
        let (ci, cj) = ((cell % self.strata) as f64, (cell / self.strata) as f64);
        let g = self.strata as f64;
        let mut out = Sums::default();
        for pair in from..from + k {
            let mut f = [[DVec3::ZERO; 3]; 2];
            for (j, fj) in f.iter_mut().enumerate() {
                let s = 2 * (pair * cells + cell as u64) + j as u64;
                let mut rng = Rng::new(seed_of(&[self.seed, stream::POLYGON, p as u64, s]));
                let u = (ci + rng.next_f64()) / g;
                let v = (cj + rng.next_f64()) / g;
                let weight = poly.area_element(u, v) / poly.area;
                let r = self.tracer.reflected(p, poly.point(u, v), &mut rng);
                *fj = [
                    weight * (r.direct + r.indirect),
                    weight * r.direct,
                    weight * r.indirect,
                ];
            }
            let [a, b] = f;
            for (q, (x, y)) in a.iter().zip(&b).enumerate() {
                out.sum[q] += *x + *y;
                let d = *x - *y;
                out.dev[q] += 0.5 * d * d;
            }
            let dl = luminance(a[0]) - luminance(b[0]);
            out.lum_dev += 0.5 * dl * dl;
        }
        out
    }
}

/// Marks the polygons that reached the sample limit or the error target.
fn mark_done(
    scene: &Scene,
    runs: &mut [PolygonRun],
    max_pairs: u64,
    cells: u64,
    target: Option<f64>,
) {
    let brightest = runs
        .iter()
        .filter(|r| r.pairs > 0)
        .map(|r| luminance(r.sums.estimate(0, 2 * cells * r.pairs).0))
        .fold(0.0, f64::max);
    let floor = ERROR_FLOOR * brightest;
    for (p, run) in runs.iter_mut().enumerate() {
        if run.done {
            continue;
        }
        let n = 2 * cells * run.pairs;
        let met = target.is_some_and(|t| {
            let (mean, _) = run.sums.estimate(0, n);
            let level = luminance(scene.material_of(p).emission + mean).max(floor);
            run.pairs >= MIN_PAIRS_FOR_TARGET && run.sums.luminance_se(n) <= t * level
        });
        run.done = met || run.pairs >= max_pairs;
    }
}

/// The fraction of the run done: pairs taken, a stopped polygon counting as complete.
fn progress(runs: &[PolygonRun], max_pairs: u64) -> f64 {
    if runs.is_empty() {
        return 1.0;
    }
    let done: f64 = runs
        .iter()
        .map(|r| if r.done { max_pairs } else { r.pairs } as f64)
        .sum();
    done / (runs.len() as f64 * max_pairs as f64)
}

fn estimate(scene: &Scene, p: usize, run: &PolygonRun, cells: u64) -> PolygonEstimate {
    let n = 2 * cells * run.pairs;
    let emission = scene.material_of(p).emission;
    let (reflected, reflected_se) = run.sums.estimate(0, n);
    let (direct, direct_se) = run.sums.estimate(1, n);
    let (indirect, indirect_se) = run.sums.estimate(2, n);
    PolygonEstimate {
        polygon: p as u32,
        samples: n,
        emission,
        radiosity: emission + reflected,
        radiosity_se: reflected_se,
        direct,
        direct_se,
        indirect,
        indirect_se,
    }
}
