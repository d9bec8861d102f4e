//! Adaptive subdivision of the quadtrees against the true radiosity (the solve's step 3 and
//! 5, see the parent module): which leaves split, the depth and size limits, and the memory
//! guard of each refinement pass.

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use rayon::prelude::*;

mod criteria;
mod reach;

use super::peaks::{light_peaks, PEAK_SHARE};
use super::poly::{at_cell, cell_order, PatchLayout, Poly};
use super::{lum, memory_error, spread, state_bytes};
use crate::transfer::seen::SeenCache;
use crate::transfer::{sub_area, PairClass, ShooterKind, Transfer};
use crate::GuardStops;
use base::error::{human_bytes, Result};
use base::quadtree::{Cell, VertexKey, MAX_DEPTH};
use criteria::{deviation, extremum_between, shadow_step};
pub(crate) use reach::LIGHT_DEPTH_FACTOR;
#[cfg(doc)]
use reach::SPOT_EDGE_FACTOR;
use reach::{light_reaches, step_reaches, LightReach, StepReach, STEP_LEVELS};
use scene::Scene;

/// Floor of the refinement criterion, as a fraction of the brightest reflected radiosity
/// (luminance) sampled so far: an element's variation is judged relative to its own level, but
/// never to a level below this fraction of the peak, so that dark regions (where any noise is a
/// large relative change) do not refine to the depth limit.
pub(crate) const REFINE_FLOOR: f64 = 0.01;

/// Most quadtree nodes one polygon may hold below its guard depth ([`depth_bound`]): splits
/// past the guards (near a small or close light, at a spot's cone edge, around a light's peak,
/// and the graded neighbours of those) stop there. A point-like feature needs a few dozen nodes
/// per level (a small emitter 2 cm over a floor dives to level 16 in about 900); a cone edge
/// across a polygon needs about 2^level per level, and is stopped at the depth this allows.
pub const DIVE_NODES: u64 = 16_384;

/// Share of its patch's power a leaf's light may vary by (its corners' spread times its area)
/// before the patch's integral needs G at the leaf's centre ([`Refinement::unjudged_ramps`]).
const RAMP_SHARE: f64 = 1e-3;

