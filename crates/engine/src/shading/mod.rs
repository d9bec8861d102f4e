//! Shading: the deferred pass, the last stage before the image is written. It reads only a
//! composited region G-buffer ([`RegionGBuffer`]: per sample a polygon id, (u, v) and a slot into
//! the region-local patch table) and evaluates the bicubic radiosity reconstruction patch (RRP) of
//! each sample, then resolves the samples of each pixel with a box filter. It never sees the scene,
//! as PixelFlow's shader boards never saw it: everything a sample needs was written into the region
//! by the rasterizer, so shading cost depends on pixels, not on scene complexity.
//!
//! Invariants: a patch is a power-basis bicubic over local (s, t) in [0, 1]^2; a sample with
//! [`NO_POLYGON`] takes the background colour; the result is a finite, non-negative linear RGB
//! value per pixel. The only clamp of the image sits in the pixel resolve ([`Simd::sanitize`]): after
//! the box filter, a negative or non-finite channel becomes 0 (bicubic patches and the Mitchell
//! filter can ring below zero next to a sharp shadow; every method passes through it).
//!
//! Why it is built this way: neighbouring samples nearly always share one patch, so each group of
//! samples (8, or 16 on AVX-512) is evaluated with one patch's coefficients broadcast over the
//! lanes (`patches`); groups that mix patches or contain empty samples evaluate each distinct
//! patch and merge through masks. Every lane performs the scalar rule's IEEE operations in its
//! order ([`shade_sample`]; Rust never contracts `a * b + c` into an FMA), so neither the path a
//! sample takes nor the instruction set ([`lanes::Isa`]) changes its bits.
//!
//! The radiosity-texture (RAT) method runs the same block structure (`texture`): per block of
//! 8 samples the (u, v) derivatives, the level of detail and the filter are computed in lanes
//! ([`reconstruction::texture::Sampler::sample8`]) with the texels gathered per lane, one lane
//! group per distinct polygon of the block, so that the direct-versus-texture comparison sets
//! two equally careful inner loops against each other. It too reproduces its scalar
//! sample-by-sample form bit for bit (kept as the tests' reference).
//!
//! Antialiasing filter: every pixel's N samples (see [`crate::raster::sample_offsets`]) are
//! averaged with equal weights, a box filter over the pixel's own square; samples that see nothing
//! contribute the background colour.
//!
//! The module is split by shader: `patches` (the direct method and the Gouraud mesh: patch
//! tables) and `texture` (the RAT filters); this file holds what every shader shares: the
//! [`Shader`] choice, the plane-order accumulation and box-filter resolve every lane shader ends
//! its blocks and rows with, the per-sample form used by the reference shader, and the frame pass over
//! all regions. The two lane shaders keep their own row and block loops: folding them into one
//! generic block driver measured 25-40 % slower on the RRP pass (criterion, `deferred/rrp-1024`),
//! so the loops stay written out.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

mod patches;
mod texture;

use glam::Vec3;
use rayon::prelude::*;

use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};
use lanes::{sanitize1, Isa, Simd, LANES};
use reconstruction::texture::{Filter, TextureSet};

pub use patches::shade_sample;
pub use reconstruction::{PatchCoeffs, PatchSource};

/// The radiosity of a polygon at (u, v), for [`Shader::Reference`].
pub(crate) type ReferenceFn<'a> = dyn Fn(u32, f32, f32) -> Vec3 + Sync + 'a;

/// What the deferred pass evaluates at each visible sample: the one place where the rendering
/// methods differ (everything before it, rasterization and composition, is shared).
#[derive(Clone, Copy)]
pub enum Shader<'a> {
    /// The region's patch table, filled by the rasterizer from this source: the direct method
    /// (RRPs), and the Gouraud mesh (one degree-(1, 1) patch per triangle).
    Patches(&'a dyn PatchSource),
    /// The Gouraud mesh's triangles (`patches[k]` for scene polygon k), each sample's patch read
    /// by its polygon: the same bits as [`Shader::Patches`] over the mesh as a patch source
    /// ([`reconstruction::mesh::MeshModel`]), with no patch table to fill. A polygon without a
    /// patch is black.
    Gouraud(&'a [reconstruction::mesh::GouraudPatch]),
    /// The polygon's radiosity texture, filtered, at a per-sample level of detail (RAT).
    Texture {
        /// Every polygon's texture (the texture memory every shader board would hold).
        set: &'a TextureSet,
        /// The on-screen filter.
        filter: Filter,
        /// Most taps of one lookup along a footprint's longer axis: 1 filters isotropically
        /// (the paper's hardware), more anisotropically up to
        /// [`reconstruction::texture::MAX_ANISOTROPY`] ([`crate::frame::FrameOptions::anisotropy`]).
        anisotropy: u32,
    },
    /// A function of (polygon, u, v), evaluated per sample: the reference (the solver's oracle).
    Reference(&'a ReferenceFn<'a>),
}

impl Shader<'_> {
    /// The patch source whose patches the rasterizer must copy into the regions, if any.
    pub(crate) fn patch_source(&self) -> Option<&dyn PatchSource> {
        match self {
            Shader::Patches(s) => Some(*s),
            _ => None,
        }
    }
}

