//! Rasterization: the PixelFlow emulator's renderer, and the frame entry point
//! [`render_frame`] that drives a frame through every stage after the scene and its radiosity
//! reconstruction exist: [`geometry`] (view, projection, near-plane and guard-band clipping,
//! back-face policy) -> [`setup`] (fixed-point edge functions, top-left rule) -> round-robin
//! distribution of the primitives over R virtual renderers -> [`region`] (binning per region and
//! 8-lane block rasterization into [`gbuffer`]s, with each visible sample's radiosity patch located
//! and copied into a region-local table) -> [`crate::composition`] (merge by depth over renderers)
//! -> [`crate::shading`] (deferred bicubic evaluation and the supersampling resolve).
//!
//! Invariants: the image depends only on the scene, the camera, the patch source and the image
//! size and sample count: it is bit-identical for any number of threads and of renderers (stable
//! polygon-id tie-breaks, canonical patch tables, per-region work with no cross-region reduction).
//! No output pixel is NaN or infinite.
//!
//! Antialiasing samples per pixel (fixed patterns, offsets in pixels from the pixel's top-left
//! corner, all multiples of 1/256 so they are exact in the fixed-point grid):
//! - 1: the pixel centre (0.5, 0.5);
//! - 4: a rotated grid, (3/8, 1/8), (7/8, 3/8), (1/8, 5/8), (5/8, 7/8): four distinct rows and
//!   columns, which resolves near-horizontal and near-vertical edges into 5 levels;
//! - 16: a 4 x 4 stratified grid at the centres of the 1/4-pixel cells.
//!
//! Each sample position is rasterized and shaded on its own (as PixelFlow re-rasterized a region
//! per subpixel offset) and the resolve is a box filter: the mean of the pixel's samples.

pub mod gbuffer;
pub mod geometry;
pub mod region;
pub mod setup;

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::composition::{self, RegionReport};
use crate::error::{Error, Result};
use crate::scene::{Camera, Scene, MAX_IMAGE_DIM};
use crate::shading::{self, PatchSource, Shader};

use gbuffer::RegionGBuffer;
use region::RegionGrid;
use setup::Prim;

/// Default region side in pixels (PixelFlow's 1992 SIMD array).
pub const DEFAULT_REGION: u32 = 128;

/// Most virtual renderers accepted.
pub const MAX_RENDERERS: u32 = 64;

const CENTRE: [(f32, f32); 1] = [(0.5, 0.5)];
const ROTATED_GRID: [(f32, f32); 4] = [
    (0.375, 0.125),
    (0.875, 0.375),
    (0.125, 0.625),
    (0.625, 0.875),
];
const STRATIFIED_16: [(f32, f32); 16] = {
    let mut o = [(0.0f32, 0.0f32); 16];
    let c = [0.125f32, 0.375, 0.625, 0.875];
    let mut k = 0;
    while k < 16 {
        o[k] = (c[k % 4], c[k / 4]);
        k += 1;
    }
    o
};

/// The sample pattern for `aa` samples per pixel (1, 4 or 16): offsets within the pixel.
pub fn sample_offsets(aa: u32) -> Result<&'static [(f32, f32)]> {
    match aa {
        1 => Ok(&CENTRE),
        4 => Ok(&ROTATED_GRID),
        16 => Ok(&STRATIFIED_16),
        _ => Err(Error::Usage(format!(
            "--aa {aa}: antialiasing takes 1, 4 or 16 samples per pixel"
        ))),
    }
}

/// What a frame is rendered with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel: 1, 4 or 16.
    pub aa: u32,
    /// Virtual renderers (1 to [`MAX_RENDERERS`]).
    pub renderers: u32,
    /// Region side in pixels: a multiple of 8 in 8..=1024.
    pub region: u32,
    /// Cull polygons whose back faces the camera (off by default; see [`geometry`]).
    pub cull_back_faces: bool,
}

impl FrameOptions {
    /// Options for a `width` x `height` image with the defaults: AA 1, 1 renderer, 128 regions.
    pub fn new(width: u32, height: u32) -> FrameOptions {
        FrameOptions {
            width,
            height,
            aa: 1,
            renderers: 1,
            region: DEFAULT_REGION,
            cull_back_faces: false,
        }
    }

