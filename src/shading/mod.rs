//! Shading: the deferred pass, the last stage before the image is written. It reads only a
//! composited region G-buffer ([`RegionGBuffer`]: per sample a polygon id, (u, v) and a slot into
//! the region-local patch table) and evaluates the bicubic radiosity reconstruction patch (RRP) of
//! each sample, then resolves the samples of each pixel with a box filter. It never sees the scene,
//! as PixelFlow's shader boards never saw it: everything a sample needs was written into the region
//! by the rasterizer, so shading cost depends on pixels, not on scene complexity.
//!
//! Invariants: a patch is a power-basis bicubic over local (s, t) in [0, 1]^2; a sample with
//! [`NO_POLYGON`] takes the background colour; the result is a finite, non-negative linear RGB
//! value per pixel. The only clamp of the image sits in the pixel resolve (`sanitize8`): after
//! the box filter, a negative or non-finite channel becomes 0 (bicubic patches and the Mitchell
//! filter can ring below zero next to a sharp shadow; every method passes through it).
//!
//! Why it is built this way: neighbouring samples nearly always share one patch, so each run of 8
//! samples with the same slot is evaluated with the patch's 48 coefficients broadcast over 8 lanes
//! (Horner in s for each of the 4 rows, then Horner in t: 15 multiply-adds per channel per lane,
//! in fixed-width `[f32; 8]` loops the compiler vectorizes); blocks that mix patches or contain
//! empty samples fall back to the same arithmetic one lane at a time. Both paths perform the same
//! IEEE operations in the same order (Rust never contracts `a * b + c` into an FMA), so which path a
//! sample takes never changes its bits.
//!
//! The radiosity-texture (RAT) method runs the same block structure
//! ([`shade_region_texture_into`]): per block of 8 samples the (u, v) derivatives, the level of
//! detail and the filter are computed in lanes ([`crate::texture::Sampler::sample8`]) with the
//! texels gathered per lane, one lane group per distinct polygon of the block, so that the
//! direct-versus-texture comparison sets two equally careful inner loops against each other. It
//! too reproduces its scalar sample-by-sample form bit for bit (kept as the tests' reference).
//!
//! Antialiasing filter: every pixel's N samples (see [`crate::raster::sample_offsets`]) are
//! averaged with equal weights, a box filter over the pixel's own square; samples that see nothing
//! contribute the background colour.
//!
//! The module is split by shader: [`patches`] (the direct method and the Gouraud mesh: patch
//! tables) and [`texture`] (the RAT filters); this file holds what every shader shares: the
//! [`Shader`] choice, the plane-order accumulation and box-filter resolve every lane shader ends
//! its blocks and rows with, the per-sample form used by the reference shader, and the frame pass over
//! all regions. The two lane shaders keep their own row and block loops: folding them into one
//! generic block driver measured 25-40 % slower on the RRP pass (criterion, `deferred/rrp-1024`),
//! so the loops stay written out.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

pub mod patches;
pub mod texture;

use glam::Vec3;
use rayon::prelude::*;

use crate::lanes::{F32x8, LANES};
use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};
use crate::texture::{Filter, TextureSet};

pub use crate::reconstruction::{PatchCoeffs, PatchSource};
pub use patches::{shade_region, shade_region_into};
pub use texture::shade_region_texture_into;

/// The radiosity of a polygon at (u, v), for [`Shader::Reference`].
pub type ReferenceFn<'a> = dyn Fn(u32, f32, f32) -> Vec3 + Sync + 'a;

/// What the deferred pass evaluates at each visible sample: the one place where the rendering
/// methods differ (everything before it, rasterization and composition, is shared).
#[derive(Clone, Copy)]
pub enum Shader<'a> {
    /// The region's patch table, filled by the rasterizer from this source: the direct method
    /// (RRPs), and the Gouraud mesh (one degree-(1, 1) patch per triangle).
    Patches(&'a dyn PatchSource),
    /// The polygon's radiosity texture, filtered, at a per-sample level of detail (RAT).
    Texture {
        /// Every polygon's texture (the texture memory every shader board would hold).
        set: &'a TextureSet,
        /// The on-screen filter.
        filter: Filter,
    },
    /// A function of (polygon, u, v), evaluated per sample: the reference (the solver's oracle).
    Reference(&'a ReferenceFn<'a>),
}

