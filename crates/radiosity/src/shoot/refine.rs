//! Adaptive subdivision of the quadtrees against the true radiosity (the solve's step 3 and
//! 5, see the parent module): which leaves split, the depth and size limits, and the memory
//! guard of each refinement pass.

use glam::DVec3;
use rayon::prelude::*;

use super::poly::{cell_order, PatchLayout, Poly};
use super::{lum, memory_error, state_bytes};
use crate::transfer::{PairClass, ShooterKind, Transfer};
use crate::GuardStops;
use base::error::{human_bytes, Result};
use base::quadtree::{Cell, VertexKey};
use scene::Scene;

/// Floor of the refinement criterion, as a fraction of the brightest reflected radiosity
/// (luminance) sampled so far: an element's variation is judged relative to its own level, but
/// never to a level below this fraction of the peak, so that dark regions (where any noise is a
/// large relative change) do not refine to the depth limit.
pub const REFINE_FLOOR: f64 = 0.01;

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
///
/// The leaves are judged a generation at a time: the splittable leaves, then the children of
/// those that split, until none splits. Every G the pass computes is the oracle's gather from
/// `totals`, and the new vertices keep it.
pub(super) fn refine(
    scene: &Scene,
    tr: &Transfer<'_>,
    polys: &mut [Poly],
    totals: &[DVec3],
    patches: &PatchLayout,
    memory_limit: u64,
    guarded: &mut GuardStops,
) -> Result<usize> {
    let tolerance = scene.radiosity.tolerance;
    if tolerance <= 0.0 || !tolerance.is_finite() {
        return Ok(0);
    }
    let mut pass = Refinement::new(scene, tr, polys, totals, memory_limit);

    let mut pending = pass.splittable_leaves(polys);
    let mut splits = 0;
    for p in polys.iter_mut() {
        p.tests.clear();
    }
    while !pending.is_empty() {
        let probes = pass.probe(polys, &pending);
        let split_now = pass.leaves_to_split(polys, &pending, &probes, guarded);
        keep_tests(polys, &pending, &split_now, &probes);
        pass.memory.admit(scene, split_now.len() as u64)?;
        splits += split_now.len();
        pending = pass.split(polys, &split_now, &probes, patches);
    }
    for p in polys.iter_mut() {
        p.tests.sort_unstable_by_key(|(c, _)| cell_order(*c));
    }
    Ok(splits)
}

/// Keeps G at the test points of the `pending` leaves that do not split (`split_now` is a
/// subsequence of `pending`): the patches' integrals use them (Simpson's rule).
fn keep_tests(
    polys: &mut [Poly],
    pending: &[(u32, u32)],
    split_now: &[(u32, u32)],
    probes: &Probes,
) {
    let mut k = 0;
    for &(r, id) in pending {
        if k < split_now.len() && split_now[k] == (r, id) {
            k += 1;
            continue;
        }
        let p = &polys[r as usize];
        let cell = p.tree.node(id).cell;
        let g = test_points(cell).map(|t| probes.g_at(p, r, t));
        polys[r as usize].tests.push((cell, g));
    }
}

/// One refinement pass: what judges the leaves, and the memory guard.
struct Refinement<'r, 't> {
    scene: &'r Scene,
    tr: &'r Transfer<'t>,
    totals: &'r [DVec3],
    /// The scene's `radiosity.tolerance`.
    tolerance: f64,
    /// [`min_element_size`] of the scene.
    min_size: f64,
    /// The lights (emitters and spots) as spheres: where a light is small and close, its
    /// light varies over less than the guards' smallest element ([`Refinement::may_split`]).
    lights: Vec<(DVec3, f64)>,
    /// The brightest reflected luminance sampled so far (the criterion's floor follows it).
    peak: f64,
    /// Per polygon: the lights that have shot and whose pairs with it may be occluded,
    /// ascending (their shadows drive the visibility test).
    shadow_lights: Vec<Vec<usize>>,
    memory: MemoryGuard,
}

