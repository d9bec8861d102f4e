//! Composition: the stage between the renderers and the shaders. With R virtual renderers, each
//! rasterizes a round-robin share of the primitives into full-screen region G-buffers; the
//! composition network merges, region by region, the G-buffers of every renderer that had
//! primitives there into one, by depth, ties broken by the smaller polygon id, then hands the
//! composited region on to the deferred shading stage. PixelFlow built this network in hardware
//! (a pipelined z-compare over all renderers: Molnar, Eyles and Poulton, SIGGRAPH 1992) running
//! concurrently with rasterization; here the merge runs inside each region's task
//! ([`crate::frame::FrameContext::render`]), on whichever worker rasterized the region, while
//! the other workers rasterize other regions: the network is as parallel as the regions are, and
//! its buffers are still in cache when it merges them ([`merge_records_into`]).
//!
//! Invariants: the merge is commutative and associative (depth, then polygon id, is a total order
//! on distinct polygons), and after merging the patch table is renumbered in memory order of first
//! use, so a composited region is bit-identical for every R, every thread count and every arrival
//! order. With one report for a region the report is passed through unchanged: the renderer built
//! its table in the same canonical order.
//!
//! Two merges: `composite_in_place` merges reports that carry patch tables and rebuilds the
//! table (the reference the frame's merge is tested against, and a stage the benchmarks time:
//! compiled only for tests and with the `bench` feature); [`merge_records_into`] merges pixel
//! records only, for the frame stage, which locates the patches once in the merged region. Both give the same composited region (tested),
//! and the second does not locate the samples every renderer drew but another one hid: with R
//! renderers the frame costs the rasterization plus a records merge, not R patch locations and a
//! table rebuild.
//!
//! Traffic model: every report that crosses the network costs its pixel records
//! ([`PIXEL_RECORD_BYTES`] per sample) plus its patch table; the composited region sent on to the
//! shaders costs the same again. In the frame stage the region's one table is counted once on
//! the way in (the reports' tables hold the same patches, each sent once) and once on the way
//! out, which for one renderer is exactly the two counts above. Renderers with no primitive
//! binned in a region send nothing (a renderer skips its empty regions), and regions no renderer
//! touches cost nothing at all.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

use lanes::{Isa, Kernel, Simd, LANES};

use crate::raster::gbuffer::RegionGBuffer;
#[cfg(any(test, feature = "bench"))]
use crate::raster::gbuffer::{IdMap, NO_POLYGON};
#[cfg(any(test, feature = "bench"))]
use reconstruction::PatchCoeffs;

pub use crate::raster::gbuffer::PIXEL_RECORD_BYTES;

/// Working memory of [`composite_in_place`], kept across regions by its caller.
#[cfg(any(test, feature = "bench"))]
#[derive(Debug, Default)]
pub struct MergeScratch {
    /// Per sample: which part the composited sample came from.
    src: Vec<u32>,
    /// Per part, per old slot: the new slot (`u32::MAX` until first used).
    remap: Vec<Vec<u32>>,
    index: IdMap,
    table: Vec<PatchCoeffs>,
    ids: Vec<u32>,
}

/// Merges the G-buffers of one region, one per renderer that had primitives there (in any
/// order), into `parts[0]`, by depth then polygon id, and rebuilds its patch table in canonical
/// order. `parts[1..]` are left as they were. With one part nothing changes: its renderer built
/// the table in canonical order already.
#[cfg(any(test, feature = "bench"))]
pub fn composite_in_place(isa: Isa, parts: &mut [RegionGBuffer], scratch: &mut MergeScratch) {
    if parts.len() <= 1 {
        return;
    }
    let (head, rest) = parts.split_at_mut(1);
    let out = &mut head[0];
    let n = out.len();
    let src = &mut scratch.src;
    src.clear();
    src.resize(n, 0);
    for (k, part) in rest.iter().enumerate() {
        let k = (k + 1) as u32;
        assert_eq!(
            part.len(),
            n,
            "composited parts of one region differ in size"
        );
        merge_part::<true>(isa, part, out, src, k);
    }
    // Shaders without patches (textures, the reference) leave every table empty: nothing to
    // rebuild, and no slot means anything.
    if out.table_ids.is_empty() && rest.iter().all(|p| p.table_ids.is_empty()) {
        out.slot.fill(0);
        return;
    }
    renumber_table(out, rest, scratch);
}