impl Shader<'_> {
    /// The patch source whose patches the rasterizer must copy into the regions, if any.
    pub fn patch_source(&self) -> Option<&dyn PatchSource> {
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

/// Shades one composited region with any [`Shader`] into `dst` (see [`shade_region_into`]).
pub fn shade_region_with(
    shader: &Shader<'_>,
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    let mut rows = Rows::new(dst, pitch, gb.width as usize, gb.height as usize);
    shade_region_rows(shader, gb, background, &mut rows)
}

/// Shades one composited region with any [`Shader`] into `rows` (`gb.width` x `gb.height`
/// pixels).
pub fn shade_region_rows(
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
        Shader::Patches(_) => patches::shade_region_rows(gb, background, rows),
        Shader::Texture { set, filter } => {
            texture::shade_region_texture_rows(set, filter, gb, background, rows)
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
/// filter, then the clamp of [`sanitize8`]).
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

/// A row's output: with one sample per pixel each block is resolved and written straight into
/// the image row (the pass streams its output); with more, blocks are summed into row
/// accumulators in plane order and the row is resolved once all planes are in.
pub(crate) struct RowOut {
    samples: u32,
    inv: F32x8,
    acc: [Vec<f32>; 3],
}

impl RowOut {
    /// The output of rows `stride` entries wide with `samples` planes (accumulators are
    /// allocated only when there is more than one plane).
    pub(crate) fn new(samples: u32, stride: usize) -> RowOut {
        let n = if samples > 1 { stride } else { 0 };
        RowOut {
            samples,
            inv: F32x8::splat(1.0 / samples as f32),
            acc: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
        }
    }

    /// Takes one block's 8 lanes of RGB at column `bx` of plane `si`, for image row `out`. `HW`
    /// (only in the AVX2 builds, after the CPU check) writes pixels with AVX2 shuffles.
    #[inline(always)]
    pub(crate) fn block<const HW: bool>(
        &mut self,
        out: &mut [Vec3],
        bx: usize,
        si: usize,
        c: &[F32x8; 3],
    ) {
        if self.samples == 1 {
            store8::<HW>(out, bx, c);
        } else {
            accumulate8(&mut self.acc, bx, si, c);
        }
    }

    /// [`RowOut::block`] for 16 lanes in AVX-512 registers (two neighbouring blocks): the same
    /// operations on each lane, so the same bits.
    ///
    /// # Safety
    /// The CPU must support AVX-512F; `bx + 16` must not exceed the row's stride.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(crate) unsafe fn block16_avx512(
        &mut self,
        out: &mut [Vec3],
        bx: usize,
        si: usize,
        c: &[std::arch::x86_64::__m512; 3],
    ) {
        use std::arch::x86_64::*;
        // SAFETY: the accumulator rows hold `stride >= bx + 16` entries; the image row is
        // checked to hold pixels `bx..bx + 16`, 48 f32 (`Vec3` is three f32, `repr(C)`).
        unsafe {
            if self.samples == 1 {
                let o = &mut out[bx..bx + 2 * LANES];
                store16_avx512(o.as_mut_ptr() as *mut f32, c);
            } else {
                for ch in 0..3 {
                    let a = self.acc[ch][bx..bx + 2 * LANES].as_mut_ptr();
                    let x = if si == 0 {
                        c[ch]
                    } else {
                        _mm512_add_ps(_mm512_loadu_ps(a), c[ch])
                    };
                    _mm512_storeu_ps(a, x);
                }
            }
        }
    }

    /// Ends a row: resolves the accumulated planes into `out` (nothing to do with one plane).
    #[inline(always)]
    pub(crate) fn finish_row<const HW: bool>(&mut self, out: &mut [Vec3]) {
        if self.samples > 1 {
            resolve_row::<HW>(&self.acc, self.inv, out);
        }
    }
}

/// Writes one block's 8 lanes, clamped by [`sanitize8`], as pixels `bx..bx + 8` of `out` (fewer at
/// the row's end): every resolved pixel goes through it (with one sample per pixel straight from
/// the block, with more from [`resolve_row`]). `HW` writes whole blocks with [`store8_avx2`].
#[inline(always)]
fn store8<const HW: bool>(out: &mut [Vec3], bx: usize, c: &[F32x8; 3]) {
    #[cfg(target_arch = "x86_64")]
    if HW {
        if let Some(o) = out.get_mut(bx..bx + LANES) {
            // SAFETY: HW is true only in the AVX2 builds, run after the CPU check; `o` is 8
            // pixels, 24 f32.
            unsafe { store8_avx2(o.as_mut_ptr() as *mut f32, c) };
            return;
        }
    }
    let [r, g, b] = [sanitize8(c[0]).0, sanitize8(c[1]).0, sanitize8(c[2]).0];
    if let Some(o) = out.get_mut(bx..bx + LANES) {
        let o: &mut [Vec3; LANES] = o.try_into().unwrap();
        for l in 0..LANES {
            o[l] = Vec3::new(r[l], g[l], b[l]);
        }
    } else {
        for (l, o) in out[bx..].iter_mut().enumerate() {
            *o = Vec3::new(r[l], g[l], b[l]);
        }
    }
}

const _: () = assert!(std::mem::size_of::<Vec3>() == 12 && std::mem::align_of::<Vec3>() == 4);

/// [`sanitize8`] in AVX registers, three instructions: `max(x, +0)` is `x` for x > 0 and the
/// second operand, +0, for x <= 0 (-0 included) and for NaN (x86's MAXPS returns its second
/// operand when either is NaN); the ordered `x < inf` then clears inf and NaN.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn sanitize8_avx2(x: std::arch::x86_64::__m256) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    let kept = _mm256_max_ps(x, _mm256_setzero_ps());
    let finite = _mm256_cmp_ps::<_CMP_LT_OQ>(x, _mm256_set1_ps(f32::INFINITY));
    _mm256_and_ps(kept, finite)
}

/// Writes 8 lanes of r, g, b, each clamped by [`sanitize8_avx2`], as 8 pixels at `dst` (24
/// floats, 3 registers). Output float k is channel k % 3 of pixel k / 3, so every channel's
/// lanes land at distinct positions modulo 3 in the three registers: one permutation per
/// channel puts each lane at its position within its register, and two blends per register
/// pick the channels.
///
/// # Safety
/// The CPU must support AVX2; `dst` must be valid for 24 f32 writes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn store8_avx2(dst: *mut f32, c: &[F32x8; 3]) {
    use std::arch::x86_64::*;
    // SAFETY: F32x8 is 8 aligned f32; `dst` is valid (the caller's promise).
    unsafe {
        let ld = |x: &F32x8| sanitize8_avx2(_mm256_load_ps(x.0.as_ptr()));
        let (r, g, b) = (ld(&c[0]), ld(&c[1]), ld(&c[2]));
        // r_i goes to float 3i, g_i to 3i + 1, b_i to 3i + 2 (register k / 8, position k % 8).
        let r = _mm256_permutevar8x32_ps(r, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
        let g = _mm256_permutevar8x32_ps(g, _mm256_setr_epi32(5, 0, 3, 6, 1, 4, 7, 2));
        let b = _mm256_permutevar8x32_ps(b, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
        // Register 0: r at 0, 3, 6; g at 1, 4, 7; b at 2, 5. Registers 1 and 2 rotate the roles.
        let o0 = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(r, g), b);
        let o1 = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(b, r), g);
        let o2 = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(g, b), r);
        _mm256_storeu_ps(dst, o0);
        _mm256_storeu_ps(dst.add(8), o1);
        _mm256_storeu_ps(dst.add(16), o2);
    }
}

