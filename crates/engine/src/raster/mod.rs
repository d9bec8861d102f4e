//! Rasterization: the PixelFlow emulator's renderers. Given a scene, a camera and an image size,
//! [`build_primitives`] runs [`geometry`] (view, projection, near-plane and guard-band clipping,
//! back-face policy) and [`setup`] (fixed-point edge functions, top-left rule), with a fused path
//! for triangles that need no clipping (`triangles`, the bulk of a mesh);
//! [`bin_round_robin_into`] deals the primitives to R virtual renderers and bins each renderer's
//! share per screen region ([`region::RegionGrid`]); a frame does both in one pass,
//! [`build_and_bin_into`], binning chunk by chunk ([`binning`]); [`rasterize_region_into`] is one renderer's
//! work on one region: 8-lane block rasterization into a [`gbuffer::RegionGBuffer`], with each visible
//! sample's radiosity patch located and copied into a region-local table. Running these for a
//! frame, merging the renderers' regions and shading them is the `frame` stage's job.
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
pub mod binning;
mod triangles;

use glam::DVec3;
use lanes::Isa;
use rayon::prelude::*;

use base::error::Result;
use base::method::Aa;
use reconstruction::PatchSource;
use scene::{Camera, Scene, Shape};

use gbuffer::{PatchScratch, RegionGBuffer};
use region::RegionGrid;
use setup::Prim;

/// Default region side in pixels (PixelFlow's 1992 SIMD array).
pub(crate) const DEFAULT_REGION: u32 = 128;

/// Most virtual renderers accepted.
pub(crate) const MAX_RENDERERS: u32 = 64;

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

/// The sample pattern for `aa` samples per pixel: offsets within the pixel.
pub fn sample_offsets(aa: Aa) -> &'static [(f32, f32)] {
    match aa.samples() {
        1 => &CENTRE,
        4 => &ROTATED_GRID,
        _ => &STRATIFIED_16,
    }
}

/// The side of one sample's share of a pixel when the pixel has `samples` samples: 1, 1/2, 1/4
/// for 1, 4, 16 (exact powers of two; 0 samples count as 1).
///
/// A texture lookup's level of detail is taken at this footprint, not the pixel's: the samples
/// of a pixel are box-filtered afterwards, so a lookup filtered over the whole pixel would
/// filter the texture twice, blurring a shadow's edge over about two pixels where the direct
/// method's samples resolve it (what supersampling hardware does too: its derivatives are
/// taken between samples, a sample's spacing apart).
pub fn sample_spacing(samples: u32) -> f32 {
    1.0 / (samples.max(1) as f32).sqrt()
}

/// Geometry and setup for a frame: the primitives that reach the rasterizer, in polygon order.
/// `width` x `height` is the image size; with `cull_back_faces`, polygons facing away from the
/// camera are dropped (see [`geometry`]).
pub fn build_primitives(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    cull_back_faces: bool,
) -> Result<Vec<Prim>> {
    let mut prims = Vec::new();
    build_primitives_into(scene, camera, width, height, cull_back_faces, &mut prims)?;
    prims.retain(|p| !p.is_empty());
    Ok(prims)
}

/// Geometry and setup for a frame into `prims`, one record per scene polygon (`prims[i]` is
/// polygon i's): a polygon that does not reach the rasterizer (clipped away, culled, off screen,
/// covering no sample) leaves an empty record ([`Prim::is_empty`]), which binning skips. Keeping
/// the polygon order by position, rather than compacting, lets every polygon be set up in
/// parallel straight into its own record: no staging buffer, no sequential copy of the records
/// (a 6 MB copy for the 16.5 k triangles of a mesh). `prims` keeps its capacity across frames,
/// so a warm frame allocates nothing.
pub fn build_primitives_into(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    cull_back_faces: bool,
    prims: &mut Vec<Prim>,
) -> Result<()> {
    let view = frame_view(scene, camera, width, height)?;
    let n = scene.polygons.len();
    prims.truncate(n);
    prims.resize_with(n, Prim::default);
    prims
        .par_iter_mut()
        .zip(scene.polygons.par_iter())
        .enumerate()
        .with_min_len(64)
        .for_each(|(i, (out, p))| {
            set_up(&view, p, i as u32, cull_back_faces, out);
        });
    Ok(())
}

