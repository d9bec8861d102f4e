//! Adaptive subdivision of the quadtrees against the true radiosity (the solve's step 3 and
//! 5, see the parent module): which leaves split, the depth and size limits, and the memory
//! guard of each refinement pass.

use glam::DVec3;
use rayon::prelude::*;

use super::{lum, memory_error, rebuild_leaves, state_bytes, Poly};
use crate::transfer::{PairClass, ShooterKind, Transfer};
use base::error::Result;
use base::quadtree::{Cell, VertexKey};
use scene::Scene;

/// Floor of the refinement criterion, as a fraction of the brightest reflected radiosity
/// (luminance) sampled so far: an element's variation is judged relative to its own level, but
/// never to a level below this fraction of the peak, so that dark regions (where any noise is a
/// large relative change) do not refine to the depth limit.
pub const REFINE_FLOOR: f64 = 0.01;

/// The brightest reflected radiosity rho * G (luminance) at any vertex of a reflecting polygon.
fn peak_reflected(polys: &[Poly]) -> f64 {
    polys
        .iter()
        .filter(|p| lum(p.rho) > 0.0)
        .flat_map(|p| p.g.iter().map(|g| lum(p.rho * *g)))
        .fold(0.0, f64::max)
}

/// Adaptive subdivision against the true radiosity; returns the number of splits.
///
/// A leaf splits (below `max_depth` and above [`min_element_size`]) when either
/// - **variation**: at its centre or an edge midpoint the reflected radiosity rho * G differs
///   from the bilinear prediction of its corners by more than `tolerance * level` (luminance of
///   the per-channel difference), `level` being the larger of the leaf's own level (the mean
///   luminance of rho * G over its corners and test points) and [`REFINE_FLOOR`] times the
///   peak; nothing in this test depends on the polygon's area or shape, so thin and small
///   polygons refine like large ones; or
/// - **visibility**: for a light (spot or emitter) with occluders between it and the polygon,
///   the visible fraction of the light differs across the leaf's corners and test points (a
///   shadow boundary crosses it) and the light's unshadowed contribution times that difference
///   exceeds the same `tolerance * level`: the leaf is split toward the boundary, down to the
///   depth limit, even where the bilinear prediction happens to agree at the test points.
pub(super) fn refine(
    scene: &Scene,
    tr: &Transfer<'_>,
    polys: &mut [Poly],
    totals: &[DVec3],
    (base, depth): (&[u32], &[u32]),
    memory_limit: u64,
) -> Result<usize> {
    let st = &scene.radiosity;
    let tol = st.tolerance;
    if tol <= 0.0 || !tol.is_finite() {
        return Ok(0);
    }
    // The memory guard: nodes and samples held now, and the pair tables built so far (they do
    // not grow while refining).
    let mut nodes: u64 = polys.iter().map(|p| p.tree.nodes().len() as u64).sum();
    let mut vertices: u64 = polys.iter().map(|p| p.keys.len() as u64).sum();
    let pair_bytes = tr.pair_bytes();
    let mut peak = peak_reflected(polys);
    // The lights that have shot (their shadows drive the visibility test) and, per polygon,
    // those whose pairs with it may be occluded, ascending (from the per-receiver index, so
    // this costs the pairs, not lights x polygons).
    let is_light: Vec<bool> = (0..tr.shooters.len())
        .map(|s| {
            !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }) && totals[s] != DVec3::ZERO
        })
        .collect();
    let shadow_lights: Vec<Vec<usize>> = (0..polys.len())
        .map(|r| {
            tr.shooters_of(r)
                .iter()
                .map(|&(s, _)| s as usize)
                .filter(|&s| {
                    is_light[s]
                        && tr.pairs[s]
                            .as_ref()
                            .is_some_and(|p| p.class(r) == PairClass::Occluded)
                })
                .collect()
        })
        .collect();
    let min_size = min_element_size(scene);
    let mut pending: Vec<(u32, u32)> = Vec::new();
    for (r, p) in polys.iter().enumerate() {
        if p.rho.max_element() <= 0.0 {
            // A non-reflecting polygon's radiosity is its constant emission.
            continue;
        }
        for id in p.tree.leaves() {
            if can_split(scene, r, p.tree.node(id).cell, min_size) {
                pending.push((r as u32, id));
            }
        }
    }
    let mut splits = 0;
    while !pending.is_empty() {
        // Probe keys not yet vertices, per polygon, deduplicated and sorted.
        let mut probes: Vec<(u32, VertexKey)> = Vec::new();
        // Every point (corners and test points) of a pending leaf that some light's shadow
        // may cross.
        let mut shadow_keys: Vec<(u32, VertexKey)> = Vec::new();
        for &(r, id) in &pending {
            let p = &polys[r as usize];
            let cell = p.tree.node(id).cell;
            for k in test_points(cell) {
                if p.keys.binary_search(&k).is_err() {
                    probes.push((r, k));
                }
            }
            if !shadow_lights[r as usize].is_empty() {
                shadow_keys.extend(
                    cell.corners()
                        .iter()
                        .chain(&test_points(cell))
                        .map(|&k| (r, k)),
                );
            }
        }
        probes.sort_unstable();
        probes.dedup();
        shadow_keys.sort_unstable();
        shadow_keys.dedup();
        let vals: Vec<DVec3> = probes
            .par_iter()
            .map(|&(r, k)| tr.gather(totals, r as usize, k.u(), k.v()))
            .collect();
        // Per shadow key and light (in `lights` order; lights without occluders toward the
        // polygon are skipped): the unshadowed reflected luminance and the visible fraction.
        let shadows: Vec<Vec<(f64, f64)>> = shadow_keys
            .par_iter()
            .map(|&(r, k)| {
                let rho = polys[r as usize].rho;
                shadow_lights[r as usize]
                    .iter()
                    .map(|&s| {
                        let (open, vis) = tr.shadowed(s, r as usize, k.u(), k.v());
                        (lum(rho * totals[s] * open), vis)
                    })
                    .collect()
            })
            .collect();
        for (&(r, _), g) in probes.iter().zip(&vals) {
            peak = peak.max(lum(polys[r as usize].rho * *g));
        }
        let floor = REFINE_FLOOR * peak;
        let probe_g = |r: u32, k: VertexKey, polys: &[Poly]| -> DVec3 {
            let p = &polys[r as usize];
            match p.keys.binary_search(&k) {
                Ok(i) => p.g[i],
                Err(_) => {
                    let i = probes
                        .binary_search(&(r, k))
                        .expect("every test point was probed");
                    vals[i]
                }
            }
        };
        let mut split_now: Vec<(u32, u32)> = Vec::new();
        for &(r, id) in &pending {
            let p = &polys[r as usize];
            let cell = p.tree.node(id).cell;
            let c = cell.corners().map(|k| probe_g(r, k, polys));
            let tp = test_points(cell);
            let t = tp.map(|k| probe_g(r, k, polys));
            let level = c.iter().chain(&t).map(|g| lum(p.rho * *g)).sum::<f64>() / 9.0;
            let thresh = tol * level.max(floor);
            let pred = [
                0.25 * (c[0] + c[1] + c[2] + c[3]),
                0.5 * (c[0] + c[1]),
                0.5 * (c[1] + c[2]),
                0.5 * (c[2] + c[3]),
                0.5 * (c[3] + c[0]),
            ];
            let varies = t.iter().zip(pred).any(|(g, pr)| {
                let d = p.rho * (*g - pr);
                lum(d.abs()) > thresh
            });
            let shadowed = !varies && !shadow_lights[r as usize].is_empty() && {
                let at = |k: VertexKey| {
                    let i = shadow_keys
                        .binary_search(&(r, k))
                        .expect("every point of a shadowed leaf was tested");
                    &shadows[i]
                };
                let pts: Vec<&Vec<(f64, f64)>> =
                    cell.corners().iter().chain(&tp).map(|&k| at(k)).collect();
                let n = pts.first().map_or(0, |v| v.len());
                (0..n).any(|j| {
                    let (mut lo, mut hi, mut open) = (f64::INFINITY, f64::NEG_INFINITY, 0f64);
                    for q in &pts {
                        let (a, v) = q[j];
                        lo = lo.min(v);
                        hi = hi.max(v);
                        open = open.max(a);
                    }
                    hi > lo && open * (hi - lo) > thresh
                })
            };
            if varies || shadowed {
                split_now.push((r, id));
            }
        }
        // Each split adds 4 nodes and at most 5 samples (4 edge midpoints and the centre).
        let k = split_now.len() as u64;
        let (n_after, v_after) = (nodes + 4 * k, vertices + 5 * k);
        let need = state_bytes(n_after, v_after).saturating_add(pair_bytes);
        if need > memory_limit {
            return Err(memory_error(
                scene,
                need,
                memory_limit,
                format!(
                    "{n_after} quadtree nodes and up to {v_after} samples in this refinement \
                     pass, pair tables {}",
                    base::error::human_bytes(pair_bytes)
                ),
            ));
        }
        (nodes, vertices) = (n_after, v_after);
        let mut next = Vec::new();
        let mut touched: Vec<u32> = Vec::new();
        for &(r, id) in &split_now {
            let p = &mut polys[r as usize];
            let f = p.tree.split(id);
            splits += 1;
            for c in f..f + 4 {
                if can_split(scene, r as usize, p.tree.node(c).cell, min_size) {
                    next.push((r, c));
                }
            }
            touched.push(r);
        }
        touched.dedup();
        for &r in &touched {
            let keys = polys[r as usize].tree.vertex_keys();
            let g: Vec<DVec3> = keys.iter().map(|&k| probe_g(r, k, polys)).collect();
            let p = &mut polys[r as usize];
            p.keys = keys;
            p.g = g;
            rebuild_leaves(scene, r as usize, p, base, depth);
        }
        pending = next;
    }
    Ok(splits)
}

