//! Composition: the stage between the renderers and the shaders. With R virtual renderers, each
//! rasterizes a round-robin share of the primitives into full-screen region G-buffers; the
//! composition network merges, region by region, the G-buffers of every renderer that had
//! primitives there into one, by depth, ties broken by the smaller polygon id, then hands the
//! composited region on to the deferred shading stage. PixelFlow built this network in hardware
//! (a pipelined z-compare over all renderers: Molnar, Eyles and Poulton, SIGGRAPH 1992); here it is a compositor thread
//! between crossbeam channels: renderer tasks -> compositor -> shading.
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

use std::collections::HashMap;
use std::time::{Duration, Instant};

use crossbeam::channel::{Receiver, Sender};

use crate::raster::gbuffer::{IdMap, RegionGBuffer, NO_POLYGON};
use crate::reconstruction::PatchCoeffs;

pub use crate::raster::gbuffer::PIXEL_RECORD_BYTES;

/// One renderer's G-buffer of one region, as it travels to the compositor.
#[derive(Debug)]
pub struct RegionReport {
    /// The renderer that produced it.
    pub renderer: u32,
    /// Covered samples the renderer rasterized (fragments, before its depth test).
    pub fragments: u64,
    /// The G-buffer.
    pub gbuffer: RegionGBuffer,
}

/// What the compositor did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CompositorStats {
    /// Bytes that crossed the network (reports in, composited regions out).
    pub traffic_bytes: u64,
    /// Time spent merging.
    pub busy: Duration,
    /// Regions composited.
    pub regions: u32,
    /// Fragments reported by the renderers.
    pub fragments: u64,
}

/// Merges the reports of one region (in any order) into one G-buffer with a canonical table.
pub fn composite(mut parts: Vec<RegionGBuffer>) -> RegionGBuffer {
    if parts.len() == 1 {
        return parts.pop().expect("one part");
    }
    let mut out = parts[0].clone();
    let n = out.len();
    let mut src = vec![0u16; n];
    for (k, part) in parts.iter().enumerate().skip(1) {
        for i in 0..n {
            let (d, p) = (part.depth[i], part.polygon[i]);
            let take = d < out.depth[i] || (d == out.depth[i] && p < out.polygon[i]);
            if take {
                out.depth[i] = d;
                out.polygon[i] = p;
                out.u[i] = part.u[i];
                out.v[i] = part.v[i];
                out.slot[i] = part.slot[i];
                src[i] = k as u16;
            }
        }
    }
    // Shaders without patches (textures, the reference) leave every table empty: nothing to
    // rebuild, and no slot means anything.
    if parts.iter().all(|p| p.table_ids.is_empty()) {
        out.slot.fill(0);
        return out;
    }
    // Canonical table: memory order of first use.
    let mut index = IdMap::default();
    let mut table: Vec<PatchCoeffs> = Vec::new();
    let mut ids = Vec::new();
    for i in 0..n {
        if out.polygon[i] == NO_POLYGON {
            out.slot[i] = 0;
            continue;
        }
        let part = &parts[src[i] as usize];
        let old = out.slot[i] as usize;
        let id = part.table_ids[old];
        out.slot[i] = *index.entry(id).or_insert_with(|| {
            table.push(part.table[old]);
            ids.push(id);
            (table.len() - 1) as u32
        });
    }
    out.table = table;
    out.table_ids = ids;
    out
}

/// The compositor stage: receives reports until each region has `expected[region]` of them,
/// merges it and sends it on. Returns when every sender is gone.
pub fn compositor(
    rx: Receiver<RegionReport>,
    tx: Sender<RegionGBuffer>,
    expected: &[u32],
) -> CompositorStats {
    let mut stats = CompositorStats::default();
    let mut pending: HashMap<u32, Vec<RegionGBuffer>> = HashMap::new();
    for report in rx {
        stats.fragments += report.fragments;
        stats.traffic_bytes += report.gbuffer.bytes();
        let region = report.gbuffer.region;
        let parts = pending.entry(region).or_default();
        parts.push(report.gbuffer);
        if parts.len() as u32 >= expected[region as usize] {
            let parts = pending.remove(&region).unwrap_or_default();
            let t = Instant::now();
            let out = composite(parts);
            stats.busy += t.elapsed();
            stats.traffic_bytes += out.bytes();
            stats.regions += 1;
            if tx.send(out).is_err() {
                break;
            }
        }
    }
    stats
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
