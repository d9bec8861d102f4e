//! Adjacency: which polygon sides meet which, and how.
//!
//! Real models make one flat surface of many polygons (a floor of tiles, a wall around a door, any
//! OBJ from a modelling tool), so the radiosity of a surface crosses polygon borders everywhere.
//! A reconstruction that is C1 inside each polygon but built from each polygon's samples alone
//! has a slope kink at every such border: the Gouraud-sized artefact the RRPs exist to remove.
//! This module finds the borders; the reconstruction stage uses them to make neighbours agree.
//!
//! A **side** is one of a polygon's four parametric edges ([`Side`]): side 0 is v = 0 (c0 -> c1),
//! 1 is u = 1 (c1 -> c2), 2 is v = 1 (c3 -> c2), 3 is u = 0 (c0 -> c3); the parameter along a side
//! ([`side_uv`]) runs from the first corner named to the second. A triangle's side 2 has length 0
//! and is never shared. Two sides are **shared** ([`SharedEdge`]) when they lie on one line within
//! [`EDGE_TOL`] of the longer one's length and overlap in a segment longer than that: the whole of
//! both (a matched edge), or part of one (a T-junction: a long side meeting several short ones).
//! Sides that come within [`NEAR_EDGE`] of that but no closer are **near misses** ([`NearMiss`]):
//! a crack or a misplaced vertex the author may want to know about.
//!
//! How the polygons meet ([`Junction`]): in one plane on opposite sides of the edge (coplanar
//! neighbours: radiosity continues across unless the materials differ), at an angle (a crease:
//! the two sides see different hemispheres and the light may jump), back to back (a thin wall's
//! two faces), or folded onto each other (overlapping; the loader's coincidence check names
//! those).
//!
//! Invariants: edges are listed with `a.polygon < b.polygon`, sorted by (a, b); a pair of sides
//! appears at most once; the result depends only on the polygons (candidates from a BVH box query
//! are sorted before use), so it is the same for any thread count.

use glam::DVec3;

use crate::bvh::{Aabb, Bvh};
use crate::coincident::diameter;
use crate::{Polygon, Shape};

/// Sides whose endpoints lie within this fraction of the longer side's length of each other's
/// line are shared. A millionth of a metre-long edge is far above f64 rounding of any modelled
/// coordinate and far below any gap a viewer could see.
pub const EDGE_TOL: f64 = 1e-6;

/// Collinear sides further apart than [`EDGE_TOL`] but within this fraction of their length are
/// reported as near misses: a crack of a thousandth of a wall.
pub const NEAR_EDGE: f64 = 1e-3;

/// Normals within this angle (degrees) are parallel: coplanar neighbours or back to back.
pub const COPLANAR_DEGREES: f64 = 0.5;

/// One parametric edge of a polygon.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Side {
    /// Index of the polygon in the scene.
    pub polygon: u32,
    /// 0: v = 0, 1: u = 1, 2: v = 1, 3: u = 0.
    pub side: u8,
}

/// The (u, v) of parameter `s` in [0, 1] along `side` (see the module docs for the directions).
pub fn side_uv(side: u8, s: f64) -> (f64, f64) {
    match side {
        0 => (s, 0.0),
        1 => (1.0, s),
        2 => (s, 1.0),
        _ => (0.0, s),
    }
}

/// The 3D endpoints (parameter 0, parameter 1) of `side` of `p`.
pub fn side_endpoints(p: &Polygon, side: u8) -> (DVec3, DVec3) {
    let [c0, c1, c2, c3] = p.corners;
    match side {
        0 => (c0, c1),
        1 => (c1, c2),
        2 => (c3, c2),
        _ => (c0, c3),
    }
}

/// How two polygons meet along a shared edge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Junction {
    /// One plane, the polygons on opposite sides of the edge.
    Coplanar,
    /// An angle between the normals, in degrees (in (COPLANAR_DEGREES, 180 - COPLANAR_DEGREES)).
    Crease {
        /// Angle between the two normals.
        degrees: f64,
    },
    /// Opposite normals, the polygons on opposite sides (a thin wall's two faces seen edge-on
    /// meet this way only when folded flat) or on the same side.
    BackToBack,
    /// One plane, both polygons on the same side of the edge: they overlap.
    Overlap,
}

