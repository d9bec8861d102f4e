//! Truth: an independent Monte Carlo path tracer of the project's scene model, the physical
//! reference the radiosity solver is measured against. It shares the scene (polygons, materials,
//! spot lights, camera), the ray-query BVH and the random streams with the rest of the project,
//! and nothing of the solver: no form factors, no visibility sampling, no quadtrees, no
//! reconstruction. An error the solver makes is therefore not repeated here.
//!
//! What it estimates, in the solver's units: the radiosity B = E + rho * H (W/m^2 per channel) of
//! every point, where E is the material's exitance and H the irradiance on the polygon's front
//! side. [`render`] estimates, per pixel, the mean of B at the first surface the camera sees over
//! the pixel's filter (what `render --exr` holds per pixel); [`fn@polygons`] estimates, per polygon,
//! the area average of B with its direct and indirect parts, from points sampled over the
//! polygon itself (no camera involved), so a solution can be compared face by face.
//!
//! Physics, as the solver models it (`docs/truth.md` gives the estimator in full):
//! - polygons are one-sided Lambertian surfaces: they emit (radiance E / pi) and reflect
//!   (reflectance rho) on their front side, the side the normal points to, and are opaque on
//!   both; a path that meets a back face sees black and ends;
//! - spot lights are points with intensity `SpotLight::intensity_towards`, lighting surfaces by
//!   next-event estimation only (a camera ray never sees them);
//! - area emitters are sampled by next-event estimation (an emitter chosen by power, a point
//!   uniform over its area) and by the cosine-distributed bounce, combined by multiple importance
//!   sampling (balance heuristic), which keeps every sample's weight bounded;
//! - paths end by Russian roulette (unbiased), never by a fixed depth unless
//!   [`TruthOptions::max_bounces`] asks for one; the background emits nothing.
//!
//! Invariants: every random number comes from a SplitMix64 stream seeded by
//! `base::rng::seed_of(&[seed, stream, pixel or polygon, sample])`, and every sum is reduced in a
//! fixed order, so the results are the same bits for any number of threads. Every standard error
//! is estimated from the samples themselves (per-pixel sample variance; per-polygon variance of
//! stratified pairs) and is an honest one-sigma error of the mean it accompanies.

#![forbid(unsafe_code)]

pub mod camera;
mod lights;
mod tracer;
pub mod image;
pub mod polygons;
pub mod shadows;

use base::error::{Error, Result};
use scene::Scene;

pub use camera::{CameraRays, PixelFilter};
pub use image::{render, TruthImage};
pub use polygons::{polygons, PolygonEstimate};
pub use shadows::{shadow_map, ShadowMap};

/// Most camera samples per pixel accepted (far more than any run needs; bounds the run time of
/// a mistyped option).
pub const MAX_SAMPLES_PER_PIXEL: u32 = 1 << 24;

/// Most samples per polygon accepted.
pub const MAX_SAMPLES_PER_POLYGON: u64 = 1 << 32;

/// Most strata per side of a polygon's (u, v) grid.
pub const MAX_STRATA: u32 = 64;

/// What a truth run computes and how long it may take.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthOptions {
    /// Seed of every random stream (the same seed gives the same bits).
    pub seed: u64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Camera samples per pixel, at most (fewer when [`TruthOptions::max_error`] is reached).
    pub samples_per_pixel: u32,
    /// Where in the pixel the camera samples lie.
    pub filter: PixelFilter,
    /// Samples per polygon, at most (rounded up to whole pairs in every stratum).
    pub samples_per_polygon: u64,
    /// Strata per side of each polygon's (u, v) grid: `strata^2` cells, two samples in each cell
    /// per round.
    pub strata: u32,
    /// Target relative standard error: a run stops early once it is met (see [`render`] and
    /// [`fn@polygons`] for what is compared with it). `None`: every sample is taken.
    pub max_error: Option<f64>,
    /// Most reflections a path follows before the estimated point (0: direct light only).
    /// `None`: no limit, paths end by Russian roulette alone (unbiased).
    pub max_bounces: Option<u32>,
}

impl TruthOptions {
    /// The defaults for `scene`: its image size, 64 samples per pixel with the box filter,
    /// 4,096 samples per polygon in 4 x 4 strata, seed 1, no error target, no bounce limit.
    pub fn new(scene: &Scene) -> TruthOptions {
        TruthOptions {
            seed: 1,
            width: scene.width,
            height: scene.height,
            samples_per_pixel: 64,
            filter: PixelFilter::Box,
            samples_per_polygon: 4096,
            strata: 4,
            max_error: None,
            max_bounces: None,
        }
    }

    /// Checks every option; each error names the command line's option.
    pub fn validate(&self) -> Result<()> {
        let dims = 1..=scene::MAX_IMAGE_DIM;
        if !dims.contains(&self.width) || !dims.contains(&self.height) {
            return Err(Error::invalid_option(
                "image size",
                format!("{} x {}", self.width, self.height),
                format!("width and height must be in 1..={}", scene::MAX_IMAGE_DIM),
            ));
        }
        if !(1..=MAX_SAMPLES_PER_PIXEL).contains(&self.samples_per_pixel) {
            return Err(Error::invalid_option(
                "spp",
                self.samples_per_pixel.to_string(),
                format!("samples per pixel must be in 1..={MAX_SAMPLES_PER_PIXEL}"),
            ));
        }
        if !(1..=MAX_SAMPLES_PER_POLYGON).contains(&self.samples_per_polygon) {
            return Err(Error::invalid_option(
                "polygon-samples",
                self.samples_per_polygon.to_string(),
                format!("samples per polygon must be in 1..={MAX_SAMPLES_PER_POLYGON}"),
            ));
        }
        if !(1..=MAX_STRATA).contains(&self.strata) {
            return Err(Error::invalid_option(
                "strata",
                self.strata.to_string(),
                format!("strata per side must be in 1..={MAX_STRATA}"),
            ));
        }
        if let Some(e) = self.max_error {
            if !(e > 0.0 && e.is_finite()) {
                return Err(Error::invalid_option(
                    "max-error",
                    e.to_string(),
                    "the target relative standard error must be positive and finite",
                ));
            }
        }
        Ok(())
    }
}

/// The first words of every random stream's seed that say what it samples, so a pixel's and a
/// polygon's streams never coincide.
pub(crate) mod stream {
    /// Camera samples: `[seed, PIXEL, pixel index, sample index]`.
    pub(crate) const PIXEL: u64 = 0x0070_6978_656c;
    /// Polygon samples: `[seed, POLYGON, polygon index, sample index]`.
    pub(crate) const POLYGON: u64 = 0x0070_6f6c_7967_6f6e;
}

/// Luminance (Rec. 709) of a linear RGB value: what the error targets compare.
pub(crate) fn luminance(c: glam::DVec3) -> f64 {
    let w = base::image::LUMINANCE_WEIGHTS;
    w[0] * c.x + w[1] * c.y + w[2] * c.z
}
