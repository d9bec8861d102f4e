//! Composition: the stage between the renderers and the shaders. With R virtual renderers, each
//! rasterizes a round-robin share of the primitives into full-screen region G-buffers; the
//! composition network merges, region by region, the G-buffers of every renderer that had
//! primitives there into one, by depth, ties broken by the smaller polygon id, then hands the
//! composited region on to the deferred shading stage. PixelFlow built this network in hardware
//! (a pipelined z-compare over all renderers: Molnar, Eyles and Poulton, SIGGRAPH 1992) running
//! concurrently with rasterization; here the merge runs inside each region's task
//! ([`crate::frame::FrameContext::render`]), on whichever worker rasterized the region, while
//! the other workers rasterize other regions: the network is as parallel as the regions are, and
//! its buffers are still in cache when it merges them ([`composite_in_place`]).
//!
//! Invariants: the merge is commutative and associative (depth, then polygon id, is a total order
//! on distinct polygons), and after merging the patch table is renumbered in memory order of first
//! use, so a composited region is bit-identical for every R, every thread count and every arrival
//! order. With one report for a region the report is passed through unchanged: the renderer built
//! its table in the same canonical order.
//!
//! Traffic model: every report that crosses the network costs its pixel records
//! ([`PIXEL_RECORD_BYTES`] per sample) plus its patch table; the composited region sent on to the
//! shaders costs the same again. Renderers with no primitive binned in a region send nothing (a
//! renderer skips its empty regions), and regions no renderer touches cost nothing at all.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

use crate::lanes::LANES;

use crate::raster::gbuffer::{IdMap, RegionGBuffer, NO_POLYGON};
use crate::reconstruction::PatchCoeffs;

pub use crate::raster::gbuffer::PIXEL_RECORD_BYTES;

/// Working memory of [`composite_in_place`], kept across regions and frames by the frame stage.
#[derive(Debug, Default)]
pub struct MergeScratch {
    /// Per sample: which part the composited sample came from.
    src: Vec<u16>,
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
pub fn composite_in_place(parts: &mut [RegionGBuffer], scratch: &mut MergeScratch) {
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
        let k = (k + 1) as u16;
        assert_eq!(
            part.len(),
            n,
            "composited parts of one region differ in size"
        );
        // Blocks of 8 with lane-wise selects: the take test is a total order on distinct
        // polygons, so the result does not depend on the order of the parts.
        for b0 in (0..n).step_by(LANES) {
            let r = b0..b0 + LANES;
            let d: &[f32; LANES] = part.depth[r.clone()].try_into().unwrap();
            let p: &[u32; LANES] = part.polygon[r.clone()].try_into().unwrap();
            let od: &mut [f32; LANES] = (&mut out.depth[r.clone()]).try_into().unwrap();
            let op: &mut [u32; LANES] = (&mut out.polygon[r.clone()]).try_into().unwrap();
            let mut take = [false; LANES];
            let mut any = false;
            for l in 0..LANES {
                take[l] = (d[l] < od[l]) | ((d[l] == od[l]) & (p[l] < op[l]));
                any |= take[l];
            }
            if !any {
                continue;
            }
            for l in 0..LANES {
                if take[l] {
                    let i = b0 + l;
                    od[l] = d[l];
                    op[l] = p[l];
                    out.u[i] = part.u[i];
                    out.v[i] = part.v[i];
                    out.slot[i] = part.slot[i];
                    src[i] = k;
                }
            }
        }
    }
    // Shaders without patches (textures, the reference) leave every table empty: nothing to
    // rebuild, and no slot means anything.
    if out.table_ids.is_empty() && rest.iter().all(|p| p.table_ids.is_empty()) {
        out.slot.fill(0);
        return;
    }
    // Canonical table: memory order of first use. Each (part, old slot) pair asks the id map
    // once; later samples of the same pair read the per-part remap.
    let remap = &mut scratch.remap;
    if remap.len() < rest.len() + 1 {
        remap.resize_with(rest.len() + 1, Vec::new);
    }
    remap[0].clear();
    remap[0].resize(out.table_ids.len(), u32::MAX);
    for (k, part) in rest.iter().enumerate() {
        remap[k + 1].clear();
        remap[k + 1].resize(part.table_ids.len(), u32::MAX);
    }
    let (index, table, ids) = (&mut scratch.index, &mut scratch.table, &mut scratch.ids);
    index.clear();
    table.clear();
    ids.clear();
    for i in 0..n {
        if out.polygon[i] == NO_POLYGON {
            out.slot[i] = 0;
            continue;
        }
        let k = src[i] as usize;
        let old = out.slot[i] as usize;
        let new = remap[k][old];
        if new != u32::MAX {
            out.slot[i] = new;
            continue;
        }
        let (part_table, part_ids) = if k == 0 {
            (&out.table, &out.table_ids)
        } else {
            (&rest[k - 1].table, &rest[k - 1].table_ids)
        };
        let id = part_ids[old];
        let slot = *index.entry(id).or_insert_with(|| {
            table.push(part_table[old]);
            ids.push(id);
            (table.len() - 1) as u32
        });
        remap[k][old] = slot;
        out.slot[i] = slot;
    }
    std::mem::swap(&mut out.table, table);
    std::mem::swap(&mut out.table_ids, ids);
}

/// Merges the reports of one region (in any order) into one G-buffer with a canonical table
/// ([`composite_in_place`] on owned buffers).
pub fn composite(mut parts: Vec<RegionGBuffer>) -> RegionGBuffer {
    composite_in_place(&mut parts, &mut MergeScratch::default());
    parts.swap_remove(0)
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let ab = composite(vec![a.clone(), b.clone()]);
        let ba = composite(vec![b, a]);
        assert_eq!(ab, ba);
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
        let m = composite(vec![a, b]);
        assert_eq!(m.polygon[..4], [4, 7, 7, N]);
        assert!(m.table.is_empty() && m.slot.iter().all(|&s| s == 0));
    }
}