/// The memory guard of a refinement pass: nodes and samples held, and the pair tables built so
/// far (they do not grow while refining).
struct MemoryGuard {
    nodes: u64,
    vertices: u64,
    pair_bytes: u64,
    limit: u64,
}

impl MemoryGuard {
    /// Admits `splits` more splits, each adding 4 nodes and at most 5 samples (4 edge midpoints
    /// and the centre), or stops the solve with [`base::error::Error::Memory`] before they
    /// allocate.
    fn admit(&mut self, scene: &Scene, splits: u64) -> Result<()> {
        let (nodes, vertices) = (self.nodes + 4 * splits, self.vertices + 5 * splits);
        let need = state_bytes(nodes, vertices).saturating_add(self.pair_bytes);
        if need > self.limit {
            return Err(memory_error(
                scene,
                need,
                self.limit,
                format!(
                    "{nodes} quadtree nodes and up to {vertices} samples in this refinement \
                     pass, pair tables {}",
                    human_bytes(self.pair_bytes)
                ),
            ));
        }
        (self.nodes, self.vertices) = (nodes, vertices);
        Ok(())
    }
}

/// How far a leaf fails the error test, relative to its level: by its light's deviation from
/// the bilinear prediction (`smooth`; a cone's edge counts here too), and by the step of a
/// shadow boundary crossing it (`shadow`).
#[derive(Debug, Clone, Copy)]
struct Excess {
    smooth: f64,
    shadow: f64,
}

/// What a generation of pending leaves is judged on.
struct Probes {
    /// Test points of pending leaves that are not yet vertices, per polygon, deduplicated and
    /// sorted, and G gathered at each.
    keys: Vec<(u32, VertexKey)>,
    g: Vec<DVec3>,
    /// Every point (corners and test points) of a pending leaf that some light's shadow may
    /// cross, sorted, and at each per shadow light (in `shadow_lights` order) the unshadowed
    /// reflected luminance and the visible fraction.
    shadow_keys: Vec<(u32, VertexKey)>,
    shadows: Vec<Vec<(f64, f64)>>,
}

impl Probes {
    /// G at point `k` of polygon `r` (`p`): its vertex's, or the probe's.
    fn g_at(&self, p: &Poly, r: u32, k: VertexKey) -> DVec3 {
        match p.keys.binary_search(&k) {
            Ok(i) => p.g[i],
            Err(_) => {
                let i = self
                    .keys
                    .binary_search(&(r, k))
                    .expect("every test point was probed");
                self.g[i]
            }
        }
    }

    /// Per shadow light of polygon `r`: the unshadowed reflected luminance and the visible
    /// fraction at point `k`.
    fn shadows_at(&self, r: u32, k: VertexKey) -> &[(f64, f64)] {
        let i = self
            .shadow_keys
            .binary_search(&(r, k))
            .expect("every point of a shadowed leaf was tested");
        &self.shadows[i]
    }
}

impl<'r, 't> Refinement<'r, 't> {
    fn new(
        scene: &'r Scene,
        tr: &'r Transfer<'t>,
        polys: &[Poly],
        totals: &'r [DVec3],
        memory_limit: u64,
    ) -> Self {
        Refinement {
            scene,
            tr,
            totals,
            tolerance: scene.radiosity.tolerance,
            min_size: min_element_size(scene),
            lights: light_spheres(scene),
            peak: peak_reflected(polys),
            shadow_lights: shadow_lights(tr, totals, polys.len()),
            memory: MemoryGuard {
                nodes: polys.iter().map(|p| p.tree.nodes().len() as u64).sum(),
                vertices: polys.iter().map(|p| p.keys.len() as u64).sum(),
                pair_bytes: tr.pair_bytes(),
                limit: memory_limit,
            },
        }
    }

    /// Every leaf that may split, in polygon order (a non-reflecting polygon's radiosity is its
    /// constant emission: none of its leaves).
    fn splittable_leaves(&self, polys: &[Poly]) -> Vec<(u32, u32)> {
        let mut pending = Vec::new();
        for (r, p) in polys.iter().enumerate() {
            if p.rho.max_element() <= 0.0 {
                continue;
            }
            for id in p.tree.leaves() {
                if self.may_split(r, p.tree.node(id).cell) {
                    pending.push((r as u32, id));
                }
            }
        }
        pending
    }