/// Adaptive subdivision against the true radiosity; returns the number of splits.
///
/// A leaf splits (below `max_depth` and above [`min_element_size`]) when either
/// - **variation**: at its centre or an edge midpoint the reflected radiosity rho * G differs
///   from the bilinear prediction of its corners by more than `tolerance * level` (luminance of
///   the per-channel difference), `level` being the larger of the leaf's own level (the mean
///   luminance of rho * G over its corners and test points) and [`REFINE_FLOOR`] times the
///   peak; nothing in this test depends on the polygon's area or shape, so thin and small
///   polygons refine like large ones; or
/// - **extremum**: along one of its edges or its two centre lines, the parabola through the
///   line's three points peaks (or dips) beyond the line's ends by more than [`PEAK_SHARE`]
///   times `tolerance * level` ([`extremum_between`]): the reconstruction draws such a leaf no
///   higher than its corners, so a maximum between them would be clipped; or
/// - **visibility**: for a light (spot or emitter) with occluders between it and the polygon,
///   the visible fraction of the light differs across the leaf's corners and test points (a
///   shadow boundary crosses it) and the light's unshadowed contribution times that difference
///   exceeds the same `tolerance * level`: the leaf is split toward the boundary, down to the
///   depth limit, even where the bilinear prediction happens to agree at the test points, and
///   where the edge of an area light's penumbra crosses it (lit, penumbra and umbra meet among
///   its points) [`SHADOW_EDGE_LEVELS`] past it; or
/// - **peak**: the leaf holds (on its closed cell, not at a corner) the point where a light's
///   unoccluded contribution to the polygon peaks (`peaks`), and the radiosity there stands
///   above the largest at the leaf's corners by more than [`PEAK_SHARE`] times
///   `tolerance * level`. Such a leaf splits past the guards, down to the quadtree's deepest
///   level: only the few leaves around each peak do, and the peak is otherwise lost.
///
/// Past the guards a leaf splits only near a light ([`LightReach`]), beside the outline of a
/// polygon lying close over its polygon ([`StepReach`]) or on a penumbra's edge (above), where
/// the light varies over less than the guards' smallest element; there a polygon holds at
/// most [`DIVE_NODES`] nodes, so that `max_depth` and that bound together limit a solve's
/// growth (a fuzzed two-polygon scene at `max_depth = 3` grew 927,000 elements and 1.3 GB; a
/// floor under 64 tiny emitters 1 mm above it dives 26,000 nodes deep without the bound);
/// leaves stopped by it are reported with the guards' stops.
///
/// The leaves are judged a generation at a time: the splittable leaves, then the children of
/// those that split, until none splits. Every G the pass computes is the oracle's gather from
/// `totals` (taking the geometry `seen` keeps of the points gathered before, and keeping the
/// new points'), and the new vertices keep it. Last, the leaves a limit stopped while their
/// light still falls steeply across them gather G at their centre, for the patches'
/// integrals ([`Refinement::unjudged_ramps`]). The pass holds its state under `memory_limit`,
/// `seen` giving its room back if the state needs it.
pub(super) fn refine(
    scene: &Scene,
    tr: &Transfer<'_>,
    polys: &mut [Poly],
    totals: &[DVec3],
    patches: &PatchLayout,
    (memory_limit, seen): (u64, &mut SeenCache),
    guarded: &mut GuardStops,
) -> Result<usize> {
    let tolerance = scene.radiosity.tolerance;
    if tolerance <= 0.0 || !tolerance.is_finite() {
        return Ok(0);
    }
    let mut pass = Refinement::new(scene, tr, polys, totals, memory_limit, seen);

    let mut pending = pass.splittable_leaves(polys);
    let mut splits = 0;
    for p in polys.iter_mut() {
        p.tests.clear();
        p.centres.clear();
    }
    while !pending.is_empty() {
        let probes = pass.probe(polys, &pending);
        let (split_now, edges) = pass.leaves_to_split(polys, &pending, &probes, guarded);
        keep_tests(polys, &pending, &split_now, &probes);
        pass.memory
            .admit(scene, split_now.len() as u64, &mut *pass.seen)?;
        splits += split_now.len();
        pending = pass.split(polys, (&split_now, &edges), &probes, patches);
    }
    for p in polys.iter_mut() {
        p.tests.sort_unstable_by_key(|(c, _)| cell_order(*c));
    }
    let ramps = pass.unjudged_ramps(polys, patches);
    let centres = pass.gather_centres(polys, &ramps);
    for (&(r, id), g) in ramps.iter().zip(centres) {
        let p = &mut polys[r as usize];
        let cell = p.tree.node(id).cell;
        p.centres.push((cell, g));
    }
    for p in polys.iter_mut() {
        p.centres.sort_unstable_by_key(|(c, _)| cell_order(*c));
    }
    Ok(splits)
}

/// A leaf of a polygon's tree: the polygon and the node.
type LeafId = (u32, u32);

