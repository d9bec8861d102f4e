//! Regions: the third stage of the renderer. The screen is cut into square regions (default
//! 128 x 128, PixelFlow's SIMD array size); each renderer bins its primitives per region by
//! bounding box and, per region, rasterizes every binned primitive into the region's G-buffer.
//!
//! The inner loop works on whole blocks of 8 horizontally adjacent samples, as PixelFlow's
//! enhanced-memory chips evaluated linear expressions at every pixel at once: the integer edge
//! functions are fixed-width `[i64; 8]` lanes whose sign bits are OR-ed into a coverage mask, and
//! depth, 1/w and the plane coordinates are `[f32; 8]` lanes; the bilinear inverse, the depth test
//! and the writes are computed for all 8 lanes and committed through masks (select), with no
//! per-sample branch. The only branches are per row (a conservative span of covered columns from
//! the edges' slopes, so thin and slanted primitives do not walk their empty bounding box), per
//! block (interior blocks skip the per-lane edge test; blocks with no covered sample are skipped;
//! blocks whose every covered sample fails the depth test skip the (u, v) work and the stores) and
//! per primitive (the form of the (u, v) inverse, up to 3, 4 or 9 edges, 32- or 64-bit edge
//! lanes), monomorphized out of the loop, each combination a kernel function of its own (so a
//! small triangle pays only its own kernel's setup); the projection (perspective or orthographic)
//! is a per-lane select, not a kernel of its own, which keeps the variants to 12 per instruction
//! set. None of them changes a result: the exact integer edge test and the depth test still decide every sample.
//!
//! The per-pixel linear expressions are re-based at each region's origin in f64 and only then
//! rounded to f32, so their f32 evaluation works with small local coordinates and keeps its
//! precision anywhere on a 16k-pixel screen.
//!
//! Depth test: a sample is written when its depth is smaller, or equal with a smaller polygon id,
//! so the result does not depend on the order primitives arrive in.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

use super::gbuffer::RegionGBuffer;
use super::geometry::plane;
use super::setup::{
    clamp_uv, invert_bilinear, triangle_u, BilinearInverse, Edge, InverseKind, Prim, MAX_EDGES, ONE,
};
use lanes::{Isa, Kernel, Portable, Simd, LANES};

/// The frame's grid of regions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RegionGrid {
    /// Region side in pixels (a multiple of 8).
    pub size: u32,
    /// Regions per row.
    pub cols: u32,
    /// Regions per column.
    pub rows: u32,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
}

impl RegionGrid {
    /// The grid of `size` x `size` regions over a `width` x `height` image.
    pub fn new(width: u32, height: u32, size: u32) -> RegionGrid {
        RegionGrid {
            size,
            cols: width.div_ceil(size),
            rows: height.div_ceil(size),
            width,
            height,
        }
    }

    /// Number of regions.
    pub fn count(&self) -> usize {
        (self.cols * self.rows) as usize
    }

    /// Pixel rectangle (x0, y0, width, height) of region `r`.
    pub fn rect(&self, r: u32) -> (u32, u32, u32, u32) {
        let (cx, cy) = (r % self.cols, r / self.cols);
        let (x0, y0) = (cx * self.size, cy * self.size);
        (
            x0,
            y0,
            self.size.min(self.width - x0),
            self.size.min(self.height - y0),
        )
    }

    /// Bins primitives: for each region, the indices (into `prims`, ascending) of those whose
    /// bounding box meets it (empty records, [`Prim::is_empty`], are skipped).
    pub fn bin<'a>(&self, prims: impl Iterator<Item = (usize, &'a Prim)>) -> Vec<Vec<u32>> {
        let mut bins = vec![Vec::new(); self.count()];
        for (i, p) in prims.filter(|(_, p)| !p.is_empty()) {
            self.bin_one(i as u32, p, &mut bins);
        }
        bins
    }

    /// Appends primitive `i` to the list of every region its bounding box meets.
    #[inline]
    pub(crate) fn bin_one(&self, i: u32, p: &Prim, bins: &mut [Vec<u32>]) {
        let [x0, y0, x1, y1] = p.bbox;
        for ry in y0 / self.size..=y1 / self.size {
            for rx in x0 / self.size..=x1 / self.size {
                bins[(ry * self.cols + rx) as usize].push(i);
            }
        }
    }
}