/// Two sides that share a segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SharedEdge {
    /// The side of the polygon with the smaller index.
    pub a: Side,
    /// The other side.
    pub b: Side,
    /// The shared segment as parameters along `a`, increasing.
    pub a_range: [f64; 2],
    /// The same segment's endpoints as parameters along `b`: `b_range[k]` is the point at
    /// `a_range[k]` (decreasing when the sides run in opposite directions).
    pub b_range: [f64; 2],
    /// How the polygons meet.
    pub junction: Junction,
    /// Largest distance between the two sides' lines at the segment's ends, relative to the
    /// longer side's length (0 for exactly matching vertices).
    pub gap: f64,
}

impl SharedEdge {
    /// Whether the segment is the whole of both sides (no T-junction).
    pub fn is_full(&self) -> bool {
        let whole = |r: [f64; 2]| r[0].min(r[1]) == 0.0 && r[0].max(r[1]) == 1.0;
        whole(self.a_range) && whole(self.b_range)
    }

    /// Whether the sides run in opposite directions along the segment.
    pub fn reversed(&self) -> bool {
        self.b_range[1] < self.b_range[0]
    }

    /// The lattice indices (`base::quadtree::LATTICE` steps along each side) of the shared
    /// segment's ends on `a` and on `b`, if the two lattices line up there: both ends are
    /// lattice points of both sides and one side's step is a power of two times the other's,
    /// so every lattice point of the coarser side along the segment is one of the finer side.
    /// Only such edges can be joined point for point by the reconstruction.
    pub fn lattice_link(&self) -> Option<([i64; 2], [i64; 2])> {
        let ka = [
            lattice_index(self.a_range[0])?,
            lattice_index(self.a_range[1])?,
        ];
        let kb = [
            lattice_index(self.b_range[0])?,
            lattice_index(self.b_range[1])?,
        ];
        let (la, lb) = ((ka[1] - ka[0]).abs(), (kb[1] - kb[0]).abs());
        if la == 0 || lb == 0 {
            return None;
        }
        let ratio_ok = |x: i64, y: i64| x % y == 0 && (x / y).count_ones() == 1;
        (ratio_ok(la, lb) || ratio_ok(lb, la)).then_some((ka, kb))
    }

    /// The parameter along `b` of the point at parameter `s` along `a` (affine in s).
    pub fn b_of_a(&self, s: f64) -> f64 {
        let [a0, a1] = self.a_range;
        let [b0, b1] = self.b_range;
        b0 + (s - a0) * (b1 - b0) / (a1 - a0)
    }
}

/// The lattice index of parameter `x` in [0, 1], if it is one (within rounding).
fn lattice_index(x: f64) -> Option<i64> {
    let lattice = base::quadtree::LATTICE as f64;
    let y = x * lattice;
    let r = y.round();
    ((y - r).abs() <= 1e-6 && (0.0..=lattice).contains(&r)).then_some(r as i64)
}

/// Two collinear sides further apart than [`EDGE_TOL`] but within [`NEAR_EDGE`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearMiss {
    /// The side of the polygon with the smaller index.
    pub a: Side,
    /// The other side.
    pub b: Side,
    /// Distance between the sides relative to the longer one's length.
    pub gap: f64,
}

/// Every shared edge and near miss of a scene's polygons.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Adjacency {
    /// Shared edges, sorted by (a, b).
    pub edges: Vec<SharedEdge>,
    /// Near misses, sorted by (a, b).
    pub near_misses: Vec<NearMiss>,
}

