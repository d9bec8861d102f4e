//! Frame: one frame through every stage after the scene and its radiosity reconstruction exist.
//! [`render`] takes the scene (or, for the mesh method, the mesh's triangles), a camera, the
//! method's deferred [`Shader`] and the [`FrameOptions`], and runs, in order:
//! geometry and setup ([`raster::build_primitives`]) -> round-robin distribution over R virtual
//! renderers and binning per region ([`raster::bin_round_robin`]) -> the renderers, in parallel,
//! each rasterizing its regions ([`raster::rasterize_region`]) and sending them down a crossbeam
//! channel -> the compositor thread ([`crate::composition`]), which merges each region by depth as
//! soon as every renderer that touched it has reported -> the deferred pass over the composited
//! regions ([`crate::shading`]) -> the supersampling resolve. It fills [`FrameStats`]: counters,
//! per-stage times and the wall-clock frame time.
//!
//! Invariants: the image depends only on the scene, the camera, the shader's data, the image size
//! and the sample count: it is bit-identical for any number of threads and of renderers (stable
//! polygon-id tie-breaks in composition, canonical patch tables, per-region work with no
//! cross-region reduction, counters summed in a fixed order). No output pixel is NaN or infinite.
//! Every option is validated ([`FrameOptions::validate`]) before any work.
//!
//! Why a stage of its own: the rasterizer only rasterizes, the compositor only merges, the shaders
//! only shade; the frame is where they are wired together and timed, so each of them can be tested
//! and benchmarked alone.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;

use crate::composition::{self, RegionReport};
use crate::error::{Error, Result};
use crate::image::ImageView;
use crate::method::Method;
use crate::raster::gbuffer::RegionGBuffer;
use crate::raster::region::RegionGrid;
use crate::raster::{self, sample_offsets, DEFAULT_REGION, MAX_RENDERERS};
use crate::reconstruction::PatchSource;
use crate::scene::{Camera, Scene, MAX_IMAGE_DIM};
use crate::shading::{self, Shader};

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
    /// Cull polygons whose back faces the camera (off by default; see [`crate::raster::geometry`]).
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

    /// Checks every option; a bad value is an [`Error::InvalidOption`] naming the command-line
    /// option, a size or renderer count over the limit an [`Error::ResourceLimit`].
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("--width", self.width), ("--height", self.height)] {
            if v == 0 {
                return Err(Error::invalid_option(name, "0", "must be at least 1"));
            }
            if v > MAX_IMAGE_DIM {
                return Err(Error::limit(name, v.into(), MAX_IMAGE_DIM.into()));
            }
        }
        crate::method::check_aa("--aa", self.aa)?;
        if self.renderers == 0 {
            return Err(Error::invalid_option(
                "--renderers",
                "0",
                "must be at least 1",
            ));
        }
        if self.renderers > MAX_RENDERERS {
            return Err(Error::limit(
                "--renderers",
                self.renderers.into(),
                MAX_RENDERERS.into(),
            ));
        }
        if self.region < 8 || self.region > 1024 || !self.region.is_multiple_of(8) {
            return Err(Error::invalid_option(
                "--region",
                self.region.to_string(),
                "must be a multiple of 8 in 8..=1024",
            ));
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
    /// Rendering method ([`Method::name`]).
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
    /// geometry + raster + composition + shading, ms. Composition overlaps rasterization (the
    /// compositor merges regions while renderers still rasterize others), so this sum overstates
    /// the frame; it says where the work went, [`FrameStats::frame_ms`] how long the frame took.
    pub stage_sum_ms: f64,
    /// Wall-clock time of the whole frame, from the first geometry step to the last resolved
    /// pixel, ms. Frame rates (`fps`) are `1000 / frame_ms`.
    pub frame_ms: f64,
    /// Blocks of 8 samples the deferred pass evaluated with one broadcast patch (texture
    /// methods: one polygon's texture).
    pub uniform_blocks: u64,
    /// Blocks that mixed patches (texture methods: polygons) or held empty samples, evaluated
    /// lane by lane.
    pub mixed_blocks: u64,
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

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

impl Frame {
    /// The frame's pixels, borrowed as an image (for [`crate::image::write_png`] and friends).
    pub fn view(&self) -> ImageView<'_> {
        ImageView {
            width: self.width,
            height: self.height,
            pixels: &self.pixels,
        }
    }
}

/// Renders one frame of `scene` seen by `camera`, every visible sample shaded from `source`'s
/// bicubic patches (the direct method; the mesh method passes its triangles and their patches).
/// Runs in the current rayon pool.
pub fn render_patches(
    scene: &Scene,
    camera: &Camera,
    source: &dyn PatchSource,
    opts: &FrameOptions,
) -> Result<Frame> {
    render(
        scene,
        camera,
        &Shader::Patches(source),
        Method::Direct,
        opts,
    )
}

/// Renders one frame of `scene` seen by `camera` with any deferred [`Shader`]: the stages up to
/// composition are the same for every method; only a patch shader makes the rasterizer fill the
/// regions' patch tables. `method` only names the frame in its statistics. Runs in the current
/// rayon pool.
pub fn render(
    scene: &Scene,
    camera: &Camera,
    shader: &Shader<'_>,
    method: Method,
    opts: &FrameOptions,
) -> Result<Frame> {
    let source = shader.patch_source();
    opts.validate()?;
    let t_frame = Instant::now();
    let offsets = sample_offsets(opts.aa)?;
    let background = scene.display.background.as_vec3();
    let background = if background.is_finite() {
        background
    } else {
        Vec3::ZERO
    };

    let t_geom = t_frame;
    let prims =
        raster::build_primitives(scene, camera, opts.width, opts.height, opts.cull_back_faces)?;
    let grid = RegionGrid::new(opts.width, opts.height, opts.region);
    let bins = raster::bin_round_robin(&grid, &prims, opts.renderers);
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
            let ids = &bins[r as usize][reg as usize];
            let (gb, fragments) =
                raster::rasterize_region(&grid, reg, &prims, ids, offsets, source);
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
        method: method.name().into(),
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
        uniform_blocks: counts.uniform_blocks,
        mixed_blocks: counts.mixed_blocks,
        ..FrameStats::default()
    };
    for gb in &composited {
        stats.gbuffer_bytes += gb.bytes();
        stats.patch_table_entries += gb.table.len() as u64;
    }
    stats.stage_sum_ms =
        stats.geometry_ms + stats.raster_ms + stats.composition_ms + stats.shading_ms;
    stats.frame_ms = ms(t_frame.elapsed());
    Ok(Frame {
        width: opts.width,
        height: opts.height,
        pixels,
        stats,
    })
}