    /// Checks every option; a bad value is a usage error.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 || v > MAX_IMAGE_DIM {
                return Err(Error::Usage(format!(
                    "--{name} {v}: must be in 1..={MAX_IMAGE_DIM}"
                )));
            }
        }
        sample_offsets(self.aa)?;
        if self.renderers == 0 || self.renderers > MAX_RENDERERS {
            return Err(Error::Usage(format!(
                "--renderers {}: must be in 1..={MAX_RENDERERS}",
                self.renderers
            )));
        }
        if self.region < 8 || self.region > 1024 || self.region % 8 != 0 {
            return Err(Error::Usage(format!(
                "--region {}: must be a multiple of 8 in 8..=1024",
                self.region
            )));
        }
        Ok(())
    }
}

/// Counters and stage times of one frame (`--stats` JSON).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Rendering method (`direct`).
    pub method: String,
    /// Worker threads of the rayon pool the frame ran in.
    pub threads: usize,
    /// Virtual renderers.
    pub renderers: u32,
    /// Samples per pixel.
    pub aa: u32,
    /// Region side in pixels.
    pub region_size: u32,
    /// Regions at least one primitive was binned into.
    pub regions_touched: u32,
    /// Primitives that reached the rasterizer (after clipping, culling and off-screen rejection).
    pub primitives: u32,
    /// Covered samples the renderers rasterized, before depth tests (fragments).
    pub pixels_rasterized: u64,
    /// Samples that saw a polygon and were shaded.
    pub pixels_shaded: u64,
    /// Bytes that crossed the composition network (see [`crate::composition`]).
    pub composition_traffic_bytes: u64,
    /// Bytes of the composited G-buffers (pixel records and patch tables).
    pub gbuffer_bytes: u64,
    /// Patch-table entries over all composited regions.
    pub patch_table_entries: u64,
    /// Geometry and setup time, ms.
    pub geometry_ms: f64,
    /// Rasterization time (renderers, including patch location), ms.
    pub raster_ms: f64,
    /// Time the compositor spent merging, ms (overlaps rasterization: the stages are pipelined).
    pub composition_ms: f64,
    /// Deferred shading and resolve time, ms.
    pub shading_ms: f64,
    /// geometry + raster + composition + shading, ms.
    pub frame_ms: f64,
}

/// A rendered frame.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB radiosity per pixel, row-major, row 0 at the top.
    pub pixels: Vec<Vec3>,
    /// Statistics.
    pub stats: FrameStats,
}