/// [`build_primitives_into`] and [`bin_round_robin_into`] in one parallel pass: each chunk of
/// polygons is set up and binned while its records are in cache (binning afterwards, on one
/// thread, would re-read every record: a tenth of a 10^5-triangle mesh's frame), and the chunks'
/// lists are joined in chunk order, so `bins` holds exactly what the two calls would give.
/// `chunks` is working memory kept across frames. Returns the number of primitives binned.
///
/// The view needs the scene's bounds and nearest polygon, a pass over every polygon of its
/// own before setup can start (a sixth of a 10^5-triangle mesh's geometry stage). With
/// `guess`, the previous frame's scene bounds, the view is built from them with the near plane
/// at its largest (what it is unless a polygon comes within twice that of the eye), the chunks
/// measure the true bounds as they set up their polygons, and the frame is set up again with
/// the true view only if it differs: the records are always those of the true view. `guess`
/// is then updated for the next frame (emptied when guessing would not have given this frame's
/// view).
#[allow(clippy::too_many_arguments)]
pub fn build_and_bin_into(
    scene: &Scene,
    camera: &Camera,
    (width, height): (u32, u32),
    cull_back_faces: bool,
    grid: &RegionGrid,
    renderers: u32,
    prims: &mut Vec<Prim>,
    chunks: &mut Vec<binning::ChunkBins>,
    bins: &mut Vec<Vec<Vec<u32>>>,
    guess: &mut Option<ViewBounds>,
) -> Result<u32> {
    let guessed = |b: &ViewBounds| {
        let far = ViewBounds {
            nearest: f64::INFINITY,
            ..*b
        };
        far.view(scene, camera, width, height)
    };
    let (view, speculative) = match guess.take() {
        Some(b) => (guessed(&b)?, true),
        None => (frame_view(scene, camera, width, height)?, false),
    };
    let n = scene.polygons.len();
    prims.truncate(n);
    prims.resize_with(n, Prim::default);
    let r_count = renderers.max(1) as usize;
    let size = binning::chunk_size(n);
    let n_chunks = n.div_ceil(size);
    chunks.resize_with(n_chunks, binning::ChunkBins::default);
    chunks.truncate(n_chunks);
    let pass = ChunkPass {
        scene,
        eye: camera.eye,
        cull: cull_back_faces,
        grid,
        renderers: r_count,
        size,
    };
    let found = pass.run(&view, prims, chunks);
    let exact = found.view(scene, camera, width, height)?;
    debug_assert!(
        speculative || exact == view,
        "the chunks' bounds are frame_view's"
    );
    if speculative && exact != view {
        pass.run(&exact, prims, chunks);
    }
    // Guessing next frame pays off when it would have given this frame's view.
    if guessed(&found)? == exact {
        *guess = Some(found);
    }
    Ok(binning::join(grid, chunks, r_count, bins))
}

/// The chunked setup and binning pass of [`build_and_bin_into`].
struct ChunkPass<'a> {
    scene: &'a Scene,
    eye: DVec3,
    cull: bool,
    grid: &'a RegionGrid,
    renderers: usize,
    /// Polygons per chunk.
    size: usize,
}

impl ChunkPass<'_> {
    /// Sets up every polygon with `view` into its record and bins it into its chunk's lists,
    /// chunks in parallel; returns the view bounds of every polygon, measured on the way.
    fn run(
        &self,
        view: &geometry::View,
        prims: &mut [Prim],
        chunks: &mut [binning::ChunkBins],
    ) -> ViewBounds {
        prims
            .par_chunks_mut(self.size)
            .zip(self.scene.polygons.par_chunks(self.size))
            .zip(chunks.par_iter_mut())
            .enumerate()
            .for_each(|(c, ((out, polys), local))| {
                local.reset(self.grid, self.renderers);
                let first = c * self.size;
                let mut bounds = ViewBounds::EMPTY;
                for (j, (out, p)) in out.iter_mut().zip(polys).enumerate() {
                    let i = (first + j) as u32;
                    bounds = bounds.merge(ViewBounds::of(p, self.eye));
                    if set_up(view, p, i, self.cull, out) {
                        local.push(self.grid, i, out);
                    }
                }
                local.bounds = bounds;
            });
        chunks
            .iter()
            .fold(ViewBounds::EMPTY, |a, c| a.merge(c.bounds))
    }
}

/// What a frame's view takes from the scene besides the camera: the bounds of its polygons'
/// corners and a lower bound of the distance from the eye to its nearest polygon (the larger
/// of its distance to a polygon's plane and to the polygon's corners' box), merged polygon by
/// polygon with min and max (exact, in any order).
#[derive(Clone, Copy, Debug)]
pub struct ViewBounds {
    lo: DVec3,
    hi: DVec3,
    nearest: f64,
}

impl Default for ViewBounds {
    fn default() -> Self {
        ViewBounds::EMPTY
    }
}

impl ViewBounds {
    /// Bounds of no polygon.
    pub const EMPTY: ViewBounds = ViewBounds {
        lo: DVec3::splat(f64::INFINITY),
        hi: DVec3::splat(f64::NEG_INFINITY),
        nearest: f64::INFINITY,
    };