/// Calls `visit(local_y, block_x, bits)` for every block of 8 samples of one sample position
/// (`offset`, fixed point within the pixel) of region `rect` that the primitive covers at least
/// partly. Bit l of `bits` (never 0) is whether lane l is covered (and inside the region).
///
/// `N` is the number of edge functions evaluated per block, a compile-time constant (4 for
/// triangles and quads, [`MAX_EDGES`] for clipped polygons) so the edge loop is unrolled; edges
/// beyond the primitive's own are the constant function 0 (dx = dy = 0, bias 0), which covers
/// every sample and so leaves the mask unchanged.
#[inline(always)]
fn for_each_block<S: Simd, const N: usize, T: EdgeLane>(
    simd: S,
    prim: &Prim,
    rect: (u32, u32, u32, u32),
    offset: (i64, i64),
    mut visit: impl FnMut(u32, u32, u32),
) {
    debug_assert!(prim.n_edges <= N);
    let (rx, ry, rw, rh) = rect;
    let [bx0, by0, bx1, by1] = prim.bbox;
    if bx1 < rx || by1 < ry || bx0 >= rx + rw || by0 >= ry + rh {
        return;
    }
    let lx0 = (bx0.max(rx) - rx) / LANES as u32 * LANES as u32;
    let lx1 = bx1.min(rx + rw - 1) - rx; // inclusive
    let ly0 = by0.max(ry) - ry;
    let ly1 = by1.min(ry + rh - 1) - ry;
    // Unused entries of `prim.edges` are `Edge::default()`: the constant 0 (see above).
    let edges: &[Edge; N] = prim.edges[..N].try_into().unwrap();
    let Steps {
        lane: lane_step,
        block: block_step,
        min: min_step,
        row: row_step,
    } = Steps::<T, N>::of(edges);
    let mut inv_d = [0.0f64; N];
    // A box at most two blocks wide (the small triangles of a mesh) walks every block of each
    // row: the span below would cost more than the one empty block it can skip.
    let narrow = lx1 - lx0 < 2 * LANES as u32;
    if !narrow {
        for (k, e) in edges.iter().enumerate() {
            inv_d[k] = 1.0 / (e.dy as i64 * ONE) as f64;
        }
    }
    let mut row = [T::ZERO; N];
    // The edge functions at the first block of the first row, then stepped a row at a time:
    // E(X, Y + ONE) = E(X, Y) + dx ONE, exact in i64 (the same values `Edge::at` gives).
    let mut row64 = [0i64; N];
    {
        let y = (ry + ly0) as i64 * ONE + offset.1;
        let x = (rx + lx0) as i64 * ONE + offset.0;
        for (k, e) in edges.iter().enumerate() {
            row64[k] = e.at(x, y) - row_step[k];
        }
    }
    for ly in ly0..ly1 + 1 {
        for k in 0..N {
            row64[k] += row_step[k];
        }
        let (start, end) = if narrow {
            // The row starts at the box's first block: the values at lx0 themselves.
            for k in 0..N {
                row[k] = T::of(row64[k]);
            }
            (lx0, lx1)
        } else {
            let Some((start, end)) = span(edges, &row64, &inv_d, (lx0, lx1)) else {
                continue;
            };
            for k in 0..N {
                row[k] = T::of(row64[k] - edges[k].dy as i64 * ONE * (start - lx0) as i64);
            }
            (start, end)
        };
        let mut bx = start;
        while bx <= end {
            // Interior blocks first: an edge function is linear along the row, so its smallest
            // lane value is at lane 0 or lane 7 (`min_step`); when every edge's smallest value is
            // >= 0 all 8 lanes are covered and the per-lane test is skipped (N scalar adds).
            let mut inner = T::ZERO;
            for k in 0..N {
                inner = inner | (row[k] + min_step[k]);
            }
            // Lanes inside the region, as bits (lane l is bit l).
            let in_region = if rw - bx >= LANES as u32 {
                0xff
            } else {
                (1u32 << (rw - bx)) - 1
            };
            let bits = if inner >= T::ZERO {
                in_region
            } else {
                T::covered_bits::<S, N>(simd, &row, &lane_step) & in_region
            };
            for k in 0..N {
                row[k] = row[k] - block_step[k];
            }
            if bits != 0 {
                visit(ly, bx, bits);
            }
            bx += LANES as u32;
        }
    }
}