/// Smallest element edge worth splitting: the scene's bounding diagonal / 2^max_depth. Depth
/// limits are per polygon, so without this a small polygon (a 1 m floor tile in a 15 m hall)
/// would be refined to elements far smaller than a large one's at the same depth; with it,
/// `max_depth` means "the scene resolved to 1 / 2^max_depth of its size" everywhere.
pub fn min_element_size(scene: &Scene) -> f64 {
    let (lo, hi) = scene.bounds();
    (hi - lo).length() / (1u64 << scene.radiosity.max_depth.min(63)) as f64
}

/// Whether a leaf may split: below max_depth, and its longer world-space edge (at the cell's
/// centre) is longer than `min_size`.
///
/// Both tangents of a polygon are at most its longest edge long everywhere (for a quad a convex
/// combination of two opposite edges, for a triangle at most an edge), which bounds the depth
/// any of its leaves can reach: [`depth_bound`].
fn can_split(scene: &Scene, r: usize, cell: Cell, min_size: f64) -> bool {
    if cell.level >= scene.radiosity.max_depth {
        return false;
    }
    let (u0, v0, u1, v1) = cell.bounds();
    let (du, dv) = scene.polygons[r].tangents(0.5 * (u0 + u1), 0.5 * (v0 + v1));
    let w = u1 - u0;
    (du.length() * w).max(dv.length() * w) > min_size
}