/// Counts of an [`Adjacency`] for reports.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AdjacencySummary {
    /// Shared edges in all.
    pub shared: usize,
    /// Coplanar neighbours.
    pub coplanar: usize,
    /// Coplanar neighbours with the same material: radiosity continues across these.
    pub continuous: usize,
    /// Creases.
    pub creases: usize,
    /// Back-to-back or overlapping pairs.
    pub folded: usize,
    /// Shared edges that are part of a longer side (T-junctions).
    pub partial: usize,
    /// Near misses.
    pub near_misses: usize,
    /// Largest gap of a shared edge, relative to its length.
    pub largest_gap: f64,
}

impl Adjacency {
    /// Finds the shared edges and near misses of `polygons`.
    ///
    /// Each polygon's pairs with the later polygons near it are found in parallel (in chunks of
    /// consecutive polygons) and joined in polygon order, so the result is the same for any thread count.
    pub fn of(polygons: &[Polygon]) -> Adjacency {
        use rayon::prelude::*;
        let bvh = Bvh::build(polygons);
        const CHUNK: usize = 1024;
        let chunks = polygons.len().div_ceil(CHUNK);
        let parts: Vec<Adjacency> = (0..chunks)
            .into_par_iter()
            .map(|c| {
                let mut part = Adjacency::default();
                let mut later = Vec::new();
                for i in c * CHUNK..((c + 1) * CHUNK).min(polygons.len()) {
                    let p = &polygons[i];
                    let b = Aabb::of(p.vertices());
                    let grow = NEAR_EDGE * diameter(p);
                    let b = Aabb {
                        lo: b.lo - DVec3::splat(grow),
                        hi: b.hi + DVec3::splat(grow),
                    };
                    later.clear();
                    bvh.for_each_overlapping(&b, |j| {
                        if j as usize > i {
                            later.push(j as usize);
                        }
                    });
                    later.sort_unstable();
                    for &j in &later {
                        pair(polygons, i, j, &mut part);
                    }
                }
                part
            })
            .collect();
        let mut out = Adjacency::default();
        for part in parts {
            out.edges.extend(part.edges);
            out.near_misses.extend(part.near_misses);
        }
        out
    }

    /// The adjacency of `polygons` after some of the polygons this one was found on were cut
    /// into pieces in place (`pieces`: per polygon cut, its index before and how many pieces it
    /// became, ascending; every other polygon keeps its geometry and its order). Equal to
    /// [`Adjacency::of`] on the new polygons: pairs of uncut polygons keep their edges (their
    /// indices shift, their order does not), and only the pieces are paired again, under the
    /// same test of boxes that `of` applies. `tracked` locates the candidates: the boxes the
    /// previous pass started from ([`Tracked`]), each covering its pieces.
    pub(crate) fn after_cut(
        &self,
        polygons: &[Polygon],
        pieces: &[(u32, u32)],
        tracked: &mut Tracked,
    ) -> Adjacency {
        let old_n = polygons.len() - pieces.iter().map(|&(_, n)| n as usize - 1).sum::<usize>();
        // New index of every old polygon's first piece, and whether it was cut.
        let mut first = Vec::with_capacity(old_n + 1);
        let mut cut = vec![false; old_n];
        let (mut next, mut k) = (0usize, 0usize);
        for (i, was_cut) in cut.iter_mut().enumerate() {
            first.push(next);
            let n = match pieces.get(k) {
                Some(&(at, n)) if at as usize == i => {
                    k += 1;
                    *was_cut = true;
                    n as usize
                }
                _ => 1,
            };
            next += n;
        }
        first.push(next);
        tracked.remap(&first);
        let moved = |s: Side| Side {
            polygon: first[s.polygon as usize] as u32,
            side: s.side,
        };
        let kept = |a: Side, b: Side| !cut[a.polygon as usize] && !cut[b.polygon as usize];
        let mut out = Adjacency::default();
        for e in &self.edges {
            if kept(e.a, e.b) {
                out.edges.push(SharedEdge {
                    a: moved(e.a),
                    b: moved(e.b),
                    ..*e
                });
            }
        }
        for m in &self.near_misses {
            if kept(m.a, m.b) {
                out.near_misses.push(NearMiss {
                    a: moved(m.a),
                    b: moved(m.b),
                    gap: m.gap,
                });
            }
        }
        let new_pieces: Vec<usize> = pieces
            .iter()
            .flat_map(|&(at, n)| first[at as usize]..first[at as usize] + n as usize)
            .collect();
        let is_piece = |i: usize| new_pieces.binary_search(&i).is_ok();
        let reach = NEAR_EDGE * polygons.iter().map(diameter).fold(0.0, f64::max);
        for &p in &new_pieces {
            let b = grown(&polygons[p], reach);
            let mut near = Vec::new();
            tracked.for_each_overlapping(&b, |c| near.push(c));
            near.sort_unstable();
            near.dedup();
            for c in near {
                if c == p || (is_piece(c) && c < p) {
                    continue;
                }
                let (i, j) = (p.min(c), p.max(c));
                if grown(&polygons[i], NEAR_EDGE * diameter(&polygons[i]))
                    .overlaps(&Aabb::of(polygons[j].vertices()))
                {
                    pair(polygons, i, j, &mut out);
                }
            }
        }
        let key = |a: Side, b: Side| (a.polygon, b.polygon);
        out.edges.sort_by_key(|e| key(e.a, e.b));
        out.near_misses.sort_by_key(|m| key(m.a, m.b));
        out
    }