/// The steps of the edge functions in a block walk ([`for_each_block`]), per edge: each lane's
/// offset from lane 0, a block's step along the row, the smallest lane offset (the whole-block
/// test's) and a row's step (in i64, exact).
struct Steps<T, const N: usize> {
    lane: [[T; LANES]; N],
    block: [T; N],
    min: [T; N],
    row: [i64; N],
}

impl<T: EdgeLane, const N: usize> Steps<T, N> {
    #[inline(always)]
    fn of(edges: &[Edge; N]) -> Self {
        let mut s = Steps {
            lane: [[T::ZERO; LANES]; N],
            block: [T::ZERO; N],
            min: [T::ZERO; N],
            row: [0; N],
        };
        for (k, e) in edges.iter().enumerate() {
            for (l, x) in s.lane[k].iter_mut().enumerate() {
                *x = T::of(-(e.dy as i64) * ONE * l as i64);
            }
            s.block[k] = T::of(e.dy as i64 * ONE * LANES as i64);
            s.min[k] = T::of((-(e.dy as i64) * ONE * (LANES as i64 - 1)).min(0));
            s.row[k] = e.dx as i64 * ONE;
        }
        s
    }
}

/// The blocks of one row worth walking: from `start` (a multiple of 8) through `end`, `None`
/// when none is. The row's covered columns p satisfy, for every edge, row + (lx0 - p) * dy *
/// ONE >= 0, i.e. p >= q (dy < 0) or p <= q (dy > 0) with q = lx0 + row / (dy * ONE), `row64`
/// holding the edge functions at column `lx0`. The bounds are widened by a pixel against f64
/// rounding (|q| < 2^40, far below a pixel of error, the reciprocal `inv_d` included), so the
/// span only skips blocks the exact integer test would reject anyway: it spares the edge lanes
/// of the empty blocks around thin or slanted primitives.
#[inline(always)]
fn span<const N: usize>(
    edges: &[Edge; N],
    row64: &[i64; N],
    inv_d: &[f64; N],
    (lx0, lx1): (u32, u32),
) -> Option<(u32, u32)> {
    let (mut lo, mut hi) = (lx0 as f64, lx1 as f64);
    for k in 0..N {
        let dy = edges[k].dy;
        let q = lx0 as f64 + row64[k] as f64 * inv_d[k];
        if dy < 0 {
            lo = lo.max(q - 1.0);
        } else if dy > 0 {
            hi = hi.min(q + 1.0);
        } else if row64[k] < 0 {
            hi = -1.0;
        }
    }
    if lo > hi {
        return None;
    }
    // lx0 <= lo <= hi <= lx1 here, so both casts are in range.
    Some((lo as u32 / LANES as u32 * LANES as u32, hi as u32))
}

/// The integer type of the edge-function lanes: `i64` always holds them (see
/// [`super::setup`]); `i32` holds them for primitives whose box is small
/// ([`Prim::i32_edges`]), and then 8 lanes are one AVX2 register instead of two.
trait EdgeLane:
    Copy
    + PartialOrd
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::BitOr<Output = Self>
{
    const ZERO: Self;
    /// `x`, which the caller guarantees is in range.
    fn of(x: i64) -> Self;

    /// The covered lanes of a block as bits (lane l is bit l): lane l is covered when
    /// `row[k] + step[k][l] >= 0` for every edge k, tested as the sign of the OR of the sums.
    /// The 64-bit lanes run the portable loop (vectorized for the kernel's instruction set);
    /// the 32-bit ones take the token's operations.
    #[inline(always)]
    fn covered_bits<S: Simd, const N: usize>(
        simd: S,
        row: &[Self; N],
        step: &[[Self; LANES]; N],
    ) -> u32 {
        let _ = simd;
        covered_bits_portable(row, step)
    }
}

/// The portable form of [`EdgeLane::covered_bits`], for either lane width.
#[inline(always)]
fn covered_bits_portable<T: EdgeLane, const N: usize>(row: &[T; N], step: &[[T; LANES]; N]) -> u32 {
    let mut acc = [T::ZERO; LANES];
    for k in 0..N {
        for l in 0..LANES {
            acc[l] = acc[l] | (row[k] + step[k][l]);
        }
    }
    let mut bits = 0u32;
    for l in 0..LANES {
        bits |= ((acc[l] >= T::ZERO) as u32) << l;
    }
    bits
}

impl EdgeLane for i64 {
    const ZERO: i64 = 0;
    #[inline(always)]
    fn of(x: i64) -> i64 {
        x
    }
}