/// For interleaving 16 lanes of r, g, b into 16 pixels (48 floats, 3 registers): output
/// register j, lane q holds float k = 16 j + q, channel k % 3 of pixel k / 3. The first
/// two-source permutation picks r or g (index i or 16 + i), the second keeps that (index q) or
/// picks b (16 + i).
#[cfg(target_arch = "x86_64")]
const INTERLEAVE16: [[[i32; 16]; 2]; 3] = {
    let mut t = [[[0i32; 16]; 2]; 3];
    let mut j = 0;
    while j < 3 {
        let mut q = 0;
        while q < 16 {
            let k = 16 * j + q;
            let (i, c) = ((k / 3) as i32, k % 3);
            t[j][0][q] = match c {
                0 => i,
                1 => 16 + i,
                _ => 0,
            };
            t[j][1][q] = if c == 2 { 16 + i } else { q as i32 };
            q += 1;
        }
        j += 1;
    }
    t
};

/// Writes 16 lanes of r, g, b, each clamped as [`sanitize8`] does (kept where 0 < x < inf, else
/// +0), as 16 pixels at `dst` (48 floats).
///
/// # Safety
/// The CPU must support AVX-512F; `dst` must be valid for 48 f32 writes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn store16_avx512(dst: *mut f32, c: &[std::arch::x86_64::__m512; 3]) {
    use std::arch::x86_64::*;
    // SAFETY: the index loads read the constant table; `dst` is valid (the caller's promise).
    unsafe {
        let zero = _mm512_setzero_ps();
        let inf = _mm512_set1_ps(f32::INFINITY);
        let mut k = [zero; 3];
        for ch in 0..3 {
            let m = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(c[ch], zero);
            let m = _mm512_mask_cmp_ps_mask::<_CMP_LT_OQ>(m, c[ch], inf);
            k[ch] = _mm512_maskz_mov_ps(m, c[ch]);
        }
        let [r, g, b] = k;
        for (j, idx) in INTERLEAVE16.iter().enumerate() {
            let rg = _mm512_loadu_si512(idx[0].as_ptr() as *const _);
            let tb = _mm512_loadu_si512(idx[1].as_ptr() as *const _);
            let x = _mm512_permutex2var_ps(_mm512_permutex2var_ps(r, rg, g), tb, b);
            _mm512_storeu_ps(dst.add(16 * j), x);
        }
    }
}