/// The table rebuild of [`composite_in_place`]: `out`'s merged samples, each from the part
/// `scratch.src` names, get their patches numbered in memory order of first use (the canonical
/// table). Each (part, old slot) pair asks the id map once; later samples of the same pair read
/// the per-part remap.
#[cfg(any(test, feature = "bench"))]
fn renumber_table(out: &mut RegionGBuffer, rest: &[RegionGBuffer], scratch: &mut MergeScratch) {
    let MergeScratch {
        src,
        remap,
        index,
        table,
        ids,
    } = scratch;
    if remap.len() < rest.len() + 1 {
        remap.resize_with(rest.len() + 1, Vec::new);
    }
    remap[0].clear();
    remap[0].resize(out.table_ids.len(), u32::MAX);
    for (k, part) in rest.iter().enumerate() {
        remap[k + 1].clear();
        remap[k + 1].resize(part.table_ids.len(), u32::MAX);
    }
    index.clear();
    table.clear();
    ids.clear();
    let RegionGBuffer {
        polygon,
        slot,
        table: head_table,
        table_ids: head_ids,
        ..
    } = out;
    let blocks = polygon
        .chunks_exact(LANES)
        .zip(slot.chunks_exact_mut(LANES))
        .zip(src.chunks_exact(LANES));
    for ((polys, slots), srcs) in blocks {
        let polys: &[u32; LANES] = polys.try_into().unwrap();
        let slots: &mut [u32; LANES] = slots.try_into().unwrap();
        let srcs: &[u32; LANES] = srcs.try_into().unwrap();
        // A whole block from one part and one old slot (the common case inside a polygon's
        // patch), already numbered: one remap for all 8 samples.
        let (k0, s0) = (srcs[0], slots[0]);
        let mut same = true;
        for l in 0..LANES {
            same &= (srcs[l] == k0) & (slots[l] == s0) & (polys[l] != NO_POLYGON);
        }
        if same {
            let new = remap[k0 as usize][s0 as usize];
            if new != u32::MAX {
                *slots = [new; LANES];
                continue;
            }
        }
        for l in 0..LANES {
            if polys[l] == NO_POLYGON {
                slots[l] = 0;
                continue;
            }
            let k = srcs[l] as usize;
            let old = slots[l] as usize;
            let new = remap[k][old];
            if new != u32::MAX {
                slots[l] = new;
                continue;
            }
            let (part_table, part_ids) = if k == 0 {
                (&*head_table, &*head_ids)
            } else {
                (&rest[k - 1].table, &rest[k - 1].table_ids)
            };
            let id = part_ids[old];
            let new = *index.entry(id).or_insert_with(|| {
                table.push(part_table[old]);
                ids.push(id);
                (table.len() - 1) as u32
            });
            remap[k][old] = new;
            slots[l] = new;
        }
    }
    std::mem::swap(&mut out.table, table);
    std::mem::swap(&mut out.table_ids, ids);
}

/// Merges `part` (the `k`-th) into `out` sample by sample: a sample of `part` replaces `out`'s when
/// it is nearer, or as near with a smaller polygon id (a total order on distinct polygons, so
/// the result does not depend on the order of the parts). With `TABLES` the slot moves too and
/// `src` records where each sample came from (for the table rebuild); without, only the pixel
/// records (depth, polygon, u, v) move. Runs with the instruction set `isa` at its full width
/// (16 samples per step on AVX-512); the result does not depend on it.
fn merge_part<const TABLES: bool>(
    isa: Isa,
    part: &RegionGBuffer,
    out: &mut RegionGBuffer,
    src: &mut [u32],
    k: u32,
) {
    isa.run(MergePart::<TABLES> { part, out, src, k })
}

/// [`merge_part`] as a kernel.
struct MergePart<'a, const TABLES: bool> {
    part: &'a RegionGBuffer,
    out: &'a mut RegionGBuffer,
    src: &'a mut [u32],
    k: u32,
}