    /// Gathers G at the test points of the `pending` leaves that are not vertices yet, and the
    /// shadows of their lights at every point of the leaves some shadow may cross; raises the
    /// peak to the new values.
    fn probe(&mut self, polys: &[Poly], pending: &[(u32, u32)]) -> Probes {
        let mut keys: Vec<(u32, VertexKey)> = Vec::new();
        let mut shadow_keys: Vec<(u32, VertexKey)> = Vec::new();
        for &(r, id) in pending {
            let p = &polys[r as usize];
            let cell = p.tree.node(id).cell;
            for k in test_points(cell) {
                if p.keys.binary_search(&k).is_err() {
                    keys.push((r, k));
                }
            }
            if !self.shadow_lights[r as usize].is_empty() {
                shadow_keys.extend(leaf_points(cell).map(|k| (r, k)));
            }
        }
        keys.sort_unstable();
        keys.dedup();
        shadow_keys.sort_unstable();
        shadow_keys.dedup();
        let (tr, totals) = (self.tr, self.totals);
        let g: Vec<DVec3> = keys
            .par_iter()
            .map(|&(r, k)| tr.gather(totals, r as usize, k.u(), k.v()))
            .collect();
        let shadows = shadow_keys
            .par_iter()
            .map(|&(r, k)| self.shadows(polys[r as usize].rho, r as usize, k))
            .collect();
        for (&(r, _), g) in keys.iter().zip(&g) {
            self.peak = self.peak.max(lum(polys[r as usize].rho * *g));
        }
        Probes {
            keys,
            g,
            shadow_keys,
            shadows,
        }
    }

    /// Per shadow light of polygon `r` (reflectance `rho`) at point `k`: the unshadowed
    /// reflected luminance and the visible fraction of the light.
    fn shadows(&self, rho: DVec3, r: usize, k: VertexKey) -> Vec<(f64, f64)> {
        self.shadow_lights[r]
            .iter()
            .map(|&s| {
                let (open, vis) = self.tr.shadowed(s, r, k.u(), k.v());
                (lum(rho * self.totals[s] * open), vis)
            })
            .collect()
    }

    /// The `pending` leaves that split (see [`refine`]), in order. A leaf that splits while its
    /// children may not (the depth or size guard) is counted in `guarded`: the error test still
    /// fails there.
    fn leaves_to_split(
        &self,
        polys: &[Poly],
        pending: &[(u32, u32)],
        probes: &Probes,
        guarded: &mut GuardStops,
    ) -> Vec<(u32, u32)> {
        let floor = REFINE_FLOOR * self.peak;
        let judged: Vec<(u32, u32, Excess)> = pending
            .par_iter()
            .map(|&(r, id)| {
                let p = &polys[r as usize];
                (
                    r,
                    id,
                    self.excess(p, r, p.tree.node(id).cell, probes, floor),
                )
            })
            .collect();
        let mut split = Vec::new();
        for (r, id, excess) in judged {
            if excess.smooth.max(excess.shadow) <= self.tolerance {
                continue;
            }
            split.push((r, id));
            let cell = polys[r as usize].tree.node(id).cell;
            let child = Cell {
                level: cell.level + 1,
                x: 2 * cell.x,
                y: 2 * cell.y,
            };
            if !self.may_split(r as usize, child) {
                if excess.smooth > self.tolerance {
                    guarded.record(r, excess.smooth);
                } else {
                    guarded.shadow_leaves += 1;
                }
            }
        }
        split
    }