/// Adds one block's 8 lanes of RGB to the row accumulators at column `bx` (the first sample
/// plane `si == 0` stores instead of adding): the same IEEE operations in the same order for every
/// shader, so samples are always summed in plane order.
#[inline(always)]
fn accumulate8(acc: &mut [Vec<f32>; 3], bx: usize, si: usize, out: &[F32x8; 3]) {
    for ch in 0..3 {
        let a: &mut [f32; LANES] = (&mut acc[ch][bx..bx + LANES]).try_into().unwrap();
        *a = if si == 0 {
            out[ch].0
        } else {
            (F32x8(*a) + out[ch]).0
        };
    }
}

/// Resolves one row: the box filter (the mean of the planes, `inv = 1 / samples`, for more than
/// one sample per pixel), the clamp of [`sanitize8`], and the write of the row's `out.len()`
/// pixels.
#[inline(always)]
fn resolve_row<const HW: bool>(acc: &[Vec<f32>; 3], inv: F32x8, out: &mut [Vec3]) {
    let [r, g, b] = acc;
    for (x, o) in out.chunks_mut(LANES).enumerate() {
        let i = x * LANES;
        let ld = |a: &[f32]| F32x8(a[i..i + LANES].try_into().unwrap()) * inv;
        let c = [ld(r), ld(g), ld(b)];
        store8::<HW>(o, 0, &c);
    }
}

/// Replaces non-finite and negative lanes (-0.0 included) by +0.0: the one clamp of every image, applied to each
/// resolved pixel. Radiosity is never negative, but a bicubic (a patch next to a sharp shadow
/// edge, or the Mitchell filter across one) can ring below zero, and a patch source with
/// non-finite coefficients must not put NaN or inf into an image.
#[inline(always)]
fn sanitize8(c: F32x8) -> F32x8 {
    // "Finite and positive" as float compares that stay vector instructions: x - x is 0 exactly
    // for finite x (NaN for inf and NaN), and x > 0 fails for NaN. (Written as `is_finite()`
    // or `x < inf`, the test is folded into an integer range check that is not vectorized.)
    let mut m = [false; LANES];
    for l in 0..LANES {
        let x = c.0[l];
        #[allow(clippy::eq_op)] // x - x is the finiteness test, on purpose
        let finite = x - x == 0.0;
        m[l] = (x > 0.0) & finite;
    }
    F32x8::select(&m, c, F32x8::splat(0.0))
}