/// Counters of one shading pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ShadeCounts {
    /// Samples that saw a polygon and were evaluated.
    pub samples_shaded: u64,
    /// Blocks of 8 evaluated with one broadcast patch (texture methods: one polygon's texture).
    pub uniform_blocks: u64,
    /// Blocks that mix patches (texture methods: polygons) or contain empty samples.
    pub mixed_blocks: u64,
}

/// Shades one composited region with any [`Shader`] into `dst`, whose element 0 is the region's
/// top-left pixel and whose rows are `pitch` pixels apart (a frame: pitch = frame width), with
/// the instruction set `isa`; the pixels do not depend on it.
pub fn shade_region_with(
    isa: Isa,
    shader: &Shader<'_>,
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    let mut rows = Rows::new(dst, pitch, gb.width as usize, gb.height as usize);
    shade_region_rows(isa, shader, gb, background, &mut rows)
}

/// Shades one composited region with any [`Shader`] into `rows` (`gb.width` x `gb.height`
/// pixels), with the instruction set `isa`.
pub fn shade_region_rows(
    isa: Isa,
    shader: &Shader<'_>,
    gb: &RegionGBuffer,
    background: Vec3,
    rows: &mut Rows<'_>,
) -> ShadeCounts {
    assert!(
        rows.width == gb.width as usize && rows.height == gb.height as usize,
        "rows do not match the region"
    );
    match *shader {
        Shader::Patches(_) => {
            patches::shade_region_rows(isa, patches::Source::Table, gb, background, rows)
        }
        Shader::Gouraud(g) => {
            let source = patches::Source::Gouraud(g);
            patches::shade_region_rows(isa, source, gb, background, rows)
        }
        Shader::Texture {
            set,
            filter,
            anisotropy,
        } => {
            texture::shade_region_texture_rows(isa, set, (filter, anisotropy), gb, background, rows)
        }
        Shader::Reference(func) => {
            let f = |i: usize, _: usize, _: usize| func(gb.polygon[i], gb.u[i], gb.v[i]);
            shade_region_per_sample(gb, background, rows, f)
        }
    }
}

/// Shades one region sample by sample with `f(index, x, y)` (index into the G-buffer's planes,
/// region-local column and row; called only for samples that see a polygon), accumulating the
/// samples of each pixel in plane order and resolving them exactly as the patch path does (box
/// filter, then the clamp of [`Simd::sanitize`]).
fn shade_region_per_sample(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut Rows<'_>,
    mut f: impl FnMut(usize, usize, usize) -> Vec3,
) -> ShadeCounts {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane = stride * h;
    let mut counts = ShadeCounts::default();
    let mut acc = vec![Vec3::ZERO; w];
    let inv = 1.0 / gb.samples as f32;
    for y in 0..h {
        for si in 0..gb.samples as usize {
            let row = si * plane + y * stride;
            for (x, a) in acc.iter_mut().enumerate() {
                let i = row + x;
                let c = if gb.polygon[i] == NO_POLYGON {
                    background
                } else {
                    counts.samples_shaded += 1;
                    f(i, x, y)
                };
                *a = if si == 0 { c } else { *a + c };
            }
        }
        let out = dst.row(y);
        for (o, a) in out.iter_mut().zip(&acc) {
            let c = if gb.samples == 1 { *a } else { *a * inv };
            *o = Vec3::from_array(c.to_array().map(sanitize1));
        }
    }
    counts
}

/// Where a region's resolved pixels go: `height` rows of `width` pixels whose starts are `pitch`
/// pixels apart. Built from a slice ([`Rows::new`], checked) or, by the frame stage, over one
/// region of a frame that other threads are writing other regions of ([`Rows::from_raw`]): each
/// row is handed out as its own slice, so two regions' rows never alias even though their
/// spans of the frame interleave.
pub struct Rows<'a> {
    ptr: *mut Vec3,
    pitch: usize,
    width: usize,
    height: usize,
    _borrow: std::marker::PhantomData<&'a mut [Vec3]>,
}

// SAFETY: a `Rows` is an exclusive borrow of its rows (see `Rows::from_raw`), like `&mut [Vec3]`.
unsafe impl Send for Rows<'_> {}