impl EdgeLane for i32 {
    const ZERO: i32 = 0;
    #[inline(always)]
    fn of(x: i64) -> i32 {
        debug_assert!(i32::try_from(x).is_ok(), "{x} out of the i32 lane range");
        x as i32
    }

    /// N adds and ORs in the token's 32-bit lanes, then the sign bits in one move-mask (the
    /// portable loop's compares and bit packing were scalarized).
    #[inline(always)]
    fn covered_bits<S: Simd, const N: usize>(
        simd: S,
        row: &[i32; N],
        step: &[[i32; LANES]; N],
    ) -> u32 {
        let mut acc = simd.splat_u(0);
        for k in 0..N {
            let mut st = [0u32; LANES];
            for l in 0..LANES {
                st[l] = step[k][l] as u32;
            }
            acc = simd.or_u(
                acc,
                simd.add_i(simd.splat_u(row[k] as u32), simd.load_u(&st)),
            );
        }
        simd.nonneg_bits(acc)
    }
}

/// Runs [`for_each_block`] with the smallest compiled edge count that holds the primitive's
/// edges, and 32-bit edge lanes when they hold its values ([`Prim::i32_edges`]).
#[inline(always)]
fn dispatch_edges<S: Simd>(
    simd: S,
    prim: &Prim,
    rect: (u32, u32, u32, u32),
    offset: (i64, i64),
    visit: impl FnMut(u32, u32, u32),
) {
    if prim.n_edges <= 3 && prim.i32_edges {
        // Small triangles (the mesh method's): one edge function fewer per row and block.
        for_each_block::<S, 3, i32>(simd, prim, rect, offset, visit)
    } else if prim.n_edges <= 4 {
        if prim.i32_edges {
            for_each_block::<S, 4, i32>(simd, prim, rect, offset, visit)
        } else {
            for_each_block::<S, 4, i64>(simd, prim, rect, offset, visit)
        }
    } else {
        for_each_block::<S, MAX_EDGES, i64>(simd, prim, rect, offset, visit)
    }
}

/// Fixed-point offsets within the pixel of sample position `si` out of `samples`.
fn offset_fixed(offsets: &[(f32, f32)], si: usize) -> (i64, i64) {
    let (ox, oy) = offsets[si];
    ((ox * ONE as f32) as i64, (oy * ONE as f32) as i64)
}

/// Rasterizes `prim` into the region G-buffer `gb` at every sample position of `offsets`
/// (fractions of a pixel, multiples of 1/256) with the instruction set `isa` (its 8-lane build:
/// on AVX-512 CPUs the kernels are compiled with AVX-512 enabled). Returns the number of covered
/// samples (fragments, counted before the depth test). The result does not depend on `isa`.
pub fn rasterize(isa: Isa, prim: &Prim, gb: &mut RegionGBuffer, offsets: &[(f32, f32)]) -> u64 {
    match prim.kind {
        InverseKind::Linear => by_edges::<LINEAR>(isa, prim, gb, offsets),
        InverseKind::Triangle => by_edges::<TRIANGLE>(isa, prim, gb, offsets),
        InverseKind::General => by_edges::<GENERAL>(isa, prim, gb, offsets),
    }
}

const LINEAR: u8 = 0;
const TRIANGLE: u8 = 1;
const GENERAL: u8 = 2;

/// Picks the kernel compiled for the primitive's projection, (u, v) inverse, edge count and
/// edge-lane width (as [`dispatch_edges`] does), each a function of its own: a small triangle
/// then pays only its own kernel's setup, not a prologue preparing every variant's values.
#[inline(always)]
fn by_edges<const KIND: u8>(
    isa: Isa,
    prim: &Prim,
    gb: &mut RegionGBuffer,
    offsets: &[(f32, f32)],
) -> u64 {
    macro_rules! kernel {
        ($n:expr, $t:ty) => {
            isa.run8(RasterKernel::<KIND, $n, $t> {
                prim,
                gb,
                offsets,
                edge_lane: std::marker::PhantomData,
            })
        };
    }
    if prim.n_edges <= 3 && prim.i32_edges {
        kernel!(3, i32)
    } else if prim.n_edges <= 4 {
        if prim.i32_edges {
            kernel!(4, i32)
        } else {
            kernel!(4, i64)
        }
    } else {
        kernel!(MAX_EDGES, i64)
    }
}