    /// Whether the two polygons of `e` carry one continuous radiosity across it: coplanar
    /// neighbours of equal material (same reflectance and emission).
    pub fn continuous(e: &SharedEdge, polygons: &[Polygon], materials: &[crate::Material]) -> bool {
        if e.junction != Junction::Coplanar {
            return false;
        }
        let ma = &materials[polygons[e.a.polygon as usize].material as usize];
        let mb = &materials[polygons[e.b.polygon as usize].material as usize];
        ma.reflectance == mb.reflectance && ma.emission == mb.emission
    }

    /// Per edge (aligned with `edges`): whether a third polygon meets either of its sides at
    /// an angle over part of its segment (a wall standing on the seam, whose two sides see
    /// different light). Each side's crossing edges are indexed once, so the cost grows with
    /// the edges, not their square.
    pub fn standing(&self) -> Vec<bool> {
        let mut by_side: std::collections::HashMap<Side, Vec<(usize, [f64; 2])>> =
            std::collections::HashMap::new();
        for (i, o) in self.edges.iter().enumerate() {
            if !matches!(o.junction, Junction::Coplanar) {
                by_side.entry(o.a).or_default().push((i, o.a_range));
                by_side.entry(o.b).or_default().push((i, o.b_range));
            }
        }
        let overlaps = |r: [f64; 2], q: [f64; 2]| {
            let (lo, hi) = (r[0].min(r[1]), r[0].max(r[1]));
            let (ql, qh) = (q[0].min(q[1]), q[0].max(q[1]));
            qh.min(hi) - ql.max(lo) > 1e-9
        };
        self.edges
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let on = |side: Side, range: [f64; 2]| {
                    by_side
                        .get(&side)
                        .is_some_and(|v| v.iter().any(|&(j, q)| j != i && overlaps(range, q)))
                };
                on(e.a, e.a_range) || on(e.b, e.b_range)
            })
            .collect()
    }

    /// Counts for reports.
    pub fn summary(&self, polygons: &[Polygon], materials: &[crate::Material]) -> AdjacencySummary {
        let mut s = AdjacencySummary {
            shared: self.edges.len(),
            near_misses: self.near_misses.len(),
            ..AdjacencySummary::default()
        };
        for e in &self.edges {
            match e.junction {
                Junction::Coplanar => s.coplanar += 1,
                Junction::Crease { .. } => s.creases += 1,
                Junction::BackToBack | Junction::Overlap => s.folded += 1,
            }
            s.continuous += usize::from(Adjacency::continuous(e, polygons, materials));
            s.partial += usize::from(!e.is_full());
            s.largest_gap = s.largest_gap.max(e.gap);
        }
        s
    }
}