impl<'a> Rows<'a> {
    /// The rows of `dst`: row `y` is `dst[y * pitch..y * pitch + width]`. Panics if `dst` is too
    /// small or the rows would overlap (`width > pitch` with more than one row).
    pub fn new(dst: &'a mut [Vec3], pitch: usize, width: usize, height: usize) -> Rows<'a> {
        assert!(
            height == 0 || dst.len() >= (height - 1) * pitch + width,
            "destination too small for the region"
        );
        assert!(height <= 1 || width <= pitch, "rows overlap");
        Rows {
            ptr: dst.as_mut_ptr(),
            pitch,
            width,
            height,
            _borrow: std::marker::PhantomData,
        }
    }

    /// Rows over raw memory.
    ///
    /// # Safety
    /// For the lifetime `'a`, the `height` spans `ptr + y * pitch .. + width` must be valid for
    /// writes, `width <= pitch` (or one row), and no other reference may read or write them.
    pub unsafe fn from_raw(ptr: *mut Vec3, pitch: usize, width: usize, height: usize) -> Self {
        Rows {
            ptr,
            pitch,
            width,
            height,
            _borrow: std::marker::PhantomData,
        }
    }

    /// Number of rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Row `y`, `width` pixels.
    #[inline(always)]
    pub fn row(&mut self, y: usize) -> &mut [Vec3] {
        assert!(y < self.height, "row {y} of {}", self.height);
        // SAFETY: in bounds by construction (checked in `new`, promised to `from_raw`), and the
        // rows do not overlap, so this borrow of `self` is the only access to the span.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(y * self.pitch), self.width) }
    }
}

/// A row's output: with one sample per pixel each group of lanes is resolved and written
/// straight into the image row (the pass streams its output); with more, groups are summed into
/// row accumulators in plane order and the row is resolved once all planes are in.
pub(crate) struct RowOut {
    samples: u32,
    acc: [Vec<f32>; 3],
}

impl RowOut {
    /// The output of rows `stride` entries wide with `samples` planes (accumulators are
    /// allocated only when there is more than one plane).
    pub(crate) fn new(samples: u32, stride: usize) -> RowOut {
        let n = if samples > 1 { stride } else { 0 };
        RowOut {
            samples,
            acc: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
        }
    }

    /// Takes one group's `S::LANES` lanes of RGB at column `bx` of plane `si`, for image row
    /// `out` (fewer pixels at the row's end).
    #[inline(always)]
    pub(crate) fn block<S: Simd>(
        &mut self,
        simd: S,
        out: &mut [Vec3],
        bx: usize,
        si: usize,
        c: &[S::F; 3],
    ) {
        if self.samples == 1 {
            store(simd, out, bx, c);
        } else {
            self.accumulate(simd, bx, si, c);
        }
    }

    /// [`RowOut::block`] for a group that lies whole inside the row (no tail to cut).
    #[inline(always)]
    pub(crate) fn block_whole<S: Simd>(
        &mut self,
        simd: S,
        out: &mut [Vec3],
        bx: usize,
        si: usize,
        c: &[S::F; 3],
    ) {
        if self.samples == 1 {
            simd.store_rgb(c, &mut out[bx..bx + S::LANES]);
        } else {
            self.accumulate(simd, bx, si, c);
        }
    }

    /// Adds a group to the row accumulators at column `bx`; the first plane stores, the others
    /// add: the same IEEE operations in the same order for every shader, so samples are always
    /// summed in plane order.
    #[inline(always)]
    fn accumulate<S: Simd>(&mut self, simd: S, bx: usize, si: usize, c: &[S::F; 3]) {
        for ch in 0..3 {
            let a = &mut self.acc[ch][bx..];
            let x = if si == 0 {
                c[ch]
            } else {
                simd.add(simd.load(a), c[ch])
            };
            simd.store(x, a);
        }
    }