/// One rasterizer kernel: projection, (u, v) inverse, edge count and edge-lane type fixed.
struct RasterKernel<'a, const KIND: u8, const N: usize, T> {
    prim: &'a Prim,
    gb: &'a mut RegionGBuffer,
    offsets: &'a [(f32, f32)],
    edge_lane: std::marker::PhantomData<T>,
}

impl<const KIND: u8, const N: usize, T: EdgeLane> Kernel for RasterKernel<'_, KIND, N, T> {
    type Output = u64;
    #[inline(always)]
    fn run<S: Simd>(self, simd: S) -> u64 {
        raster_kernel::<S, KIND, N, T>(simd, self.prim, self.gb, self.offsets)
    }
}

/// Smallest Q = 1/w accepted (documented clamp: a covered sample has w >= near > 0, so Q is
/// positive; the clamp only keeps a rounding accident from dividing by zero).
const MIN_Q: f32 = 1e-30;

/// A primitive's five screen-linear expressions (Q = 1/w, and the numerators and denominators of
/// s and t) as (d/dx, d/dy, value at the region's origin), re-based in f64 at the region's pixel
/// corner and then rounded to f32, so the kernel's per-lane arithmetic stays small in magnitude.
struct LocalPlanes {
    q: (f32, f32, f32),
    sa: (f32, f32, f32),
    sb: (f32, f32, f32),
    ta: (f32, f32, f32),
    tb: (f32, f32, f32),
}

/// The five expressions' values at x = 0 of one sample row.
struct RowValues {
    q: f32,
    sa: f32,
    sb: f32,
    ta: f32,
    tb: f32,
}

impl LocalPlanes {
    fn new(prim: &Prim, x0: u32, y0: u32) -> Self {
        let local = |k: usize| {
            let p = prim.planes[k];
            (p.a as f32, p.b as f32, p.at(x0 as f64, y0 as f64) as f32)
        };
        LocalPlanes {
            q: local(plane::Q),
            sa: local(plane::SA),
            sb: local(plane::SB),
            ta: local(plane::TA),
            tb: local(plane::TB),
        }
    }

    #[inline(always)]
    fn row(&self, yf: f32) -> RowValues {
        RowValues {
            q: self.q.1 * yf + self.q.2,
            sa: self.sa.1 * yf + self.sa.2,
            sb: self.sb.1 * yf + self.sb.2,
            ta: self.ta.1 * yf + self.ta.2,
            tb: self.tb.1 * yf + self.tb.2,
        }
    }

    /// The polygon's (u, v) at a block's lanes, from their x and w: s and t hold (u, v) for
    /// LINEAR and (U, v) for TRIANGLE (folded at setup); GENERAL inverts the bilinear map.
    #[inline(always)]
    fn uv<const KIND: u8>(
        &self,
        row: &RowValues,
        xs: &[f32; LANES],
        w: &[f32; LANES],
        inv: &BilinearInverse,
    ) -> ([f32; LANES], [f32; LANES]) {
        let mut s = [0.0f32; LANES];
        let mut t = [0.0f32; LANES];
        for l in 0..LANES {
            let x = xs[l];
            s[l] = self.sa.0 * x + row.sa + w[l] * (self.sb.0 * x + row.sb);
            t[l] = self.ta.0 * x + row.ta + w[l] * (self.tb.0 * x + row.tb);
        }
        let mut u = [0.0f32; LANES];
        let mut v = [0.0f32; LANES];
        for l in 0..LANES {
            let (a, b) = match KIND {
                LINEAR => clamp_uv(s[l], t[l]),
                TRIANGLE => clamp_uv(triangle_u(s[l], t[l]), t[l]),
                _ => invert_bilinear(inv, s[l], t[l]),
            };
            u[l] = a;
            v[l] = b;
        }
        (u, v)
    }
}