    /// How far leaf `cell` of polygon `r` (`p`) fails the error test, relative to its level (at
    /// least `floor`): its light's deviation from the bilinear prediction, and the step of a
    /// shadow boundary crossing it. It splits when either passes the tolerance.
    fn excess(&self, p: &Poly, r: u32, cell: Cell, probes: &Probes, floor: f64) -> Excess {
        let corners = cell.corners().map(|k| probes.g_at(p, r, k));
        let tests = test_points(cell).map(|k| probes.g_at(p, r, k));
        let level = corners
            .iter()
            .chain(&tests)
            .map(|g| lum(p.rho * *g))
            .sum::<f64>()
            / 9.0;
        let scale = level.max(floor).max(f64::MIN_POSITIVE);
        let smooth = deviation(p.rho, &corners, &tests) / scale;
        let shadow = if self.shadow_lights[r as usize].is_empty() {
            0.0
        } else {
            shadow_step(probes, r, cell) / scale
        };
        Excess { smooth, shadow }
    }

    /// Splits the leaves `split_now`, gives the polygons that changed their new vertices (G
    /// from the probes) and leaves; returns the children that may split in turn.
    fn split(
        &self,
        polys: &mut [Poly],
        split_now: &[(u32, u32)],
        probes: &Probes,
        patches: &PatchLayout,
    ) -> Vec<(u32, u32)> {
        let mut next = Vec::new();
        let mut touched: Vec<u32> = Vec::new();
        for &(r, id) in split_now {
            let p = &mut polys[r as usize];
            let f = p.tree.split(id);
            for c in f..f + 4 {
                if self.may_split(r as usize, p.tree.node(c).cell) {
                    next.push((r, c));
                }
            }
            touched.push(r);
        }
        touched.dedup();
        for &r in &touched {
            let p = &mut polys[r as usize];
            let keys = p.tree.vertex_keys();
            let g: Vec<DVec3> = keys.iter().map(|&k| probes.g_at(p, r, k)).collect();
            p.keys = keys;
            p.g = g;
            p.rebuild_leaves(self.scene, r as usize, patches);
        }
        next
    }
}

/// The brightest reflected radiosity rho * G (luminance) at any vertex of a reflecting polygon.
fn peak_reflected(polys: &[Poly]) -> f64 {
    polys
        .iter()
        .filter(|p| lum(p.rho) > 0.0)
        .flat_map(|p| p.g.iter().map(|g| lum(p.rho * *g)))
        .fold(0.0, f64::max)
}

/// Per polygon, the lights (spots and emitters) that have shot and whose pairs with it may be
/// occluded, ascending. From the per-receiver index, so this costs the pairs, not lights x
/// polygons.
fn shadow_lights(tr: &Transfer<'_>, totals: &[DVec3], polygons: usize) -> Vec<Vec<usize>> {
    let is_light: Vec<bool> = (0..tr.shooters.len())
        .map(|s| {
            !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }) && totals[s] != DVec3::ZERO
        })
        .collect();
    (0..polygons)
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
        .collect()
}

/// Whether rho * G at the test points `tests` (centre, edge midpoints) differs from the
/// bilinear prediction of the `corners` by more than `threshold` (luminance of the per-channel
/// difference) at any of them.
fn deviation(rho: DVec3, corners: &[DVec3; 4], tests: &[DVec3; 5]) -> f64 {
    let c = corners;
    let predicted = [
        0.25 * (c[0] + c[1] + c[2] + c[3]),
        0.5 * (c[0] + c[1]),
        0.5 * (c[1] + c[2]),
        0.5 * (c[2] + c[3]),
        0.5 * (c[3] + c[0]),
    ];
    tests
        .iter()
        .zip(predicted)
        .map(|(g, pr)| lum((rho * (*g - pr)).abs()))
        .fold(0.0, f64::max)
}

