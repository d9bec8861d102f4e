//! Frame: one frame through every stage after the scene and its radiosity reconstruction exist.
//! [`FrameContext::render`] takes the scene (or, for the mesh method, the mesh's triangles), a
//! camera, the method's deferred [`Shader`] and the [`FrameOptions`], and runs, in order:
//! geometry and setup, round-robin distribution over R virtual renderers and binning per region
//! (one parallel pass, [`raster::build_and_bin_into`]) -> one parallel
//! task per region: each renderer with primitives there rasterizes its share into a pooled
//! G-buffer ([`raster::rasterize_region_into`]), the compositor merges each one's pixel records
//! by depth into the region's composite as soon as it is drawn
//! ([`crate::composition::merge_records_into`]), the merged region's patches are
//! located once ([`crate::raster::gbuffer::RegionGBuffer::assign_patches_with`]) and the deferred
//! pass shades the result straight into the frame ([`crate::shading::shade_region_rows`]),
//! resolving the samples of each pixel.
//! It fills [`FrameStats`]: counters, per-stage times and the wall-clock frame time.
//!
//! Memory: a [`FrameContext`] owns every buffer a frame uses and keeps it across frames (a
//! walkthrough, a benchmark), so a warm frame allocates nothing and touches no new page; a
//! region's G-buffers return to the pool as soon as it is shaded, and each renderer's report is
//! merged as soon as it is drawn, so the G-buffer memory is two regions per worker, whatever the
//! number of renderers or regions. [`render`] is the one-frame convenience.
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
use lanes::Isa;
use rayon::prelude::*;
use reconstruction::texture::MAX_ANISOTROPY;
use serde::Serialize;

use std::sync::Mutex;
use std::time::Duration;

use crate::composition;
use crate::raster::gbuffer::{PatchScratch, RegionGBuffer};
use crate::raster::region::RegionGrid;
use crate::raster::{self, sample_offsets, DEFAULT_REGION, MAX_RENDERERS};
use crate::shading::{self, Rows, ShadeCounts, Shader};
use base::error::{Error, Result};
use base::image::ImageView;
use base::method::{Aa, Method};
use reconstruction::PatchSource;
use scene::{Camera, Scene, MAX_IMAGE_DIM};

/// What a frame is rendered with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel (checked where it was made).
    pub aa: Aa,
    /// Virtual renderers (1 to `MAX_RENDERERS`).
    pub renderers: u32,
    /// Region side in pixels: a multiple of 8 in 8..=1024.
    pub region: u32,
    /// Cull polygons whose back faces the camera (off by default; see [`crate::raster::geometry`]).
    pub cull_back_faces: bool,
    /// The instruction set the kernels run with (default [`Isa::detect`], the widest the CPU
    /// has): a choice of speed only, the image is the same for every one.
    pub isa: Isa,
    /// Texture methods: most lookups along a footprint's longer axis, 1 (isotropic, the
    /// paper's hardware; the default) to [`reconstruction::texture::MAX_ANISOTROPY`].
    pub anisotropy: u32,
}

impl FrameOptions {
    /// Options for a `width` x `height` image with the defaults: AA 1, 1 renderer, 128 regions.
    pub fn new(width: u32, height: u32) -> FrameOptions {
        FrameOptions {
            width,
            height,
            aa: Aa::ONE,
            renderers: 1,
            region: DEFAULT_REGION,
            cull_back_faces: false,
            isa: Isa::detect(),
            anisotropy: 1,
        }
    }