/// The box of polygon `p` grown by `by` on every side.
fn grown(p: &Polygon, by: f64) -> Aabb {
    let b = Aabb::of(p.vertices());
    Aabb {
        lo: b.lo - DVec3::splat(by),
        hi: b.hi + DVec3::splat(by),
    }
}

/// The boxes of the polygons of a first pass, for finding the neighbours of pieces cut from
/// them in later passes: a piece lies inside its polygon's box, so the polygons (now ranges of
/// pieces) whose boxes meet a box include every polygon that does.
pub(crate) struct Tracked {
    bvh: Bvh,
    /// Per polygon of the first pass: the range of current indices it became.
    ranges: Vec<std::ops::Range<usize>>,
}

impl Tracked {
    /// Tracks `polygons` as they are.
    pub(crate) fn new(polygons: &[Polygon]) -> Tracked {
        Tracked {
            bvh: Bvh::build(polygons),
            ranges: (0..polygons.len()).map(|i| i..i + 1).collect(),
        }
    }

    /// Follows a cut whose old polygon `i` became the new indices `first[i]..first[i + 1]`.
    fn remap(&mut self, first: &[usize]) {
        for r in &mut self.ranges {
            *r = first[r.start]..first[r.end];
        }
    }

    /// Calls `f` with every current polygon whose first-pass polygon's box meets `b` (a
    /// superset of the polygons whose own boxes do).
    fn for_each_overlapping(&self, b: &Aabb, mut f: impl FnMut(usize)) {
        self.bvh.for_each_overlapping(b, |o| {
            for i in self.ranges[o as usize].clone() {
                f(i);
            }
        });
    }
}

/// Sides of a polygon that have a length (a triangle's side 2 has none).
fn sides(p: &Polygon) -> impl Iterator<Item = u8> + '_ {
    (0..4u8).filter(move |&s| !(p.shape == Shape::Triangle && s == 2))
}

/// Compares every side of polygon `i` with every side of polygon `j` (i < j).
fn pair(polygons: &[Polygon], i: usize, j: usize, out: &mut Adjacency) {
    let (pi, pj) = (&polygons[i], &polygons[j]);
    for si in sides(pi) {
        for sj in sides(pj) {
            let (p0, p1) = side_endpoints(pi, si);
            let (q0, q1) = side_endpoints(pj, sj);
            let Some(m) = match_sides(p0, p1, q0, q1) else {
                continue;
            };
            let a = Side {
                polygon: i as u32,
                side: si,
            };
            let b = Side {
                polygon: j as u32,
                side: sj,
            };
            if m.gap > EDGE_TOL {
                out.near_misses.push(NearMiss { a, b, gap: m.gap });
                continue;
            }
            out.edges.push(SharedEdge {
                a,
                b,
                a_range: m.a_range,
                b_range: m.b_range,
                junction: junction(pi, pj, p0, p1),
                gap: m.gap,
            });
        }
    }
}

/// A candidate overlap of two segments.
struct Match {
    a_range: [f64; 2],
    b_range: [f64; 2],
    gap: f64,
}