impl<const TABLES: bool> Kernel for MergePart<'_, TABLES> {
    type Output = ();
    #[inline(always)]
    fn run<S: Simd>(self, simd: S) {
        let MergePart { part, out, src, k } = self;
        let n = out.depth.len();
        for len in [
            part.depth.len(),
            part.polygon.len(),
            part.u.len(),
            part.v.len(),
        ] {
            assert_eq!(len, n, "merged G-buffers differ in size");
        }
        assert!(!TABLES || (src.len() == n && part.slot.len() == n && out.slot.len() == n));
        let mut i = 0;
        while i + S::LANES <= n {
            merge_step::<S, TABLES>(simd, part, out, src, k, i);
            i += S::LANES;
        }
        // A 16-lane build ends with its 8-lane half, and any buffer with a scalar tail (every
        // G-buffer's length is a multiple of 8, so neither loop runs with the 8-lane builds).
        while i + LANES <= n {
            merge_step::<S::Half, TABLES>(simd.half(), part, out, src, k, i);
            i += LANES;
        }
        for i in i..n {
            let (d, od) = (part.depth[i], out.depth[i]);
            if (d < od) | ((d == od) & (part.polygon[i] < out.polygon[i])) {
                out.depth[i] = d;
                out.polygon[i] = part.polygon[i];
                out.u[i] = part.u[i];
                out.v[i] = part.v[i];
                if TABLES {
                    out.slot[i] = part.slot[i];
                    src[i] = k;
                }
            }
        }
    }
}

/// One step of [`merge_part`]: the `S::LANES` samples from `i`, compared in lanes and written
/// with full-width blends.
#[inline(always)]
fn merge_step<S: Simd, const TABLES: bool>(
    simd: S,
    part: &RegionGBuffer,
    out: &mut RegionGBuffer,
    src: &mut [u32],
    k: u32,
    i: usize,
) {
    let d = simd.load(&part.depth[i..]);
    let od = simd.load(&out.depth[i..]);
    let p = simd.load_u(&part.polygon[i..]);
    let op = simd.load_u(&out.polygon[i..]);
    let tie = simd.and_m(simd.eq(d, od), simd.lt_u(p, op));
    let take = simd.or_m(simd.lt(d, od), tie);
    if !simd.any(take) {
        return;
    }
    simd.blend_store(&mut out.depth[i..], d, take);
    simd.blend_store_u(&mut out.polygon[i..], p, take);
    simd.blend_store(&mut out.u[i..], simd.load(&part.u[i..]), take);
    simd.blend_store(&mut out.v[i..], simd.load(&part.v[i..]), take);
    if TABLES {
        simd.blend_store_u(&mut out.slot[i..], simd.load_u(&part.slot[i..]), take);
        simd.blend_store_u(&mut src[i..], simd.splat_u(k), take);
    }
}

/// Merges the pixel records (depth, polygon, u, v) of one region's reports, one per renderer
/// that had primitives there, into `parts[0]` by depth then polygon id, as [`composite_in_place`]
/// does, for reports that carry no patch table: the frame stage locates the patches once, in the
/// merged region ([`RegionGBuffer::assign_patches_with`]), which gives the table and slots
/// [`composite_in_place`] would have rebuilt (memory order of first use, and each sample's patch
/// is a function of its polygon and (u, v)) without locating the hidden samples of every report.
/// `parts[1..]` are left as they were; slots are not merged.
#[cfg(any(test, feature = "bench"))]
pub fn merge_records_in_place(isa: Isa, parts: &mut [RegionGBuffer]) {
    if parts.len() <= 1 {
        return;
    }
    let (head, rest) = parts.split_at_mut(1);
    for part in rest.iter() {
        merge_records_into(isa, &mut head[0], part);
    }
}

/// Merges one report's pixel records into the running composite `out` (as
/// `merge_records_in_place` does for each of `parts[1..]`): a streaming merge, one report at a
/// time as each renderer finishes, so the frame stage needs two G-buffers per region whatever
/// the number of renderers. The merge being commutative and associative, the composite is the
/// same for any order of the reports.
pub fn merge_records_into(isa: Isa, out: &mut RegionGBuffer, part: &RegionGBuffer) {
    merge_part::<false>(isa, part, out, &mut [], 0);
}