    /// Checks every option; a bad value is an [`Error::InvalidOption`] naming the setting
    /// (`width`, `renderers`), a size or renderer count over the limit an [`Error::ResourceLimit`].
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 {
                return Err(Error::invalid_option(name, "0", "must be at least 1"));
            }
            if v > MAX_IMAGE_DIM {
                return Err(Error::limit(name, v.into(), MAX_IMAGE_DIM.into()));
            }
        }
        if self.renderers == 0 {
            return Err(Error::invalid_option(
                "renderers",
                "0",
                "must be at least 1",
            ));
        }
        if self.renderers > MAX_RENDERERS {
            return Err(Error::limit(
                "renderers",
                self.renderers.into(),
                MAX_RENDERERS.into(),
            ));
        }
        if self.region < 8 || self.region > 1024 || !self.region.is_multiple_of(8) {
            return Err(Error::invalid_option(
                "region",
                self.region.to_string(),
                "must be a multiple of 8 in 8..=1024",
            ));
        }
        if !(1..=MAX_ANISOTROPY).contains(&self.anisotropy) {
            return Err(Error::invalid_option(
                "anisotropy",
                self.anisotropy.to_string(),
                format!("must be 1 (isotropic) to {MAX_ANISOTROPY}"),
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
    /// Rasterization time (renderers, including patch location), ms: the busy time summed over
    /// the region tasks, divided by the worker threads (the stage's share of the wall clock when
    /// every worker is busy). The three region stages are measured the same way.
    pub raster_ms: f64,
    /// Time spent merging renderers' regions, ms (per worker, as `raster_ms`).
    pub composition_ms: f64,
    /// Deferred shading and resolve time, ms (per worker, as `raster_ms`).
    pub shading_ms: f64,
    /// geometry + raster + composition + shading, ms: where the work went; it differs from
    /// [`FrameStats::frame_ms`], how long the frame took, by the idle time of the workers (load
    /// imbalance across regions) and the scheduling overhead.
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

impl FrameStats {
    /// Adds the regions' counters and stage times, summed in region order (deterministic), the
    /// busy times divided by the worker threads (the stages' shares of the wall clock).
    fn add_regions(&mut self, outcomes: &[RegionOutcome]) {
        let (mut raster, mut composition, mut shading) =
            (Duration::ZERO, Duration::ZERO, Duration::ZERO);
        for o in outcomes {
            self.regions_touched += (o.renderers > 0) as u32;
            self.pixels_rasterized += o.fragments;
            self.pixels_shaded += o.shade.samples_shaded;
            self.uniform_blocks += o.shade.uniform_blocks;
            self.mixed_blocks += o.shade.mixed_blocks;
            self.composition_traffic_bytes += o.traffic;
            self.gbuffer_bytes += o.gbuffer_bytes;
            self.patch_table_entries += o.table_entries;
            raster += o.raster;
            composition += o.composition;
            shading += o.shading;
        }
        let per_worker = |d: Duration| ms(d) / self.threads.max(1) as f64;
        self.raster_ms = per_worker(raster);
        self.composition_ms = per_worker(composition);
        self.shading_ms = per_worker(shading);
        self.stage_sum_ms =
            self.geometry_ms + self.raster_ms + self.composition_ms + self.shading_ms;
    }
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
    /// The frame's pixels, borrowed as an image (for the lab's image writers).
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
/// Runs in the current rayon pool, in a new [`FrameContext`] (a cold frame: use one context for
/// many frames).
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

/// Renders one frame of `scene` seen by `camera` with any deferred [`Shader`] in a new
/// [`FrameContext`] and returns it with its pixels (see [`FrameContext::render`]).
pub fn render(
    scene: &Scene,
    camera: &Camera,
    shader: &Shader<'_>,
    method: Method,
    opts: &FrameOptions,
) -> Result<Frame> {
    let mut ctx = FrameContext::new();
    let stats = ctx.render(scene, camera, shader, method, opts)?;
    Ok(ctx.into_frame(stats))
}

/// The working memory of a frame, kept across frames by its owner (a walkthrough, a benchmark):
/// the primitives and their bins, one workspace per worker in flight (its renderers' region
/// G-buffers, the merge's and the patch location's scratch), the per-region counters and the
/// frame itself. Every buffer keeps its capacity, so once a frame of a given size has been drawn,
/// the next allocates nothing and touches no new page; [`FrameContext::reserve`] does that
/// first-touch work ahead of the first frame.
///
/// Memory: two region G-buffers per worker thread (not per region: a region's buffers go back to
/// the pool as soon as it is shaded; not per renderer: each report is merged as soon as it is
/// drawn), plus the frame's pixels.
#[derive(Default)]
pub struct FrameContext {
    prims: Vec<raster::setup::Prim>,
    bins: Vec<Vec<Vec<u32>>>,
    chunk_bins: Vec<raster::binning::ChunkBins>,
    /// The last frame's scene bounds, to build the next view from ([`raster::build_and_bin_into`]).
    view_guess: Option<raster::ViewBounds>,
    outcomes: Vec<RegionOutcome>,
    pool: Mutex<Vec<Workspace>>,
    pixels: Vec<Vec3>,
    width: u32,
    height: u32,
}

/// One worker's buffers for one region at a time.
#[derive(Default)]
struct Workspace {
    /// `parts[0]`: the first renderer's report, then the composite; `parts[1]`: each later
    /// renderer's report in turn, merged into `parts[0]` as soon as it is drawn.
    parts: Vec<RegionGBuffer>,
    patches: PatchScratch,
}

/// What happened in one region (summed in region order: deterministic).
#[derive(Clone, Copy, Debug, Default)]
struct RegionOutcome {
    renderers: u32,
    fragments: u64,
    traffic: u64,
    gbuffer_bytes: u64,
    table_entries: u64,
    shade: ShadeCounts,
    raster: Duration,
    composition: Duration,
    shading: Duration,
}

/// A frame's pixels shared by the region tasks, each writing its own rectangle.
struct FrameTarget {
    ptr: *mut Vec3,
    width: usize,
    height: usize,
}

// SAFETY: the region tasks write disjoint rectangles (see `FrameTarget::rows`).
unsafe impl Sync for FrameTarget {}

impl FrameTarget {
    /// The rows of the rectangle (x0, y0, w, h).
    ///
    /// # Safety
    /// The rectangle lies inside the frame, and no other live `Rows` of this target overlaps it
    /// (the region grid's rectangles are disjoint and each region is one task).
    unsafe fn rows(&self, (x0, y0, w, h): (u32, u32, u32, u32)) -> Rows<'_> {
        let (x0, y0, w, h) = (x0 as usize, y0 as usize, w as usize, h as usize);
        assert!(x0 + w <= self.width && y0 + h <= self.height);
        // SAFETY: in bounds (asserted); exclusivity as promised by the caller.
        unsafe { Rows::from_raw(self.ptr.add(y0 * self.width + x0), self.width, w, h) }
    }
}

impl FrameContext {
    /// An empty context (allocates nothing until the first frame or [`FrameContext::reserve`]).
    pub fn new() -> FrameContext {
        FrameContext::default()
    }

    /// Allocates and touches, ahead of the first frame, the memory a frame with `opts` needs
    /// whatever the scene: the frame's pixels and the region G-buffers (one, or two with several
    /// renderers) of each worker of the current rayon pool. The first frame then costs what a
    /// warm one does (the primitive and bin arrays, which depend on the scene, are sized by that
    /// frame).
    ///
    /// The pages are first touched in parallel over the pool (each worker takes its share of
    /// the page faults), as the frame's own stages later write them.
    pub fn reserve(&mut self, opts: &FrameOptions) -> Result<()> {
        opts.validate()?;
        let n = opts.width as usize * opts.height as usize;
        first_touch(&mut self.pixels, n, Vec3::ZERO);
        (self.width, self.height) = (opts.width, opts.height);
        let side = opts.region.min(opts.width.max(opts.height));
        let pool = self.pool.get_mut().unwrap_or_else(|e| e.into_inner());
        let workers = rayon::current_num_threads();
        pool.resize_with(pool.len().max(workers), Workspace::default);
        pool.par_iter_mut().with_max_len(1).for_each(|ws| {
            ws.parts.resize_with(
                ws.parts.len().max(opts.renderers.min(2) as usize),
                Default::default,
            );
            for gb in ws.parts.iter_mut().take(opts.renderers.min(2) as usize) {
                gb.reset(0, 0, 0, side, side, opts.aa.samples());
                gb.u.fill(0.0);
                gb.v.fill(0.0);
                gb.slot.fill(0);
            }
        });
        Ok(())
    }

    /// [`FrameContext::reserve`], plus the primitive arrays for up to every polygon of `scene`
    /// (allocated and first touched): the first frame of `scene` then allocates nothing but its
    /// bins' lists.
    pub fn reserve_scene(&mut self, opts: &FrameOptions, scene: &Scene) -> Result<()> {
        self.reserve(opts)?;
        first_touch(
            &mut self.prims,
            scene.polygons.len(),
            raster::setup::Prim::default(),
        );
        Ok(())
    }

    /// Prepares every worker's workspace for frames shaded from `source`
    /// ([`PatchSource::warm`]: the compact RRPs' patch cache allocated, first touched and
    /// filled, in parallel over the current rayon pool), so the first frame does not pay for it.
    /// Call it after [`FrameContext::reserve`], which makes a workspace per worker.
    pub fn reserve_source(&mut self, source: &dyn PatchSource) {
        let pool = self.pool.get_mut().unwrap_or_else(|e| e.into_inner());
        pool.par_iter_mut()
            .with_max_len(1)
            .for_each(|ws| ws.patches.warm(source));
    }

    /// Bytes of the workspaces' patch caches (one per worker in flight).
    pub fn patch_cache_bytes(&mut self) -> usize {
        let pool = self.pool.get_mut().unwrap_or_else(|e| e.into_inner());
        pool.iter().map(|ws| ws.patches.cache_bytes()).sum()
    }

    /// The last frame as an owned [`Frame`] with `stats` (the context's buffers are dropped).
    pub fn into_frame(self, stats: FrameStats) -> Frame {
        Frame {
            width: self.width,
            height: self.height,
            pixels: self.pixels,
            stats,
        }
    }

    /// The last frame's linear RGB pixels, row-major, row 0 at the top.
    pub fn pixels(&self) -> &[Vec3] {
        &self.pixels
    }

    /// The last frame, borrowed as an image.
    pub fn view(&self) -> ImageView<'_> {
        ImageView {
            width: self.width,
            height: self.height,
            pixels: &self.pixels,
        }
    }

    /// Renders one frame of `scene` seen by `camera` with any deferred [`Shader`] into this
    /// context ([`FrameContext::pixels`]): the stages up to composition are the same for every
    /// method; only a patch shader makes the frame fill the regions' patch tables. `method`
    /// only names the frame in its statistics. Runs in the current rayon pool.
    ///
    /// Each region is one task: its renderers rasterize their shares into G-buffers from the
    /// pool, the compositor merges each one as soon as it is drawn, the merged region's patches
    /// are located, the deferred pass shades the result straight into the frame, and the
    /// buffers go back to the pool, still in cache for the next region. Regions run in parallel, so composition runs
    /// concurrently with other regions' rasterization (as PixelFlow's composition network did)
    /// and with R renderers the frame costs the rasterization of the same primitives plus the
    /// records merges.
    pub fn render(
        &mut self,
        scene: &Scene,
        camera: &Camera,
        shader: &Shader<'_>,
        method: Method,
        opts: &FrameOptions,
    ) -> Result<FrameStats> {
        let source = shader.patch_source();
        opts.validate()?;
        let t_frame = Instant::now();
        let offsets = sample_offsets(opts.aa);
        let background = scene.display.background.as_vec3();
        let background = if background.is_finite() {
            background
        } else {
            Vec3::ZERO
        };

        let grid = RegionGrid::new(opts.width, opts.height, opts.region);
        let primitives = raster::build_and_bin_into(
            scene,
            camera,
            (opts.width, opts.height),
            opts.cull_back_faces,
            &grid,
            opts.renderers,
            &mut self.prims,
            &mut self.chunk_bins,
            &mut self.bins,
            &mut self.view_guess,
        )?;
        let geometry_ms = ms(t_frame.elapsed());

        let n = opts.width as usize * opts.height as usize;
        // Every pixel is written below (shaded, or the background where no primitive was
        // binned), so a reused frame needs no clearing; a grown one is zero-filled once.
        self.pixels.resize(n, Vec3::ZERO);
        (self.width, self.height) = (opts.width, opts.height);
        self.outcomes.clear();
        self.outcomes.resize(grid.count(), RegionOutcome::default());
        let target = FrameTarget {
            ptr: self.pixels.as_mut_ptr(),
            width: opts.width as usize,
            height: opts.height as usize,
        };
        let pool = &self.pool;
        let inputs = RegionInputs {
            isa: opts.isa,
            grid: &grid,
            prims: &self.prims,
            bins: &self.bins,
            offsets,
            source,
            shader,
            background,
        };
        self.outcomes
            .par_iter_mut()
            .enumerate()
            .for_each(|(reg, out)| {
                let mut ws = pool
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .pop()
                    .unwrap_or_default();
                let reg = reg as u32;
                let rect = grid.rect(reg);
                // SAFETY: inside the frame (a grid rectangle) and disjoint from every other
                // region's, and this task is the only one for region `reg`.
                let mut rows = unsafe { target.rows(rect) };
                *out = region_task(&inputs, reg, &mut ws, &mut rows);
                pool.lock().unwrap_or_else(|e| e.into_inner()).push(ws);
            });

        let mut stats = FrameStats {
            width: opts.width,
            height: opts.height,
            method: method.name().into(),
            threads: rayon::current_num_threads(),
            renderers: opts.renderers,
            aa: opts.aa.samples(),
            region_size: opts.region,
            primitives,
            geometry_ms,
            ..FrameStats::default()
        };
        stats.add_regions(&self.outcomes);
        stats.frame_ms = ms(t_frame.elapsed());
        Ok(stats)
    }
}

/// Makes `v` hold `n` copies of `value`, writing them in parallel over the current rayon pool:
/// a new allocation's pages are first touched by every worker at once (and a reused one is
/// rewritten in place).
fn first_touch<T: Clone + Send + Sync>(v: &mut Vec<T>, n: usize, value: T) {
    v.clear();
    v.par_extend(rayon::iter::repeat_n(value, n));
}

/// What every region task of a frame reads.
#[derive(Clone, Copy)]
struct RegionInputs<'a> {
    isa: Isa,
    grid: &'a RegionGrid,
    prims: &'a [raster::setup::Prim],
    bins: &'a [Vec<Vec<u32>>],
    offsets: &'a [(f32, f32)],
    source: Option<&'a dyn PatchSource>,
    shader: &'a Shader<'a>,
    background: Vec3,
}

/// One region, start to finish: each renderer with primitives here rasterizes its share into a
/// G-buffer of the workspace, the compositor merges their pixel records into the first, the
/// patches of the merged region are located (methods with patches) and the deferred pass shades
/// it into `rows`; a region no renderer touched is filled with the background.
///
/// Patches are located once, after the merge, rather than by every renderer in its own share:
/// the table and slots are those the per-renderer tables merged in canonical order would give
/// (see [`composition::merge_records_into`]), so the image is the same, and with R renderers
/// the samples each renderer drew but another one hid are not located at all. Traffic is counted
/// as the composition module's model has it, with the region's table crossing the network once
/// on the way in (with the reports) and once on the way out.
fn region_task(
    inputs: &RegionInputs<'_>,
    reg: u32,
    ws: &mut Workspace,
    rows: &mut Rows<'_>,
) -> RegionOutcome {
    let RegionInputs {
        isa,
        grid,
        prims,
        bins,
        offsets,
        source,
        shader,
        background,
    } = *inputs;
    let mut out = RegionOutcome::default();
    // The composition network merges each report as its renderer finishes (a streaming merge,
    // as PixelFlow's pipelined z-compare did): renderer 0 draws into `parts[0]`, every later one
    // into `parts[1]`, which is merged into `parts[0]` at once and reused by the next: two
    // G-buffers per worker, whatever R.
    let (mut raster, mut composition) = (Duration::ZERO, Duration::ZERO);
    let mut used = 0;
    for bin in bins {
        let ids = &bin[reg as usize];
        if ids.is_empty() {
            continue;
        }
        let t0 = Instant::now();
        let k = used.min(1);
        if ws.parts.len() <= k {
            ws.parts.resize_with(k + 1, RegionGBuffer::default);
        }
        let gb = &mut ws.parts[k];
        out.fragments += raster::rasterize_region_into(
            isa,
            grid,
            reg,
            prims,
            ids,
            offsets,
            None,
            gb,
            &mut ws.patches,
        );
        out.traffic += gb.bytes();
        used += 1;
        let t1 = Instant::now();
        raster += t1 - t0;
        if k == 1 {
            let (head, rest) = ws.parts.split_at_mut(1);
            composition::merge_records_into(isa, &mut head[0], &rest[0]);
            composition += t1.elapsed();
        }
    }
    out.renderers = used as u32;
    if used == 0 {
        for y in 0..rows.height() {
            rows.row(y).fill(background);
        }
        return out;
    }
    let t2 = Instant::now();
    let gb = &mut ws.parts[0];
    if let Some(source) = source {
        gb.assign_patches_with(source, &mut ws.patches);
        out.traffic += gb.table.len() as u64 * raster::gbuffer::TABLE_ENTRY_BYTES;
    } else {
        // Shaders without patches never read a slot; the table is empty.
        debug_assert!(gb.table.is_empty());
    }
    let t3 = Instant::now();
    out.traffic += gb.bytes();
    out.gbuffer_bytes = gb.bytes();
    out.table_entries = gb.table.len() as u64;
    out.shade = shading::shade_region_rows(isa, shader, gb, background, rows);
    let t4 = Instant::now();
    // Patch location counts as rasterization (the renderers' work in the stage model).
    (out.raster, out.composition, out.shading) = (raster + (t3 - t2), composition, t4 - t3);
    out
}