#[inline(always)]
fn raster_kernel<S: Simd, const KIND: u8, const N: usize, T: EdgeLane>(
    simd: S,
    prim: &Prim,
    gb: &mut RegionGBuffer,
    offsets: &[(f32, f32)],
) -> u64 {
    const { assert!(S::LANES == LANES, "the rasterizer works in blocks of 8") };
    let rect = (gb.x0, gb.y0, gb.width, gb.height);
    let stride = gb.stride as usize;
    let plane_len = stride * gb.height as usize;
    let planes = LocalPlanes::new(prim, gb.x0, gb.y0);
    let mut inv = prim.inverse;
    inv.triangle = false; // only the GENERAL kernel calls invert_bilinear
    let id = prim.id;
    let perspective = prim.perspective;
    let mut fragments = 0u64;
    for si in 0..offsets.len() {
        let off = offset_fixed(offsets, si);
        let (fx, fy) = (off.0 as f32 / ONE as f32, off.1 as f32 / ONE as f32);
        let base = si * plane_len;
        for_each_block::<S, N, T>(
            simd,
            prim,
            rect,
            off,
            #[inline(always)]
            |ly: u32, bx: u32, bits: u32| {
                let yf = ly as f32 + fy;
                let row = planes.row(yf);
                // Depth first: w alone decides the depth test, so blocks hidden behind what the
                // region already holds (overdraw) skip the (u, v) work and every store.
                let mut xs = [0.0f32; LANES];
                let mut w = [0.0f32; LANES];
                for l in 0..LANES {
                    xs[l] = (bx + l as u32) as f32 + fx;
                    let qv = planes.q.0 * xs[l] + row.q;
                    // A select, not a branch: orthographic views are rare, and one kernel for
                    // both projections halves the rasterizer's compiled variants.
                    let inv_q = 1.0 / qv.max(MIN_Q);
                    w[l] = if perspective { inv_q } else { qv };
                }
                fragments += bits.count_ones() as u64;
                let i0 = base + ly as usize * stride + bx as usize;
                // The block's 8 samples of each plane, bounds-checked once here (the token
                // operations below then see slices of a known length).
                let depth: &mut [f32; LANES] = (&mut gb.depth[i0..i0 + LANES]).try_into().unwrap();
                let poly: &mut [u32; LANES] = (&mut gb.polygon[i0..i0 + LANES]).try_into().unwrap();
                // The depth test: covered, and nearer, or as near with a smaller polygon id.
                let wv = simd.load(&w);
                let m = {
                    let dv = simd.load(depth);
                    let smaller = simd.lt_u(simd.splat_u(id), simd.load_u(poly));
                    let nearer_or_tie =
                        simd.or_m(simd.lt(wv, dv), simd.and_m(simd.eq(wv, dv), smaller));
                    simd.and_m(simd.mask(bits), nearer_or_tie)
                };
                if !simd.any(m) {
                    return;
                }
                let (u, v) = planes.uv::<KIND>(&row, &xs, &w, &inv);
                // Full-lane blends into region memory (no masked stores: see
                // `Simd::blend_store`).
                simd.blend_store(depth, wv, m);
                simd.blend_store_u(poly, simd.splat_u(id), m);
                let gu: &mut [f32; LANES] = (&mut gb.u[i0..i0 + LANES]).try_into().unwrap();
                let gv: &mut [f32; LANES] = (&mut gb.v[i0..i0 + LANES]).try_into().unwrap();
                simd.blend_store(gu, simd.load(&u), m);
                simd.blend_store(gv, simd.load(&v), m);
            },
        );
    }
    fragments
}