/// Whether segments (p0, p1) and (q0, q1) lie on one line within [`NEAR_EDGE`] and overlap in
/// more than [`EDGE_TOL`] of the longer one's length; parameters snapped to 0 and 1 within
/// [`EDGE_TOL`].
fn match_sides(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> Option<Match> {
    let d = p1 - p0;
    let e = q1 - q0;
    // Cheap rejection first (most side pairs of neighbours are apart): segments that match lie
    // within NEAR_EDGE times the longer length of each other, and 2 max(|d|, |e|) in the max
    // norm bounds that length, so boxes apart by more than that never match.
    let reach = 2.0 * NEAR_EDGE * d.abs().max_element().max(e.abs().max_element());
    let (plo, phi) = (p0.min(p1), p0.max(p1));
    let (qlo, qhi) = (q0.min(q1), q0.max(q1));
    if (plo - qhi).max_element() > reach || (qlo - phi).max_element() > reach {
        return None;
    }
    // And off the line: q0 and q1 within NEAR_EDGE times the longer length of p's line (the
    // distance of q from it is |d x (q - p0)| / |d|; squared, against 4 NEAR_EDGE^2
    // max(|d|^2, |e|^2) |d|^2, which the true bound never exceeds).
    let dd = d.length_squared();
    let bound = 4.0 * NEAR_EDGE * NEAR_EDGE * dd.max(e.length_squared()) * dd;
    if d.cross(q0 - p0).length_squared() > bound || d.cross(q1 - p0).length_squared() > bound {
        return None;
    }
    let long = d.length().max(e.length());
    if long.is_nan()
        || long <= 0.0
        || d.length() <= EDGE_TOL * long
        || e.length() <= EDGE_TOL * long
    {
        return None;
    }
    let dd = d.length_squared();
    let t = |q: DVec3| (q - p0).dot(d) / dd;
    let off = |q: DVec3| (q - (p0 + t(q) * d)).length() / long;
    let ee = e.length_squared();
    let off_b = |p: DVec3| (p - (q0 + (p - q0).dot(e) / ee * e)).length() / long;
    let gap = off(q0).max(off(q1)).max(off_b(p0)).max(off_b(p1));
    if gap > NEAR_EDGE {
        return None;
    }
    let (t0, t1) = (t(q0), t(q1));
    let snap = |x: f64| {
        let tol = EDGE_TOL * long / d.length();
        if x.abs() <= tol {
            0.0
        } else if (x - 1.0).abs() <= tol {
            1.0
        } else {
            x
        }
    };
    let (t0, t1) = (snap(t0), snap(t1));
    let lo = t0.min(t1).max(0.0);
    let hi = t0.max(t1).min(1.0);
    if (hi - lo) * d.length() <= EDGE_TOL * long {
        return None;
    }
    let snap_b = |x: f64| {
        let tol = EDGE_TOL * long / e.length();
        if x.abs() <= tol {
            0.0
        } else if (x - 1.0).abs() <= tol {
            1.0
        } else {
            x.clamp(0.0, 1.0)
        }
    };
    let b_at = |s: f64| snap_b((s - t0) / (t1 - t0));
    Some(Match {
        a_range: [lo, hi],
        b_range: [b_at(lo), b_at(hi)],
        gap,
    })
}

/// How `pi` and `pj` meet along the edge from `p0` to `p1`.
fn junction(pi: &Polygon, pj: &Polygon, p0: DVec3, p1: DVec3) -> Junction {
    let c = pi.normal.dot(pj.normal).clamp(-1.0, 1.0);
    let parallel = COPLANAR_DEGREES.to_radians().cos();
    // Which side of the edge each polygon's centroid lies on, in pi's plane.
    let d = (p1 - p0).normalize_or_zero();
    let across = pi.normal.cross(d);
    let side = |p: &Polygon| {
        let vs = p.vertices();
        let centroid = vs.iter().copied().sum::<DVec3>() / vs.len() as f64;
        (centroid - p0).dot(across)
    };
    let opposite = side(pi) * side(pj) < 0.0;
    if c >= parallel {
        if opposite {
            Junction::Coplanar
        } else {
            Junction::Overlap
        }
    } else if c <= -parallel {
        Junction::BackToBack
    } else {
        Junction::Crease {
            degrees: c.acos().to_degrees(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(c: [[f64; 3]; 4], material: u32) -> Polygon {
        Polygon::quad(c.map(DVec3::from_array), material, 0).expect("valid quad")
    }

    /// A unit floor square at x0..x0+w, z0..z0+h (y = 0, facing up).
    fn floor(x0: f64, z0: f64, w: f64, h: f64) -> Polygon {
        quad(
            [
                [x0, 0.0, z0 + h],
                [x0 + w, 0.0, z0 + h],
                [x0 + w, 0.0, z0],
                [x0, 0.0, z0],
            ],
            0,
        )
    }

    #[test]
    fn a_split_floor_shares_one_full_reversed_edge() {
        let polys = [floor(0.0, 0.0, 1.0, 1.0), floor(1.0, 0.0, 1.0, 1.0)];
        let adj = Adjacency::of(&polys);
        assert_eq!(adj.edges.len(), 1, "{adj:?}");
        let e = adj.edges[0];
        assert_eq!(e.junction, Junction::Coplanar);
        assert!(e.is_full());
        // Polygon 0's u = 1 side meets polygon 1's u = 0 side, both running with v.
        assert_eq!((e.a.side, e.b.side), (1, 3));
        assert!(!e.reversed());
        assert_eq!(e.gap, 0.0);
        assert!(adj.near_misses.is_empty());
    }

    #[test]
    fn an_l_corner_is_a_t_junction_with_dyadic_ranges() {
        // A 2 x 1 strip and a unit square on the first half of its far side.
        let polys = [floor(0.0, 0.0, 2.0, 1.0), floor(0.0, -1.0, 1.0, 1.0)];
        let adj = Adjacency::of(&polys);
        assert_eq!(adj.edges.len(), 1, "{adj:?}");
        let e = adj.edges[0];
        assert!(!e.is_full());
        assert_eq!(e.junction, Junction::Coplanar);
        // The shared line is z = 0: the strip's side 2 and the square's side 0.
        let (p0, p1) = side_endpoints(&polys[0], e.a.side);
        assert_eq!(p0.z, 0.0);
        assert_eq!(p1.z, 0.0);
        assert_eq!(e.a_range[1] - e.a_range[0], 0.5);
        assert_eq!(e.b_range[0].min(e.b_range[1]), 0.0);
        assert_eq!(e.b_range[0].max(e.b_range[1]), 1.0);
        // The map between the two parameters is affine and hits the ends.
        assert_eq!(e.b_of_a(e.a_range[0]), e.b_range[0]);
        assert_eq!(e.b_of_a(e.a_range[1]), e.b_range[1]);
    }

    #[test]
    fn a_wall_on_a_floor_is_a_right_angle_crease() {
        let wall = quad(
            [
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            0,
        );
        let polys = [floor(0.0, 0.0, 1.0, 1.0), wall];
        let adj = Adjacency::of(&polys);
        assert_eq!(adj.edges.len(), 1, "{adj:?}");
        match adj.edges[0].junction {
            Junction::Crease { degrees } => assert!((degrees - 90.0).abs() < 1e-9, "{degrees}"),
            j => panic!("expected a crease, got {j:?}"),
        }
    }

    #[test]
    fn a_crack_is_a_near_miss_not_a_shared_edge() {
        let polys = [floor(0.0, 0.0, 1.0, 1.0), floor(1.0 + 1e-4, 0.0, 1.0, 1.0)];
        let adj = Adjacency::of(&polys);
        assert!(adj.edges.is_empty(), "{adj:?}");
        assert_eq!(adj.near_misses.len(), 1);
        assert!((adj.near_misses[0].gap - 1e-4).abs() < 1e-9);
        // A vertex moved by a tenth of the tolerance still matches.
        let polys = [floor(0.0, 0.0, 1.0, 1.0), floor(1.0 + 1e-7, 0.0, 1.0, 1.0)];
        let adj = Adjacency::of(&polys);
        assert_eq!(adj.edges.len(), 1);
        assert!(adj.edges[0].is_full());
    }

    #[test]
    fn a_triangle_fan_shares_its_spokes() {
        let c = DVec3::ZERO;
        let ring: Vec<DVec3> = (0..6)
            .map(|k| {
                let a = k as f64 * std::f64::consts::TAU / 6.0;
                DVec3::new(a.cos(), 0.0, -a.sin())
            })
            .collect();
        let polys: Vec<Polygon> = (0..6)
            .map(|k| Polygon::triangle([c, ring[k], ring[(k + 1) % 6]], 0, 0).expect("triangle"))
            .collect();
        let adj = Adjacency::of(&polys);
        assert_eq!(adj.edges.len(), 6, "{adj:?}");
        assert!(adj
            .edges
            .iter()
            .all(|e| e.junction == Junction::Coplanar && e.is_full()));
    }
}