/// Geometry and setup for a frame: the primitives that reach the rasterizer, in polygon order.
pub fn build_primitives(scene: &Scene, camera: &Camera, opts: &FrameOptions) -> Result<Vec<Prim>> {
    let (lo, hi) = scene.bounds();
    let extent = (hi - lo)
        .length()
        .max(((lo + hi) * 0.5 - camera.eye).length());
    let view = geometry::View::new(camera, opts.width, opts.height, extent)?;
    let (w, h, cull) = (opts.width, opts.height, opts.cull_back_faces);
    Ok(scene
        .polygons
        .par_iter()
        .enumerate()
        .filter_map(|(i, p)| {
            let sp = view.transform(p, i as u32)?;
            if cull && !sp.front_facing {
                return None;
            }
            setup::setup(&sp, w, h)
        })
        .collect())
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Renders one frame of `scene` seen by `camera`, every visible sample shaded from `source`'s
/// bicubic patches (the direct method). Runs in the current rayon pool.
pub fn render_frame(
    scene: &Scene,
    camera: &Camera,
    source: &dyn PatchSource,
    opts: &FrameOptions,
) -> Result<Frame> {
    render_frame_with(scene, camera, &Shader::Patches(source), opts)
}

/// Renders one frame of `scene` seen by `camera` with any deferred [`Shader`]: the stages up to
/// composition are the same for every method; only a patch shader makes the rasterizer fill the
/// regions' patch tables. `stats.method` is `direct` for a patch shader, `texture` or
/// `reference` otherwise (the pipeline names the method precisely). Runs in the current rayon
/// pool.
pub fn render_frame_with(
    scene: &Scene,
    camera: &Camera,
    shader: &Shader<'_>,
    opts: &FrameOptions,
) -> Result<Frame> {
    let source = shader.patch_source();
    opts.validate()?;
    let offsets = sample_offsets(opts.aa)?;
    let background = scene.display.background.as_vec3();
    let background = if background.is_finite() {
        background
    } else {
        Vec3::ZERO
    };

    let t_geom = Instant::now();
    let prims = build_primitives(scene, camera, opts)?;
    let grid = RegionGrid::new(opts.width, opts.height, opts.region);
    let r_count = opts.renderers as usize;
    // Round-robin distribution: the k-th primitive goes to renderer k mod R.
    let bins: Vec<Vec<Vec<u32>>> = (0..r_count)
        .map(|r| grid.bin(prims.iter().enumerate().filter(|(k, _)| k % r_count == r)))
        .collect();
    let mut expected = vec![0u32; grid.count()];
    let mut work: Vec<(u32, u32)> = Vec::new();
    for (reg, e) in expected.iter_mut().enumerate() {
        for (r, b) in bins.iter().enumerate() {
            if !b[reg].is_empty() {
                *e += 1;
                work.push((r as u32, reg as u32));
            }
        }
    }
    let geometry_ms = ms(t_geom.elapsed());

    let (tx_r, rx_r) = crossbeam::channel::unbounded::<RegionReport>();
    let (tx_c, rx_c) = crossbeam::channel::unbounded::<RegionGBuffer>();
    let mut raster_ms = 0.0;
    let mut composited: Vec<RegionGBuffer> = Vec::new();
    let comp_stats = std::thread::scope(|scope| {
        let expected = &expected;
        let compositor = scope.spawn(move || composition::compositor(rx_r, tx_c, expected));
        let t_raster = Instant::now();
        work.par_iter().for_each_with(tx_r, |tx, &(r, reg)| {
            let (x0, y0, w, h) = grid.rect(reg);
            let mut gb = RegionGBuffer::new(reg, x0, y0, w, h, offsets.len() as u32);
            let mut fragments = 0;
            for &k in &bins[r as usize][reg as usize] {
                fragments += region::rasterize(&prims[k as usize], &mut gb, offsets);
            }
            if let Some(source) = source {
                gb.assign_patches(source);
            }
            // A send fails only if the compositor is gone, which the join below reports.
            let _ = tx.send(RegionReport {
                renderer: r,
                fragments,
                gbuffer: gb,
            });
        });
        raster_ms = ms(t_raster.elapsed());
        // The shading stage's input: every composited region, as the compositor finishes it.
        composited = rx_c.into_iter().collect();
        compositor.join()
    })
    .map_err(|_| Error::Runtime("the compositor thread failed".into()))?;
    let t_shade = Instant::now();
    let (pixels, counts) = shading::shade_regions(
        shader,
        &composited,
        background,
        opts.width,
        opts.height,
        opts.region,
    );
    let shading_ms = ms(t_shade.elapsed());

    let mut stats = FrameStats {
        width: opts.width,
        height: opts.height,
        method: match shader {
            Shader::Patches(_) => "direct",
            Shader::Texture { .. } => "texture",
            Shader::Exact(_) => "reference",
        }
        .into(),
        threads: rayon::current_num_threads(),
        renderers: opts.renderers,
        aa: opts.aa,
        region_size: opts.region,
        regions_touched: expected.iter().filter(|&&e| e > 0).count() as u32,
        primitives: prims.len() as u32,
        pixels_rasterized: comp_stats.fragments,
        pixels_shaded: counts.samples_shaded,
        composition_traffic_bytes: comp_stats.traffic_bytes,
        geometry_ms,
        raster_ms,
        composition_ms: ms(comp_stats.busy),
        shading_ms,
        ..FrameStats::default()
    };
    for gb in &composited {
        stats.gbuffer_bytes += gb.bytes();
        stats.patch_table_entries += gb.table.len() as u64;
    }
    stats.frame_ms = stats.geometry_ms + stats.raster_ms + stats.composition_ms + stats.shading_ms;
    Ok(Frame {
        width: opts.width,
        height: opts.height,
        pixels,
        stats,
    })
}