/// Coverage counts of a `width` x `height` image: for each pixel, how many of `prims` cover its
/// centre, through the same block edge-function path the rasterizer uses. For tests of
/// watertightness and of the edge functions.
pub fn coverage_counts(prims: &[Prim], width: u32, height: u32, region: u32) -> Vec<u32> {
    let grid = RegionGrid::new(width, height, region);
    let mut counts = vec![0u32; (width * height) as usize];
    for r in 0..grid.count() as u32 {
        let rect = grid.rect(r);
        for p in prims {
            dispatch_edges(
                Portable::new(),
                p,
                rect,
                (ONE / 2, ONE / 2),
                |ly, bx, bits| {
                    for l in 0..LANES {
                        let (x, y) = (rect.0 + bx + l as u32, rect.1 + ly);
                        if (bits >> l) & 1 != 0 {
                            counts[(y * width + x) as usize] += 1;
                        }
                    }
                },
            );
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::geometry::{Plane, ScreenPolygon};
    use crate::raster::setup::{edges_fit_i32, setup};

    fn prim(verts: Vec<[f64; 2]>, w: u32, h: u32) -> Option<Prim> {
        let sp = ScreenPolygon {
            id: 0,
            verts: verts.into_iter().collect(),
            planes: [Plane::default(); 5],
            corners: [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0]],
            triangle: true,
            perspective: false,
            front_facing: true,
            barycentric: false,
        };
        setup(&sp, w, h)
    }

    /// Every block's mask, from the 64-bit walk or the 32-bit one, with instruction set `isa`.
    fn masks<T: EdgeLane>(isa: Isa, p: &Prim, rect: (u32, u32, u32, u32)) -> Vec<u32> {
        masks_n::<4, T>(isa, p, rect)
    }

    /// [`masks`] from the walk over `N` edge functions.
    fn masks_n<const N: usize, T: EdgeLane>(
        isa: Isa,
        p: &Prim,
        rect: (u32, u32, u32, u32),
    ) -> Vec<u32> {
        struct Walk<'a, const N: usize, T> {
            p: &'a Prim,
            rect: (u32, u32, u32, u32),
            lane: std::marker::PhantomData<T>,
        }
        impl<const N: usize, T: EdgeLane> Kernel for Walk<'_, N, T> {
            type Output = Vec<u32>;
            fn run<S: Simd>(self, simd: S) -> Vec<u32> {
                let mut out = Vec::new();
                for_each_block::<S, N, T>(
                    simd,
                    self.p,
                    self.rect,
                    (ONE / 2, ONE / 2),
                    |y, x, bits| {
                        assert!(bits != 0 && bits < 256);
                        out.push(y << 20 | x << 8 | bits);
                    },
                );
                out
            }
        }
        isa.run8(Walk::<N, T> {
            p,
            rect,
            lane: std::marker::PhantomData,
        })
    }

    /// Every instruction set this CPU has (the tests of the variants against the scalar rule,
    /// with a report of those not run, are the engine's `isa_variants` test).
    fn isas() -> Vec<Isa> {
        lanes::Level::ALL.into_iter().filter_map(Isa::at).collect()
    }

    #[test]
    fn thirty_two_bit_edge_lanes_cover_exactly_what_sixty_four_bit_lanes_do() {
        // Small random triangles, some far off screen with a small visible part (their edge
        // values are large although the clamped box is small: they must stay on 64 bits).
        let mut seed = base::rng::Rng::new(99);
        let mut rnd = |scale: f64| seed.next_f64() * scale;
        let (mut small, mut checked, mut three) = (0, 0, 0);
        for i in 0..3000 {
            let far = i % 5 == 0;
            let c = [rnd(120.0) - 4.0, rnd(120.0) - 4.0];
            let size = if far { 60_000.0 } else { rnd(40.0) + 0.3 };
            let v: Vec<[f64; 2]> = (0..3)
                .map(|_| [c[0] + rnd(size) - size / 2.0, c[1] + rnd(size) - size / 2.0])
                .collect();
            let Some(p) = prim(v, 128, 128) else { continue };
            let want = masks::<i64>(Isa::Portable(Portable::new()), &p, (0, 0, 128, 128));
            for isa in isas() {
                assert_eq!(
                    masks::<i64>(isa, &p, (0, 0, 128, 128)),
                    want,
                    "triangle {i}"
                );
                if p.i32_edges {
                    assert_eq!(
                        masks::<i32>(isa, &p, (0, 0, 128, 128)),
                        want,
                        "triangle {i}"
                    );
                    // The 3-edge walk small triangles take.
                    if p.n_edges == 3 {
                        let got = masks_n::<3, i32>(isa, &p, (0, 0, 128, 128));
                        assert_eq!(got, want, "triangle {i}");
                    }
                }
            }
            small += p.i32_edges as usize;
            three += (p.i32_edges && p.n_edges == 3) as usize;
            checked += 1;
        }
        assert!(small > 1500 && checked > 2000, "{small} small of {checked}");
        assert!(three > 1000, "{three} three-edge triangles");
    }

    #[test]
    fn a_small_clamped_box_with_far_vertices_keeps_sixty_four_bit_lanes() {
        // A huge triangle whose on-screen box is a corner of a 16 x 16 image.
        let p = prim(
            vec![[-60000.0, -60000.0], [10.0, -60000.0], [-60000.0, 10.0]],
            16,
            16,
        )
        .unwrap();
        assert!(p.bbox[2] < 16 && p.bbox[3] < 16);
        assert!(!p.i32_edges);
        // A 50-pixel triangle fits: its values stay below 2^31.
        let q = prim(vec![[1.0, 1.0], [51.0, 1.0], [1.0, 51.0]], 128, 128).unwrap();
        assert!(q.i32_edges && edges_fit_i32(&q.edges[..q.n_edges], q.bbox));
    }
}