/// The largest step a shadow boundary makes across leaf `cell` of polygon `r`: over its shadow
/// lights, the light's largest unshadowed contribution at the leaf's points times the spread of
/// its visible fraction there (0 where no boundary crosses).
fn shadow_step(probes: &Probes, r: u32, cell: Cell) -> f64 {
    let points: Vec<&[(f64, f64)]> = leaf_points(cell).map(|k| probes.shadows_at(r, k)).collect();
    let lights = points.first().map_or(0, |v| v.len());
    (0..lights)
        .map(|j| {
            let (mut lo, mut hi, mut open) = (f64::INFINITY, f64::NEG_INFINITY, 0f64);
            for q in &points {
                let (a, v) = q[j];
                lo = lo.min(v);
                hi = hi.max(v);
                open = open.max(a);
            }
            if hi > lo {
                open * (hi - lo)
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
}

/// The corners, then the test points, of a cell.
fn leaf_points(cell: Cell) -> impl Iterator<Item = VertexKey> {
    cell.corners().into_iter().chain(test_points(cell))
}

/// Smallest element edge worth splitting: the diagonal of the scene's core (its bounds without
/// backdrops, [`scene::Scene::core_diagonal`]) / 2^max_depth. Depth limits are per polygon,
/// so without this a small polygon (a 1 m floor tile in a 15 m hall) would be refined to
/// elements far smaller than a large one's at the same depth; with it, `max_depth` means "the
/// scene resolved to 1 / 2^max_depth of its size" everywhere. The core, not the whole bounds:
/// a ground plane 1e6 wide beside a room would otherwise forbid every split in the room.
pub fn min_element_size(scene: &Scene) -> f64 {
    scene.core_diagonal() / (1u64 << scene.radiosity.max_depth.min(63)) as f64
}

/// How many times finer than the distance to a light (from its centre, plus its radius) a leaf
/// may be split past the guards ([`Refinement::may_split`]): the light of a small source at
/// distance h varies over about h, and elements of h / 4 hold an emitter 2 cm over a floor to
/// 0.8 % of its peak and 0.9 % of its energy (`a_small_close_emitter_is_resolved_at_the_default_depth`);
/// h / 8 gains 0.4 % there and doubles the generated building's solve (its ceiling panels light
/// the walls beside them).
pub const LIGHT_DEPTH_FACTOR: f64 = 4.0;

/// Every emitter as (centroid, largest distance of a corner from it) and every spot as
/// (position, 0).
fn light_spheres(scene: &Scene) -> Vec<(DVec3, f64)> {
    let mut out: Vec<(DVec3, f64)> = scene.spots.iter().map(|s| (s.position, 0.0)).collect();
    for (i, p) in scene.polygons.iter().enumerate() {
        if scene.material_of(i).is_emitter() {
            out.push(p.bounding_sphere());
        }
    }
    out
}

impl Refinement<'_, '_> {
    /// Whether leaf `cell` of polygon `r` may split: within the guards (`max_depth` and the
    /// smallest element, [`can_split`]), or, up to the quadtree's deepest level, while its
    /// longer edge is more than 1 / [`LIGHT_DEPTH_FACTOR`] of the distance from its centre to
    /// some light plus that light's radius. So the depth under a small or close light comes
    /// from the light's size and distance (an emitter 1/1000 of a floor's width 2 cm above it
    /// is resolved at the default `max_depth`), and the error test still decides each split;
    /// the memory guard bounds it all. A scene with `min_depth = max_depth` (uniform trees)
    /// keeps its depth.
    fn may_split(&self, r: usize, cell: Cell) -> bool {
        if can_split(self.scene, r, cell, self.min_size) {
            return true;
        }
        // `min_depth = max_depth` asks for uniform trees: no leaf passes that depth.
        let uniform = self.scene.radiosity.min_depth >= self.scene.radiosity.max_depth;
        if uniform || cell.level >= base::quadtree::MAX_DEPTH || self.lights.is_empty() {
            return false;
        }
        let (u0, v0, u1, v1) = cell.bounds();
        let (u, v) = (0.5 * (u0 + u1), 0.5 * (v0 + v1));
        let p = &self.scene.polygons[r];
        let (du, dv) = p.tangents(u, v);
        let edge = (du.length() * (u1 - u0)).max(dv.length() * (v1 - v0));
        let centre = p.point(u, v);
        self.lights
            .iter()
            .any(|&(c, radius)| LIGHT_DEPTH_FACTOR * edge > (c - centre).length() + radius)
    }
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
