//! The truth image: per pixel, the mean of B at the first surface the camera sees, over the
//! pixel's filter, with its standard error.
//!
//! Each camera sample draws a position in the pixel ([`PixelFilter`]), casts the camera's ray
//! through it ([`CameraRays`]) and scores B = E + rho * H at the first front face it meets (one
//! path sample of rho * H), 0 at a back face (one-sided surfaces: nothing leaves their back; the
//! renderer draws a back face with its front's radiosity instead, so pixels that see back faces
//! differ from `render` by design, counted in [`TruthImage::back_face_samples`]) and the scene's
//! display background where it meets nothing (what `render` writes there). Samples are
//! independent and identically distributed, so the standard error of a pixel's mean is its
//! sample standard deviation over sqrt(n).
//!
//! The run goes in passes of [`PASS_SAMPLES`] samples per pixel, rows in parallel; sample k of
//! pixel i always uses the stream `seed_of(&[seed, PIXEL, i, k])` and each pixel sums its samples
//! in order, so the image is the same bits for any thread count. With a target
//! ([`crate::TruthOptions::max_error`]) the run stops after the first pass (of at least
//! [`MIN_SAMPLES_FOR_TARGET`] samples) whose root-mean-square luminance standard error over the
//! pixels is at most the target times the image's mean luminance.

use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::camera::{CameraRays, PixelFilter};
use crate::tracer::{Surface, Tracer};
use crate::{luminance, stream, TruthOptions};
use base::error::Result;
use base::image::LinearImage;
use base::progress::{Observer, Stage};
use base::rng::{seed_of, Rng};
use scene::Scene;

/// The progress stage of [`render`].
pub const IMAGE_STAGE: &str = "truth image";

/// Camera samples per pixel in one pass.
pub const PASS_SAMPLES: u32 = 4;

/// Samples per pixel before an error target may stop the run (fewer make the error estimate
/// itself too noisy to stop on).
pub const MIN_SAMPLES_FOR_TARGET: u32 = 16;

/// A truth image: per-pixel means and standard errors of B.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthImage {
    /// Mean B per pixel (linear RGB, W/m^2), as `render --exr` writes it.
    pub mean: LinearImage,
    /// Standard error of each pixel's mean, per channel (infinite with a single sample).
    pub stderr: LinearImage,
    /// Samples taken in every pixel.
    pub samples_per_pixel: u32,
    /// Camera samples whose first surface was a back face (scored black).
    pub back_face_samples: u64,
    /// Root-mean-square over the pixels of the luminance standard error, relative to the
    /// image's mean luminance (0 for a black image).
    pub relative_error: f64,
}

/// A pixel's running sums: of B per channel, of its square per channel, of its luminance's
/// square.
#[derive(Debug, Clone, Copy, Default)]
struct PixelSums {
    sum: DVec3,
    squares: DVec3,
    lum_squares: f64,
}

impl PixelSums {
    fn add(&mut self, b: DVec3) {
        self.sum += b;
        self.squares += b * b;
        let l = luminance(b);
        self.lum_squares += l * l;
    }

    /// Mean, per-channel standard error of the mean and luminance standard error after `n`
    /// samples (the errors are infinite for n = 1).
    fn estimate(&self, n: u32) -> (DVec3, DVec3, f64) {
        let n = n as f64;
        let mean = self.sum / n;
        if n < 2.0 {
            return (mean, DVec3::INFINITY, f64::INFINITY);
        }
        let var = ((self.squares - self.sum * mean) / (n - 1.0)).max(DVec3::ZERO);
        let l = luminance(self.sum);
        let lvar = ((self.lum_squares - l * l / n) / (n - 1.0)).max(0.0);
        (mean, (var / n).map(f64::sqrt), (lvar / n).sqrt())
    }
}