/// Keeps G at the test points of the `pending` leaves that do not split (`split_now` is a
/// subsequence of `pending`): the patches' integrals use them (Simpson's rule).
fn keep_tests(polys: &mut [Poly], pending: &[LeafId], split_now: &[LeafId], probes: &Probes) {
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
    /// The lights (emitters and spots) as spheres with the share of their distance a leaf may
    /// be refined to: where a light is small and close, its light varies over less than the
    /// guards' smallest element ([`Refinement::may_split`]).
    lights: Vec<LightReach>,
    /// The outlines of polygons lying close over a receiver (`scene::contact`), by receiver:
    /// the light beside such an outline changes over the gap, finer than the guards' smallest
    /// element ([`StepReach`]).
    steps: Vec<Vec<StepReach>>,
    /// The brightest reflected luminance sampled so far (the criterion's floor follows it).
    peak: f64,
    /// Per polygon: the lights that have shot and whose pairs with it may be occluded,
    /// ascending (their shadows drive the visibility test).
    shadow_lights: Vec<Vec<usize>>,
    /// Per polygon: the lattice points where a light's contribution peaks (sorted).
    peaks: Vec<Vec<VertexKey>>,
    /// Leaves of the next generation that split whatever their test says, to keep the tree
    /// graded around a split the guards would have refused ([`Refinement::grade`]).
    forced: HashSet<LeafId>,
    /// Per polygon: its guard depth ([`depth_bound`]) and the nodes it holds below it, which
    /// [`DIVE_NODES`] bounds.
    dives: Vec<(u32, u64)>,
    memory: MemoryGuard,
    /// What the gathers saw of the geometry at each point (the test points' gathers keep
    /// theirs here for when the points are gathered again).
    seen: &'r mut SeenCache,
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
    /// allocate; the gathers' cache (`seen`) gives its room back first if they need it.
    fn admit(&mut self, scene: &Scene, splits: u64, seen: &mut SeenCache) -> Result<()> {
        let (nodes, vertices) = (self.nodes + 4 * splits, self.vertices + 5 * splits);
        let need = state_bytes(nodes, vertices).saturating_add(self.pair_bytes);
        seen.yield_to(need, self.limit);
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
/// the bilinear prediction (`smooth`; a cone's edge counts here too), by an extremum between
/// its samples (`between`, [`extremum_between`]), by the step of a shadow boundary crossing it
/// (`shadow`), and by how far a light's peak inside it stands above its corners (`peak`).
#[derive(Debug, Clone, Copy)]
struct Excess {
    smooth: f64,
    between: f64,
    shadow: f64,
    /// The part of `shadow` from area emitters whose shadow's edge crosses the leaf (see
    /// [`shadow_step`]): such a leaf may split past the guards ([`SHADOW_EDGE_LEVELS`]).
    edge: f64,
    peak: f64,
    /// The level the shares above are of (luminance of rho G).
    scale: f64,
}

impl Excess {
    /// Whether the leaf fails the tests the guards bound (variation, extremum, shadow).
    fn fails(&self, tolerance: f64) -> bool {
        self.smooth.max(self.shadow) > tolerance || self.between > PEAK_SHARE * tolerance
    }
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
        seen: &'r mut SeenCache,
    ) -> Self {
        let tolerance = scene.radiosity.tolerance;
        let peak = peak_reflected(polys);
        // The smallest excess the peak test acts on, at the floor's level.
        let threshold = PEAK_SHARE * tolerance * REFINE_FLOOR * peak;
        Refinement {
            scene,
            tr,
            totals,
            tolerance,
            min_size: min_element_size(scene),
            lights: light_reaches(scene),
            steps: step_reaches(scene),
            peak,
            shadow_lights: shadow_lights(tr, totals, polys.len()),
            peaks: light_peaks(scene, tr, totals, polys, threshold),
            forced: HashSet::new(),
            dives: dives(scene, polys, min_element_size(scene)),
            memory: MemoryGuard {
                nodes: polys.iter().map(|p| p.tree.nodes().len() as u64).sum(),
                vertices: polys.iter().map(|p| p.keys.len() as u64).sum(),
                pair_bytes: tr.pair_bytes(),
                limit: memory_limit,
            },
            seen,
        }
    }

    /// Every leaf that may split, in polygon order (a non-reflecting polygon's radiosity is its
    /// constant emission: none of its leaves).
    fn splittable_leaves(&self, polys: &[Poly]) -> Vec<LeafId> {
        let mut pending = Vec::new();
        for (r, p) in polys.iter().enumerate() {
            if p.rho.max_element() <= 0.0 {
                continue;
            }
            for id in p.tree.leaves() {
                let cell = p.tree.node(id).cell;
                if self.may_split(r, cell) || self.holds_peak(r, cell) {
                    pending.push((r as u32, id));
                }
            }
        }
        pending
    }

    /// Gathers G at the test points of the `pending` leaves that are not vertices yet, and the
    /// shadows of their lights at every point of the leaves some shadow may cross; raises the
    /// peak to the new values.
    fn probe(&mut self, polys: &[Poly], pending: &[LeafId]) -> Probes {
        let mut keys: Vec<(u32, VertexKey)> = Vec::new();
        let mut shadow_keys: Vec<(u32, VertexKey)> = Vec::new();
        for &(r, id) in pending {
            let p = &polys[r as usize];
            let cell = p.tree.node(id).cell;
            for k in test_points(cell)
                .into_iter()
                .chain(self.peaks_in(r as usize, cell))
            {
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
        let g = self.tr.gather_points(self.totals, &keys, self.seen);
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

    /// The leaves no generation judged (a depth, size or dive limit stopped them) across whose
    /// corners the reflected light varies by more than the tolerance of its level and by more
    /// than [`RAMP_SHARE`] of its patch's power: the patches' integrals need G at their
    /// centre (the centre rule, `poly::leaf_integral`). The trapezoid rule on a leaf's corners
    /// misses the curvature of a ramp: beside a panel 2 cm under a ceiling, facing it, the
    /// ceiling's light falls to 0.29 of its value at the outline within one gap, and the
    /// trapezoid rule on the gap-wide leaves there gave the ceiling around the panel 9 % more
    /// power than it has, and the room lit by it as much more light.
    fn unjudged_ramps(&self, polys: &[Poly], patches: &PatchLayout) -> Vec<LeafId> {
        let floor = REFINE_FLOOR * self.peak;
        let mut out = Vec::new();
        for (r, p) in polys.iter().enumerate() {
            if !p.reflects() {
                continue;
            }
            let poly = &self.scene.polygons[r];
            // Per leaf: its luminances of rho G at the corners, area and patch.
            let leaves: Vec<(u32, Cell, [f64; 4], f64, u32)> = p
                .tree
                .leaves()
                .into_iter()
                .map(|id| {
                    let cell = p.tree.node(id).cell;
                    let lums = cell.corners().map(|k| {
                        let i = p
                            .keys
                            .binary_search(&k)
                            .expect("a leaf's corners are vertices");
                        lum(p.rho * p.g[i])
                    });
                    (
                        id,
                        cell,
                        lums,
                        sub_area(poly, cell),
                        patches.patch_at(r, cell),
                    )
                })
                .collect();
            let mut power: HashMap<u32, f64> = HashMap::new();
            for &(_, _, lums, area, patch) in &leaves {
                *power.entry(patch).or_default() += 0.25 * area * lums.iter().sum::<f64>();
            }
            for (id, cell, lums, area, patch) in leaves {
                if at_cell(&p.tests, cell).is_some() || cell.level >= MAX_DEPTH {
                    continue;
                }
                let d = spread(lums);
                let scale = (0.25 * lums.iter().sum::<f64>()).max(floor);
                if d > self.tolerance * scale && d * area > RAMP_SHARE * power[&patch] {
                    out.push((r as u32, id));
                }
            }
        }
        out
    }

    /// G gathered at the centres of `leaves` (in order; a leaf's centre is never a vertex).
    fn gather_centres(&mut self, polys: &[Poly], leaves: &[LeafId]) -> Vec<DVec3> {
        let keys: Vec<(u32, VertexKey)> = leaves
            .iter()
            .map(|&(r, id)| (r, polys[r as usize].tree.node(id).cell.centre()))
            .collect();
        self.tr.gather_points(self.totals, &keys, self.seen)
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

    /// The `pending` leaves that split (see [`refine`]), in order, and those of them that a
    /// shadow's edge crosses (their children may split past the guards, [`Refinement::edge_dive`]).
    /// A leaf that splits while its children may not (the depth or size guard) is counted in
    /// `guarded`: the error test still fails there.
    fn leaves_to_split(
        &self,
        polys: &[Poly],
        pending: &[LeafId],
        probes: &Probes,
        guarded: &mut GuardStops,
    ) -> (Vec<LeafId>, Vec<LeafId>) {
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
        let (mut split, mut edges) = (Vec::new(), Vec::new());
        // Nodes below each polygon's guard depth with this generation's splits counted as
        // they are admitted, so that one generation cannot overrun [`DIVE_NODES`].
        let mut below: Vec<u64> = self.dives.iter().map(|d| d.1).collect();
        for (r, id, excess) in judged {
            let cell = polys[r as usize].tree.node(id).cell;
            let past = cell.level >= self.dives[r as usize].0;
            let spent = past && below[r as usize] >= DIVE_NODES;
            let mut admit = |split: &mut Vec<LeafId>| {
                split.push((r, id));
                if past {
                    below[r as usize] += 4;
                }
            };
            if self.forced.contains(&(r, id)) {
                admit(&mut split);
                continue;
            }
            let edge = excess.edge > self.tolerance;
            let may = |cell| self.may_split(r as usize, cell) || (edge && self.edge_dive(r, cell));
            let fails = excess.fails(self.tolerance) && !spent && may(cell);
            if !fails {
                if spent && excess.fails(self.tolerance) {
                    self.record_stop(guarded, r, cell, &excess);
                } else if !spent && excess.peak > PEAK_SHARE * self.tolerance {
                    admit(&mut split);
                }
                continue;
            }
            admit(&mut split);
            if edge {
                edges.push((r, id));
            }
            let child = Cell {
                level: cell.level + 1,
                x: 2 * cell.x,
                y: 2 * cell.y,
            };
            if !may(child) {
                if excess.smooth > self.tolerance || excess.between > PEAK_SHARE * self.tolerance {
                    self.record_stop(guarded, r, cell, &excess);
                } else {
                    guarded.shadow_leaves += 1;
                }
            }
        }
        edges.sort_unstable();
        (split, edges)
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
        let lums = |g: &[DVec3]| g.iter().map(|g| lum(p.rho * *g)).collect::<Vec<_>>();
        let between = extremum_between(&lums(&corners), &lums(&tests)) / scale;
        let smooth = deviation(p.rho, &corners, &tests) / scale;
        let (shadow, edge) = if self.shadow_lights[r as usize].is_empty() {
            (0.0, 0.0)
        } else {
            let lights = &self.shadow_lights[r as usize];
            let area = |j: usize| {
                matches!(
                    self.tr.shooters[lights[j]].kind,
                    ShooterKind::Emitter { .. }
                )
            };
            let (step, edge) = shadow_step(probes, r, cell, area);
            (step / scale, edge / scale)
        };
        // The corners are what stays sampled if the leaf does not split.
        let highest = corners
            .iter()
            .map(|g| lum(p.rho * *g))
            .fold(f64::NEG_INFINITY, f64::max);
        let peak = self
            .peaks_in(r as usize, cell)
            .map(|k| (lum(p.rho * probes.g_at(p, r, k)) - highest) / scale)
            .fold(0.0, f64::max);
        Excess {
            smooth,
            between,
            shadow,
            edge,
            peak,
            scale,
        }
    }

    /// Counts leaf `cell` of polygon `r`, split to a guard with `excess` still failing, in
    /// `guarded`: the light it may misplace is [`KEPT_SHARE`] of its excess times its level
    /// times its area,
    /// unless a spot's cone edge crosses it (a step at any depth, which the reconstruction
    /// draws exactly from the spot's own light: counted apart, like a shadow boundary).
    fn record_stop(&self, guarded: &mut GuardStops, r: u32, cell: Cell, excess: &Excess) {
        let poly = &self.scene.polygons[r as usize];
        let e = excess.smooth.max(excess.between);
        let corners = cell.corners().map(|k| poly.point(k.u(), k.v()));
        if self.lights.iter().any(|l| l.edge_crosses(&corners)) {
            guarded.record_edge();
        } else {
            guarded.record(r, e, KEPT_SHARE * e * excess.scale * sub_area(poly, cell));
        }
    }

    /// The light peaks of polygon `r` on leaf `cell`'s closed cell other than its corners.
    fn peaks_in(&self, r: usize, cell: Cell) -> impl Iterator<Item = VertexKey> + '_ {
        let o = cell.origin();
        let s = cell.size();
        self.peaks[r].iter().copied().filter(move |k| {
            let inside = (o.i..=o.i + s).contains(&k.i) && (o.j..=o.j + s).contains(&k.j);
            let corner = (k.i == o.i || k.i == o.i + s) && (k.j == o.j || k.j == o.j + s);
            inside && !corner
        })
    }

    /// Whether leaf `cell` of polygon `r` holds a light's peak and may still split for it (the
    /// quadtree's deepest level is the only limit).
    fn holds_peak(&self, r: usize, cell: Cell) -> bool {
        !self.uniform() && cell.level < MAX_DEPTH && self.peaks_in(r, cell).next().is_some()
    }

    /// Whether the scene asks for uniform trees (`min_depth = max_depth`): then no leaf passes
    /// that depth, for a light's reach or its peak.
    fn uniform(&self) -> bool {
        self.scene.radiosity.min_depth >= self.scene.radiosity.max_depth
    }

    /// Whether leaf `cell` of polygon `r`, which a shadow's edge crosses, may split past the
    /// guards: up to [`SHADOW_EDGE_LEVELS`] below its guard depth, within the polygon's
    /// [`DIVE_NODES`], unless the scene asks for uniform trees.
    fn edge_dive(&self, r: u32, cell: Cell) -> bool {
        let r = r as usize;
        !self.uniform()
            && !self.shadow_lights[r].is_empty()
            && cell.level < base::quadtree::MAX_DEPTH
            && cell.level < self.dives[r].0 + SHADOW_EDGE_LEVELS
            && !self.dive_spent(r, cell)
    }

    /// Whether splitting leaf `cell` of polygon `r` would pass its guard depth with the
    /// polygon's [`DIVE_NODES`] already spent.
    fn dive_spent(&self, r: usize, cell: Cell) -> bool {
        let (bound, below) = self.dives[r];
        cell.level >= bound && below >= DIVE_NODES
    }

    /// Splits the leaves `split_now`, gives the polygons that changed their new vertices (G
    /// from the probes) and leaves; returns the children that may split in turn (those of the
    /// leaves in `edges`, sorted, also past the guards: [`Refinement::edge_dive`]).
    fn split(
        &mut self,
        polys: &mut [Poly],
        (split_now, edges): (&[LeafId], &[LeafId]),
        probes: &Probes,
        patches: &PatchLayout,
    ) -> Vec<LeafId> {
        let mut next = Vec::new();
        let mut touched: Vec<u32> = Vec::new();
        self.forced.clear();
        for &(r, id) in split_now {
            let p = &mut polys[r as usize];
            let cell = p.tree.node(id).cell;
            let f = p.tree.split(id);
            let dive = &mut self.dives[r as usize];
            if cell.level >= dive.0 {
                dive.1 += 4;
            }
            let edge = edges.binary_search(&(r, id)).is_ok();
            for c in f..f + 4 {
                let cell = p.tree.node(c).cell;
                if self.may_split(r as usize, cell)
                    || self.holds_peak(r as usize, cell)
                    || (edge && self.edge_dive(r, cell))
                {
                    next.push((r, c));
                }
            }
            if !can_split(self.scene, r as usize, cell, self.min_size) {
                for n in coarse_neighbours(&polys[r as usize].tree, cell) {
                    if self.forced.insert((r, n)) {
                        next.push((r, n));
                    }
                }
            }
            touched.push(r);
        }
        // A neighbour forced early in the loop may have split later in it, and a child made in
        // it may also be forced as a later split's neighbour.
        next.retain(|&(r, id)| polys[r as usize].tree.node(id).is_leaf());
        next.sort_unstable();
        next.dedup();
        self.forced
            .retain(|&(r, id)| polys[r as usize].tree.node(id).is_leaf());
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

/// The leaves across the four edges of `cell` (just split) that are more than one level
/// coarser than its children. A split the guards would have refused (around a light's peak or
/// close to a light) is graded: such neighbours split too, in the next generation, whatever
/// their test says, and their own neighbours after them if they in turn are past the guards.
/// Without it a guard-stopped leaf of a quarter of a 1 m floor tile sat beside a peak refined
/// to 1/64 of it; the T-vertices on its edge carried light far off its own patch, and the
/// reconstruction's refinement of it overshot its corners by 1.5 times the tile's range.
fn coarse_neighbours(tree: &base::quadtree::Quadtree, cell: Cell) -> Vec<u32> {
    let (u0, v0, u1, v1) = cell.bounds();
    let (um, vm) = (0.5 * (u0 + u1), 0.5 * (v0 + v1));
    // A quarter of a lattice step outside the lower edges (find_leaf floors); the upper edges
    // themselves belong to the cell above.
    let eps = 0.25 / base::quadtree::LATTICE as f64;
    let mut out: Vec<u32> = [
        (u0 > 0.0).then_some((u0 - eps, vm)),
        (u1 < 1.0).then_some((u1, vm)),
        (v0 > 0.0).then_some((um, v0 - eps)),
        (v1 < 1.0).then_some((um, v1)),
    ]
    .into_iter()
    .flatten()
    .map(|(u, v)| tree.find_leaf(u, v))
    .filter(|&n| tree.node(n).cell.level < cell.level)
    .collect();
    out.sort_unstable();
    out.dedup();
    out
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

/// How many levels past its guard depth a leaf that a shadow's edge crosses may split (while
/// the edge's step there still fails the error test, `shadow_step`). The C1 patches round a
/// penumbra's edge off over about one element on each side (the slope a vertex at the edge
/// takes is the mean of the two sides'), which at the guards' elements is a large part of a
/// narrow penumbra. A box's 7 cm penumbra under a 12 x 8 cm light, on 2.3 cm elements: the
/// direct method's largest error 4.2 % of the unshadowed light at the guards, 2.8 % one level
/// past them, 0.9 % two levels past, 0.46 % three
/// (`a_narrow_penumbras_edges_are_followed_past_the_guards`).
/// Two: in a furnished room lit by a 20 cm panel, the direct method's error within 2 pixels of
/// the shadow boundaries fell from 1.9 times its error elsewhere to 0.8 times, for 1.3 times
/// the solve and 1.5 times the solution's bytes (three levels: 1.75 and 2.1 times;
/// docs/accuracy.md).
pub const SHADOW_EDGE_LEVELS: u32 = 2;

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

/// The share of a stopped leaf's excess its children keep, for the light it may misplace
/// ([`GuardStops::error_power`]): the bilinear prediction's error of smooth light falls four
/// times per split. Checked on the gallery: its stopped leaves at `max_depth = 6` estimate
/// 0.59 % of its reflected light misplaced; solved at 8, its faces' light moves by 0.47 % of
/// it in all (each face's change times its area, summed).
const KEPT_SHARE: f64 = 0.25;

impl Refinement<'_, '_> {
    /// Whether leaf `cell` of polygon `r` may split: within the guards (`max_depth` and the
    /// smallest element, [`can_split`]), or, up to the quadtree's deepest level, while its
    /// longer edge is more than 1 / [`LIGHT_DEPTH_FACTOR`] of the distance from its centre to
    /// some light plus that light's radius, or a spot's cone edge crosses it and it is more
    /// than 1 / [`SPOT_EDGE_FACTOR`] of the footprint's radius ([`LightReach::reaches`]), or it
    /// lies beside the outline of a polygon close over it and is wider than its distance to the
    /// outline plus the gap ([`StepReach::reaches`]). So the depth under a small or close light
    /// comes from the light's size and distance (an emitter 1/1000 of a floor's width 2 cm
    /// above it is resolved at the default `max_depth`), and the error test still decides each
    /// split; the memory guard bounds it all. A scene with `min_depth = max_depth` (uniform
    /// trees) keeps its depth.
    fn may_split(&self, r: usize, cell: Cell) -> bool {
        if can_split(self.scene, r, cell, self.min_size) {
            return true;
        }
        if self.uniform()
            || cell.level >= base::quadtree::MAX_DEPTH
            || (self.lights.is_empty() && self.steps[r].is_empty())
            || self.dive_spent(r, cell)
        {
            return false;
        }
        let (u0, v0, u1, v1) = cell.bounds();
        let (u, v) = (0.5 * (u0 + u1), 0.5 * (v0 + v1));
        let p = &self.scene.polygons[r];
        let (du, dv) = p.tangents(u, v);
        let edge = (du.length() * (u1 - u0)).max(dv.length() * (v1 - v0));
        let centre = p.point(u, v);
        let corners = [(u0, v0), (u1, v0), (u1, v1), (u0, v1)].map(|(a, b)| p.point(a, b));
        self.lights
            .iter()
            .any(|l| l.reaches(edge, centre, &corners))
            || (cell.level < self.dives[r].0 + STEP_LEVELS
                && self.steps[r].iter().any(|s| s.reaches(edge, centre)))
    }
}

/// Per polygon: its guard depth ([`depth_bound`]) and how many of its nodes lie below it.
fn dives(scene: &Scene, polys: &[Poly], min_size: f64) -> Vec<(u32, u64)> {
    polys
        .iter()
        .enumerate()
        .map(|(r, p)| {
            let bound = depth_bound(scene, r, min_size);
            let below = p.tree.nodes().iter().filter(|n| n.cell.level > bound);
            (bound, below.count() as u64)
        })
        .collect()
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
pub(super) fn test_points(cell: Cell) -> [VertexKey; 5] {
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