/// The deepest level polygon `r`'s leaves can reach by refinement: `max_depth`, or less where
/// the polygon's longest edge `L` halved `d` times is already within the smallest element size
/// (`can_split` refuses a cell whose edges are all at most that). The starting depth may
/// exceed it (min_depth and shooter patches are imposed, not refined).
pub fn depth_bound(scene: &Scene, r: usize, min_size: f64) -> u32 {
    let vs = scene.polygons[r].vertices();
    let longest = (0..vs.len())
        .map(|i| (vs[(i + 1) % vs.len()] - vs[i]).length())
        .fold(0.0f64, f64::max);
    let max = scene.radiosity.max_depth;
    let mut d = 0;
    let mut edge = longest;
    while d < max && edge > min_size {
        edge *= 0.5;
        d += 1;
    }
    d
}

/// Centre and the four edge midpoints (bottom, right, top, left) of a cell.
fn test_points(cell: Cell) -> [VertexKey; 5] {
    let o = cell.origin();
    let s = cell.size();
    let h = s / 2;
    [
        VertexKey::new(o.i + h, o.j + h),
        VertexKey::new(o.i + h, o.j),
        VertexKey::new(o.i + s, o.j + h),
        VertexKey::new(o.i + h, o.j + s),
        VertexKey::new(o.i, o.j + h),
    ]
}