/// Renders the truth image of `scene` with `opts` (image size, samples per pixel, filter, seed,
/// error target, bounce limit), in the caller's rayon pool, reporting the stage
/// [`IMAGE_STAGE`] to `observer` (and a trace line per pass if it wants them).
pub fn render(scene: &Scene, opts: &TruthOptions, observer: &dyn Observer) -> Result<TruthImage> {
    opts.validate()?;
    let cam = CameraRays::new(&scene.camera, opts.width, opts.height)?;
    let tracer = Tracer::new(scene, opts.max_bounces);
    let (w, h) = (opts.width as usize, opts.height as usize);
    let mut sums = vec![PixelSums::default(); w * h];
    let mut back_face_samples = 0u64;
    let mut done = 0u32;
    let mut relative_error = f64::INFINITY;
    let mut stage = Stage::start(observer, IMAGE_STAGE);
    let start = Instant::now();
    while done < opts.samples_per_pixel {
        let k = PASS_SAMPLES.min(opts.samples_per_pixel - done);
        let pass = Pass {
            scene,
            tracer: &tracer,
            cam: &cam,
            filter: opts.filter,
            seed: opts.seed,
            width: w,
            first: done,
            count: k,
        };
        back_face_samples += sums
            .par_chunks_mut(w)
            .enumerate()
            .map(|(row, pixels)| pass.row(row, pixels))
            .sum::<u64>();
        done += k;
        relative_error = image_error(&sums, done);
        let fraction = done as f64 / opts.samples_per_pixel as f64;
        stage.advance(fraction);
        stage.remaining(
            "sampling",
            start.elapsed().as_secs_f64() * (1.0 / fraction - 1.0),
        );
        if observer.tracing() {
            observer.trace(&format!(
                "{IMAGE_STAGE}: {done} samples per pixel, relative error {relative_error:.5}, \
                 {:.1} s",
                start.elapsed().as_secs_f64()
            ));
        }
        let target_met = opts.max_error.is_some_and(|t| relative_error <= t);
        if target_met && done >= MIN_SAMPLES_FOR_TARGET {
            break;
        }
    }
    drop(stage);
    Ok(finish(&sums, opts, done, back_face_samples, relative_error))
}

/// One pass's samples: `count` per pixel from sample index `first`.
struct Pass<'a> {
    scene: &'a Scene,
    tracer: &'a Tracer<'a>,
    cam: &'a CameraRays,
    filter: PixelFilter,
    seed: u64,
    width: usize,
    first: u32,
    count: u32,
}

impl Pass<'_> {
    /// Adds this pass's samples to row `row`'s pixels; the number of back-face samples.
    fn row(&self, row: usize, pixels: &mut [PixelSums]) -> u64 {
        let mut back = 0;
        for (x, sums) in pixels.iter_mut().enumerate() {
            let index = (row * self.width + x) as u64;
            for s in self.first..self.first + self.count {
                let mut rng = Rng::new(seed_of(&[self.seed, stream::PIXEL, index, s as u64]));
                let (ox, oy) = self.filter.offset(&mut rng);
                let (o, d) = self.cam.ray(x as f64 + ox, row as f64 + oy);
                let b = match self.tracer.trace_from_outside(o, d) {
                    Surface::Miss => self.scene.display.background,
                    Surface::Back => {
                        back += 1;
                        DVec3::ZERO
                    }
                    Surface::Front { polygon, point } => {
                        let r = self.tracer.reflected(polygon, point, &mut rng);
                        self.scene.material_of(polygon as usize).emission + r.direct + r.indirect
                    }
                };
                sums.add(b);
            }
        }
        back
    }
}

/// Root-mean-square luminance standard error over the pixels relative to the mean luminance
/// (summed in pixel order).
fn image_error(sums: &[PixelSums], n: u32) -> f64 {
    let (mut mean, mut var) = (0.0, 0.0);
    for s in sums {
        let (m, _, se) = s.estimate(n);
        mean += luminance(m);
        var += se * se;
    }
    let count = sums.len().max(1) as f64;
    let (mean, rms) = (mean / count, (var / count).sqrt());
    if mean > 0.0 {
        rms / mean
    } else if rms == 0.0 {
        0.0
    } else {
        f64::INFINITY
    }
}

fn finish(
    sums: &[PixelSums],
    opts: &TruthOptions,
    n: u32,
    back_face_samples: u64,
    relative_error: f64,
) -> TruthImage {
    let f = |v: DVec3| Vec3::new(v.x as f32, v.y as f32, v.z as f32);
    let (mean, stderr): (Vec<Vec3>, Vec<Vec3>) = sums
        .iter()
        .map(|s| {
            let (m, se, _) = s.estimate(n);
            (f(m), f(se))
        })
        .unzip();
    let image = |pixels| LinearImage {
        width: opts.width,
        height: opts.height,
        pixels,
    };
    TruthImage {
        mean: image(mean),
        stderr: image(stderr),
        samples_per_pixel: n,
        back_face_samples,
        relative_error,
    }
}