/// [`sanitize8`] for one value.
#[inline(always)]
fn sanitize1(x: f32) -> f32 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        0.0
    }
}

/// The deferred pass over a frame: shades every region with `shader` into a `width` x `height` frame of
/// `background`, in parallel (rayon) over bands of `region_size` rows; regions are placed by their
/// own origin, and every pixel no region covers keeps the background. Returns the frame (row-major,
/// row 0 at the top) and the summed counters (summed in band order: deterministic).
pub fn shade_regions(
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
                let k = shade_region_with(shader, r, background, &mut rows[r.x0 as usize..], w);
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
    fn sanitize_zeroes_exactly_the_non_finite_and_negative_lanes() {
        let sub = f32::from_bits(1); // smallest subnormal: finite, must survive
        let x = F32x8([
            1.0,
            -0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MAX,
            sub,
            -3.5,
        ]);
        let got = sanitize8(x);
        // -0.0 becomes +0.0: no image holds a negative zero either.
        let want = [1.0, 0.0, 0.0, 0.0, 0.0, f32::MAX, sub, 0.0];
        for l in 0..LANES {
            assert_eq!(got.0[l].to_bits(), want[l].to_bits(), "lane {l}");
            assert_eq!(sanitize1(x.0[l]).to_bits(), want[l].to_bits(), "lane {l}");
        }
    }

    /// Awkward channel values for the store tests: every class the clamp separates.
    fn awkward(seed: usize) -> [F32x8; 3] {
        const V: [f32; 12] = [
            1.0,
            -0.0,
            0.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MAX,
            1e-45,
            -1e-45,
            -3.5,
            0.7,
            f32::MIN_POSITIVE,
        ];
        std::array::from_fn(|ch| F32x8(std::array::from_fn(|l| V[(seed + 5 * ch + 7 * l) % 12])))
    }

    #[test]
    fn the_lane_stores_write_the_portable_bits() {
        for seed in 0..12 {
            let c = awkward(seed);
            let mut want = [Vec3::splat(9.0); LANES];
            store8::<false>(&mut want, 0, &c);
            for (l, p) in want.iter().enumerate() {
                let scalar = [c[0].0[l], c[1].0[l], c[2].0[l]].map(sanitize1);
                assert_eq!(p.to_array().map(f32::to_bits), scalar.map(f32::to_bits));
            }
            #[cfg(target_arch = "x86_64")]
            if crate::lanes::avx2_available() {
                let mut got = [Vec3::splat(9.0); LANES];
                store8::<true>(&mut got, 0, &c);
                let bits = |p: &[Vec3]| {
                    p.iter()
                        .map(|v| v.to_array().map(f32::to_bits))
                        .collect::<Vec<_>>()
                };
                assert_eq!(bits(&got), bits(&want), "seed {seed}");
            }
            #[cfg(target_arch = "x86_64")]
            if crate::lanes::avx512_available() {
                use std::arch::x86_64::*;
                // Two blocks: this seed's and the next one's.
                let d = awkward(seed + 1);
                let mut want16 = [Vec3::splat(9.0); 2 * LANES];
                store8::<false>(&mut want16, 0, &c);
                store8::<false>(&mut want16, LANES, &d);
                let mut got16 = [Vec3::splat(9.0); 2 * LANES];
                // SAFETY: the CPU has AVX-512F (checked); the loads read 16 lanes of `both`.
                unsafe {
                    let both: [[f32; 16]; 3] = std::array::from_fn(|ch| {
                        std::array::from_fn(|l| if l < 8 { c[ch].0[l] } else { d[ch].0[l - 8] })
                    });
                    let v = both.map(|x| _mm512_loadu_ps(x.as_ptr()));
                    let mut rows = RowOut::new(1, 2 * LANES);
                    rows.block16_avx512(&mut got16, 0, 0, &v);
                }
                for (g, w) in got16.iter().zip(&want16) {
                    assert_eq!(
                        g.to_array().map(f32::to_bits),
                        w.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }

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
        let (frame, counts) = shade_regions(&Shader::Patches(&Unused), &[gb], bg, 20, 10, 8);
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