    /// Ends a row: resolves the accumulated planes into `out` (nothing to do with one plane)
    /// with the 8-lane token `simd`: the box filter (the mean of the planes) and the image's
    /// clamp, written through [`store`].
    #[inline(always)]
    pub(crate) fn finish_row<S: Simd>(&mut self, simd: S, out: &mut [Vec3]) {
        if self.samples <= 1 {
            return;
        }
        let inv = simd.splat(1.0 / self.samples as f32);
        let [r, g, b] = &self.acc;
        for x in (0..out.len()).step_by(S::LANES) {
            let c = [
                simd.mul(simd.load(&r[x..]), inv),
                simd.mul(simd.load(&g[x..]), inv),
                simd.mul(simd.load(&b[x..]), inv),
            ];
            store(simd, out, x, &c);
        }
    }
}

/// Writes one group's lanes, clamped by [`Simd::sanitize`], as pixels `bx..bx + S::LANES` of
/// `out` (fewer at the row's end): every resolved pixel goes through it, with one sample per
/// pixel straight from the group, with more from [`RowOut::finish_row`].
#[inline(always)]
fn store<S: Simd>(simd: S, out: &mut [Vec3], bx: usize, c: &[S::F; 3]) {
    if let Some(o) = out.get_mut(bx..bx + S::LANES) {
        simd.store_rgb(c, o);
    } else {
        // The row's last pixels, lane by lane (no call into the library's copy: a call in the
        // pass's loop would make every vector register it keeps live be saved around it).
        let mut rgb = [[0.0f32; 2 * LANES]; 3];
        for ch in 0..3 {
            simd.store(simd.sanitize(c[ch]), &mut rgb[ch]);
        }
        for (l, o) in out[bx..].iter_mut().enumerate() {
            *o = Vec3::new(rgb[0][l], rgb[1][l], rgb[2][l]);
        }
    }
}

/// The deferred pass over a frame: shades every region with `shader` into a `width` x `height` frame of
/// `background`, in parallel (rayon) over bands of `region_size` rows; regions are placed by their
/// own origin, and every pixel no region covers keeps the background. Returns the frame (row-major,
/// row 0 at the top) and the summed counters (summed in band order: deterministic).
pub fn shade_regions(
    isa: Isa,
    shader: &Shader<'_>,
    regions: &[RegionGBuffer],
    background: Vec3,
    width: u32,
    height: u32,
    region_size: u32,
) -> (Vec<Vec3>, ShadeCounts) {
    let (w, size) = (width as usize, region_size.max(1) as usize);
    // Zeroed memory comes from the allocator without a fill pass; only pixels no region covers
    // are then written with the background.
    let mut frame = vec![Vec3::ZERO; w * height as usize];
    let bands = (height as usize).div_ceil(size);
    let mut by_band: Vec<Vec<&RegionGBuffer>> = vec![Vec::new(); bands];
    for r in regions {
        let band = r.y0 as usize / size;
        if band < bands && (r.y0 as usize).is_multiple_of(size) && r.x0 + r.width <= width {
            by_band[band].push(r);
        }
    }
    let per_band: Vec<ShadeCounts> = frame
        .par_chunks_mut(w * size)
        .zip(by_band.par_iter())
        .map(|(rows, regs)| {
            let mut c = ShadeCounts::default();
            let rows_here = rows.len() / w;
            let mut covered = vec![false; w];
            for r in regs {
                if r.height as usize != rows_here {
                    continue;
                }
                let k =
                    shade_region_with(isa, shader, r, background, &mut rows[r.x0 as usize..], w);
                covered[r.x0 as usize..(r.x0 + r.width) as usize].fill(true);
                c.samples_shaded += k.samples_shaded;
                c.uniform_blocks += k.uniform_blocks;
                c.mixed_blocks += k.mixed_blocks;
            }
            if covered.iter().any(|&c| !c) {
                for row in rows.chunks_exact_mut(w) {
                    for (p, &cov) in row.iter_mut().zip(&covered) {
                        if !cov {
                            *p = background;
                        }
                    }
                }
            }
            c
        })
        .collect();
    let mut total = ShadeCounts::default();
    for c in per_band {
        total.samples_shaded += c.samples_shaded;
        total.uniform_blocks += c.uniform_blocks;
        total.mixed_blocks += c.mixed_blocks;
    }
    (frame, total)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_pass_places_regions_and_fills_the_rest_with_background() {
        use crate::raster::gbuffer::RegionGBuffer;
        // A 20 x 10 frame of 8 x 8 regions: only region (1, 0) (x 8..16, y 0..8) is present; its
        // sample at local (2, 3) sees polygon 0 with the constant patch 0.25.
        let mut gb = RegionGBuffer::new(1, 8, 0, 8, 8, 1);
        let i = 3 * gb.stride as usize + 2;
        gb.polygon[i] = 0;
        gb.depth[i] = 1.0;
        let mut c = [[0.0f32; 16]; 3];
        c[0][0] = 0.25;
        gb.table.push(PatchCoeffs::whole(c));
        gb.table_ids.push(7);
        let bg = Vec3::new(1.0, 2.0, 3.0);
        struct Unused;
        impl PatchSource for Unused {
            fn locate(&self, _: u32, _: f32, _: f32) -> u32 {
                unreachable!("the pass reads the region's table")
            }
            fn patch(&self, _: u32) -> PatchCoeffs {
                unreachable!("the pass reads the region's table")
            }
        }
        let (frame, counts) = shade_regions(
            Isa::detect(),
            &Shader::Patches(&Unused),
            &[gb],
            bg,
            20,
            10,
            8,
        );
        assert_eq!(counts.samples_shaded, 1);
        for y in 0..10 {
            for x in 0..20 {
                let want = if (x, y) == (10, 3) {
                    Vec3::new(0.25, 0.0, 0.0)
                } else {
                    bg
                };
                assert_eq!(frame[y * 20 + x], want, "({x}, {y})");
            }
        }
    }
}