/// Merges the reports of one region (in any order) into one G-buffer with a canonical table
/// ([`composite_in_place`] on owned buffers).
#[cfg(test)]
pub(crate) fn composite(isa: Isa, mut parts: Vec<RegionGBuffer>) -> RegionGBuffer {
    composite_in_place(isa, &mut parts, &mut MergeScratch::default());
    parts.swap_remove(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every instruction set this CPU has (the engine's `isa_variants` test reports those it
    /// lacks).
    fn isas() -> Vec<Isa> {
        lanes::Level::ALL.into_iter().filter_map(Isa::at).collect()
    }

    fn part(depths: &[f32], polys: &[u32], ids: &[u32]) -> RegionGBuffer {
        let mut g = RegionGBuffer::new(0, 0, 0, 8, 1, 1);
        for i in 0..8 {
            g.depth[i] = depths[i];
            g.polygon[i] = polys[i];
            g.u[i] = polys[i] as f32 * 0.01;
        }
        for i in 0..8 {
            if polys[i] == NO_POLYGON {
                continue;
            }
            let id = ids[i];
            let s = match g.table_ids.iter().position(|&x| x == id) {
                Some(s) => s,
                None => {
                    let mut c = PatchCoeffs::whole([[0.0; 16]; 3]);
                    c.c[0][0] = id as f32;
                    g.table.push(c);
                    g.table_ids.push(id);
                    g.table.len() - 1
                }
            };
            g.slot[i] = s as u32;
        }
        g
    }

    #[test]
    fn merge_is_by_depth_then_polygon_and_independent_of_order() {
        const N: u32 = NO_POLYGON;
        let inf = f32::INFINITY;
        let a = part(
            &[1.0, 2.0, 3.0, inf, 5.0, 1.0, 2.0, inf],
            &[1, 1, 1, N, 3, 3, 3, N],
            &[10, 10, 11, 0, 30, 30, 31, 0],
        );
        let b = part(
            &[2.0, 1.0, 3.0, 4.0, inf, 1.0, 2.5, inf],
            &[2, 2, 0, 0, N, 2, 2, N],
            &[20, 21, 5, 5, 0, 21, 20, 0],
        );
        let ab = composite(Isa::detect(), vec![a.clone(), b.clone()]);
        let ba = composite(Isa::detect(), vec![b.clone(), a.clone()]);
        assert_eq!(ab, ba);
        for isa in isas() {
            assert_eq!(
                composite(isa, vec![a.clone(), b.clone()]),
                ab,
                "{}",
                isa.name()
            );
        }
        assert_eq!(ab.polygon, vec![1, 2, 0, 0, 3, 2, 3, N]);
        assert_eq!(ab.depth[..7], [1.0, 1.0, 3.0, 4.0, 5.0, 1.0, 2.0]);
        // Table in order of first use, deduplicated: 10, 21, 5, 30, 31.
        assert_eq!(ab.table_ids, vec![10, 21, 5, 30, 31]);
        assert_eq!(ab.slot[..7], [0, 1, 2, 2, 3, 1, 4]);
        for i in 0..7 {
            let id = ab.table_ids[ab.slot[i] as usize];
            assert_eq!(ab.table[ab.slot[i] as usize].c[0][0], id as f32);
        }
    }

    #[test]
    fn parts_without_patch_tables_merge_by_depth() {
        // Regression: texture and reference frames fill no patch tables; merging two renderers'
        // parts indexed the empty tables and panicked the compositor thread.
        const N: u32 = NO_POLYGON;
        let inf = f32::INFINITY;
        let mut a = part(
            &[1.0, 2.0, inf, inf, inf, inf, inf, inf],
            &[4, 4, N, N, N, N, N, N],
            &[0; 8],
        );
        let mut b = part(
            &[2.0, 1.0, 3.0, inf, inf, inf, inf, inf],
            &[7, 7, 7, N, N, N, N, N],
            &[0; 8],
        );
        for g in [&mut a, &mut b] {
            g.table.clear();
            g.table_ids.clear();
            g.slot.fill(0);
        }
        let m = composite(Isa::detect(), vec![a, b]);
        assert_eq!(m.polygon[..4], [4, 7, 7, N]);
        assert!(m.table.is_empty() && m.slot.iter().all(|&s| s == 0));
    }

    /// Patches keyed by polygon and the half of the domain u falls in.
    struct Halves;

    impl reconstruction::PatchSource for Halves {
        fn locate(&self, polygon: u32, u: f32, _v: f32) -> u32 {
            2 * polygon + (u >= 0.5) as u32
        }
        fn patch(&self, id: u32) -> PatchCoeffs {
            let mut c = PatchCoeffs::whole([[0.0; 16]; 3]);
            c.c[1][3] = id as f32;
            c
        }
    }

    #[test]
    fn merging_records_then_locating_patches_equals_merging_tables() {
        // Three renderers' reports of a 16 x 3 region with ties, hidden samples and empty ones.
        let mut seed = base::rng::Rng::new(5);
        let mut rnd = |n: u64| seed.below(n as u32) as u64;
        for _ in 0..50 {
            let parts: Vec<RegionGBuffer> = (0..3)
                .map(|_| {
                    let mut g = RegionGBuffer::new(0, 0, 0, 16, 3, 1);
                    for i in 0..g.len() {
                        if rnd(4) == 0 {
                            continue;
                        }
                        g.depth[i] = 1.0 + rnd(3) as f32;
                        g.polygon[i] = rnd(5) as u32;
                        g.u[i] = rnd(4) as f32 * 0.25;
                        g.v[i] = rnd(4) as f32 * 0.25;
                    }
                    g
                })
                .collect();
            let mut with_tables = parts.clone();
            for g in with_tables.iter_mut() {
                g.assign_patches(&Halves);
            }
            let want = composite(Isa::detect(), with_tables);
            let mut got = parts;
            merge_records_in_place(Isa::detect(), &mut got);
            let got = &mut got[0];
            got.assign_patches(&Halves);
            assert_eq!(got.polygon, want.polygon);
            assert_eq!(got.depth, want.depth);
            assert_eq!(got.table_ids, want.table_ids);
            assert_eq!(got.table, want.table);
            for i in 0..got.len() {
                if got.polygon[i] != NO_POLYGON {
                    assert_eq!((got.u[i], got.v[i]), (want.u[i], want.v[i]));
                    assert_eq!(got.slot[i], want.slot[i], "sample {i}");
                }
            }
        }
    }

    #[test]
    fn the_records_merge_follows_the_scalar_rule_in_every_build_and_tail() {
        // Widths 8, 16 and 24: no 16-lane step, whole steps, and steps plus an 8-lane tail.
        // Depths with ties, -0 against +0, inf (empty) and NaN (never taken, never replaced:
        // ordered comparisons); polygon ids with the top bit set (the comparison is unsigned).
        const DEPTHS: [f32; 6] = [1.0, 2.0, -0.0, 0.0, f32::INFINITY, f32::NAN];
        const IDS: [u32; 4] = [3, 7, 0x8000_0001, NO_POLYGON];
        let mut seed = base::rng::Rng::new(11);
        let mut rnd = |n: usize| seed.below(n as u32) as usize;
        for width in [8, 16, 24] {
            for _ in 0..40 {
                let mut make = || {
                    let mut g = RegionGBuffer::new(0, 0, 0, width, 2, 1);
                    for i in 0..g.len() {
                        g.depth[i] = DEPTHS[rnd(DEPTHS.len())];
                        g.polygon[i] = IDS[rnd(IDS.len())];
                        g.u[i] = rnd(8) as f32 * 0.125;
                        g.v[i] = rnd(8) as f32 * 0.125;
                    }
                    g
                };
                let (out, part) = (make(), make());
                let mut want = out.clone();
                for i in 0..want.len() {
                    let (d, od) = (part.depth[i], want.depth[i]);
                    if d < od || (d == od && part.polygon[i] < want.polygon[i]) {
                        want.depth[i] = d;
                        want.polygon[i] = part.polygon[i];
                        want.u[i] = part.u[i];
                        want.v[i] = part.v[i];
                    }
                }
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                for isa in isas() {
                    let mut got = out.clone();
                    merge_records_into(isa, &mut got, &part);
                    let at = format!("width {width}, {}", isa.name());
                    assert_eq!(bits(&got.depth), bits(&want.depth), "{at}");
                    assert_eq!(got.polygon, want.polygon, "{at}");
                    assert_eq!(bits(&got.u), bits(&want.u), "{at}");
                    assert_eq!(bits(&got.v), bits(&want.v), "{at}");
                }
            }
        }
    }
}