    /// Polygon `p`'s bounds, seen from `eye`.
    #[inline]
    fn of(p: &scene::Polygon, eye: DVec3) -> ViewBounds {
        let (lo, hi) = p.vertices().iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), c| (lo.min(*c), hi.max(*c)),
        );
        ViewBounds {
            lo,
            hi,
            nearest: geometry::distance_lower_bound(p, lo, hi, eye),
        }
    }

    /// Both bounds together.
    #[inline]
    fn merge(self, o: ViewBounds) -> ViewBounds {
        ViewBounds {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            nearest: self.nearest.min(o.nearest),
        }
    }

    /// The view of `camera` for a `width` x `height` frame of `scene` with these bounds.
    fn view(
        &self,
        scene: &Scene,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<geometry::View> {
        let (lo, hi) = scene.bounds_with(self.lo, self.hi);
        let extent = (hi - lo)
            .length()
            .max(((lo + hi) * 0.5 - camera.eye).length());
        geometry::View::new(camera, width, height, extent, self.nearest)
    }
}

/// The view of `camera` for a `width` x `height` frame of `scene`: the scene's bounds and the
/// nearest polygon (for the near plane) in one parallel pass.
fn frame_view(scene: &Scene, camera: &Camera, width: u32, height: u32) -> Result<geometry::View> {
    let eye = camera.eye;
    scene
        .polygons
        .par_iter()
        .map(|p| ViewBounds::of(p, eye))
        .reduce(|| ViewBounds::EMPTY, ViewBounds::merge)
        .view(scene, camera, width, height)
}

/// Geometry and setup of polygon `p` (scene index `i`) into its record `out`: the triangle fast
/// path where it applies, the general path otherwise; an empty record (and `false`) when the
/// polygon reaches no sample or is culled.
#[inline]
fn set_up(view: &geometry::View, p: &scene::Polygon, i: u32, cull: bool, out: &mut Prim) -> bool {
    let fast = if p.shape == Shape::Triangle {
        triangles::triangle_into(view, p, i, cull, out)
    } else {
        triangles::Outcome::General
    };
    let set = match fast {
        triangles::Outcome::Set => true,
        triangles::Outcome::Rejected => false,
        triangles::Outcome::General => match view.transform(p, i) {
            Some(sp) if !geometry::culled(cull, p, sp.front_facing) => {
                let (w, h) = view.size();
                setup::setup_into(&sp, w, h, out)
            }
            _ => false,
        },
    };
    if !set {
        // Marks the record empty; its other fields are never read.
        out.n_edges = 0;
    }
    set
}

/// Round-robin distribution of the non-empty records of `prims` over `renderers` virtual
/// renderers (the k-th primitive to renderer k mod R), each renderer's share binned per region of
/// `grid` into `bins[renderer][region]` (indices into `prims`, in increasing order), reusing the
/// lists' capacity (a warm frame allocates nothing). Returns the number of primitives binned.
pub fn bin_round_robin_into(
    grid: &RegionGrid,
    prims: &[Prim],
    renderers: u32,
    bins: &mut Vec<Vec<Vec<u32>>>,
) -> u32 {
    let r_count = renderers.max(1) as usize;
    bins.resize_with(r_count, Vec::new);
    bins.truncate(r_count);
    for b in bins.iter_mut() {
        b.resize_with(grid.count(), Vec::new);
        b.truncate(grid.count());
        for list in b.iter_mut() {
            list.clear();
        }
    }
    let mut k = 0;
    for (i, p) in prims.iter().enumerate() {
        if p.is_empty() {
            continue;
        }
        grid.bin_one(i as u32, p, &mut bins[k % r_count]);
        k += 1;
    }
    k as u32
}

/// Asks the cache for every line of `x` (a hint: no effect on any result).
#[inline(always)]
fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = x as *const T as *const i8;
        for off in (0..std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: a prefetch never faults; the addresses lie inside `x` anyway.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(off)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// One renderer's work on one region, with the instruction set `isa`: resets `gb` to region `reg` of `grid`
/// (`RegionGBuffer::reset`), rasterizes the primitives `ids` (indices into `prims`, in
/// increasing order) at every sample offset into it, then, if the method has patches, locates
/// each visible sample's patch in `source` and fills the region's patch table, with the patch
/// location's working memory in `scratch`. Returns the fragments rasterized (covered samples
/// before the depth test).
#[allow(clippy::too_many_arguments)]
pub fn rasterize_region_into(
    isa: Isa,
    grid: &RegionGrid,
    reg: u32,
    prims: &[Prim],
    ids: &[u32],
    offsets: &[(f32, f32)],
    source: Option<&dyn PatchSource>,
    gb: &mut RegionGBuffer,
    scratch: &mut PatchScratch,
) -> u64 {
    let (x0, y0, w, h) = grid.rect(reg);
    gb.reset(reg, x0, y0, w, h, offsets.len() as u32);
    let mut fragments = 0;
    for (j, &k) in ids.iter().enumerate() {
        // The next record is requested while this one is drawn: a renderer's share of a region
        // is every R-th primitive, a stride the hardware prefetcher does not follow, and its
        // first touch otherwise stalls the kernel's setup.
        if let Some(&next) = ids.get(j + 1) {
            prefetch(&prims[next as usize]);
        }
        fragments += region::rasterize(isa, &prims[k as usize], gb, offsets);
    }
    if let Some(source) = source {
        gb.assign_patches_with(source, scratch);
    }
    fragments
}
