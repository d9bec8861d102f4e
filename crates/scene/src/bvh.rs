//! Ray casting over the scene's polygons, shared by the stages that trace rays: the radiosity
//! solver (the visibility half of every form factor) and the independent path tracer. A
//! binned-SAH bounding volume hierarchy over the polygons answers "any hit" queries for shadow
//! segments, "first hit" queries for paths, and box-overlap queries used to prove a
//! receiver/shooter pair unoccluded without casting rays. It holds geometry only: nothing of
//! either stage's light transport.
//!
//! Invariants: the tree is built once from the scene and never changes; leaves hold at most
//! [`LEAF_SIZE`] polygons (more only where their centroids coincide); no leaf is deeper than
//! [`MAX_TREE_DEPTH`], so the queries' fixed traversal stacks never overflow (past
//! [`SAH_DEPTH`] levels a node is split at its median centroid, which halves it: polygons spaced
//! so unevenly that every SAH split cuts off a few, sizes growing geometrically, would otherwise
//! chain one level per polygon); the build is deterministic (stable sorts, ties by polygon index), and a
//! query's answer does not depend on traversal order (any hit is a yes/no answer). Ray/polygon
//! tests run in `f64` on the polygon's two triangles (c0, c1, c2) and (c0, c2, c3), so a convex
//! planar quad is covered exactly once and a collapsed-quad triangle is one triangle.

use glam::DVec3;
use std::ops::ControlFlow;

use crate::{Polygon, Shape};

/// Most polygons in a leaf.
pub const LEAF_SIZE: usize = 4;
/// SAH bins per axis.
const BINS: usize = 12;
/// Levels split by the surface area heuristic; deeper nodes are split at their median centroid.
pub const SAH_DEPTH: usize = 32;
/// Deepest leaf (the root at depth 0): [`SAH_DEPTH`] levels, then halvings of at most 2^32
/// polygons down to leaves of [`LEAF_SIZE`]. A traversal's stack holds at most one entry per
/// level plus one, within the queries' 64.
pub const MAX_TREE_DEPTH: usize = SAH_DEPTH + 30;

/// An axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub lo: DVec3,
    /// Maximum corner.
    pub hi: DVec3,
}

impl Aabb {
    /// The empty box (union identity).
    pub const EMPTY: Aabb = Aabb {
        lo: DVec3::splat(f64::INFINITY),
        hi: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The smallest box containing `pts`.
    pub fn of(pts: &[DVec3]) -> Aabb {
        pts.iter().fold(Aabb::EMPTY, |b, p| b.grow(*p))
    }

    /// This box grown to contain `p`.
    pub fn grow(self, p: DVec3) -> Aabb {
        Aabb {
            lo: self.lo.min(p),
            hi: self.hi.max(p),
        }
    }

    /// Union of two boxes.
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    /// Whether the closed boxes overlap.
    pub fn overlaps(&self, o: &Aabb) -> bool {
        self.lo.cmple(o.hi).all() && o.lo.cmple(self.hi).all()
    }

    fn half_area(&self) -> f64 {
        let d = (self.hi - self.lo).max(DVec3::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

#[derive(Debug, Clone, Copy)]
struct Node {
    bounds: Aabb,
    /// Leaf: index of the first entry in `order`; inner: index of the left child (right = +1).
    first: u32,
    /// Number of polygons for a leaf, 0 for an inner node.
    count: u32,
}

/// A bounding volume hierarchy over a scene's polygons.
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
    tris: Vec<[DVec3; 4]>,
    shapes: Vec<Shape>,
    boxes: Vec<Aabb>,
    /// Per polygon, whether faces lying over its front hide it from every ray coming from in
    /// front ([`crate::Polygon::sealed`]), and whether a face back to back with it shows
    /// instead of it from behind ([`crate::Polygon::backed`]): a first hit never stops there
    /// from that side, the other face is what the ray meets, even where the two tie (a panel
    /// snapped onto a ceiling's plane, a two-sided polygon's reversed twin).
    hidden: Vec<(bool, bool)>,
}

impl Bvh {
    /// Builds the hierarchy (binned SAH, deterministic).
    pub fn build(polygons: &[Polygon]) -> Bvh {
        let boxes: Vec<Aabb> = polygons.iter().map(|p| Aabb::of(p.vertices())).collect();
        let cents: Vec<DVec3> = boxes.iter().map(|b| 0.5 * (b.lo + b.hi)).collect();
        let mut bvh = Bvh {
            nodes: Vec::new(),
            order: (0..polygons.len() as u32).collect(),
            tris: polygons.iter().map(|p| p.corners).collect(),
            shapes: polygons.iter().map(|p| p.shape).collect(),
            boxes: boxes.clone(),
            hidden: polygons
                .iter()
                .map(|p| (p.sealed.hidden_from_front(), p.backed))
                .collect(),
        };
        if polygons.is_empty() {
            return bvh;
        }
        bvh.nodes.push(Node {
            bounds: Aabb::EMPTY,
            first: 0,
            count: 0,
        });
        let mut stack = vec![(0usize, 0usize, polygons.len(), 0usize)];
        while let Some((id, start, end, depth)) = stack.pop() {
            let bounds = bvh.order[start..end]
                .iter()
                .fold(Aabb::EMPTY, |b, &i| b.union(boxes[i as usize]));
            bvh.nodes[id].bounds = bounds;
            let split = if end - start <= LEAF_SIZE {
                None
            } else if depth < SAH_DEPTH {
                sah_split(&mut bvh.order[start..end], &boxes, &cents)
            } else {
                median_split(&mut bvh.order[start..end], &cents)
            };
            match split {
                Some(mid) => {
                    let left = bvh.nodes.len();
                    for _ in 0..2 {
                        bvh.nodes.push(Node {
                            bounds: Aabb::EMPTY,
                            first: 0,
                            count: 0,
                        });
                    }
                    bvh.nodes[id].first = left as u32;
                    bvh.nodes[id].count = 0;
                    stack.push((left + 1, start + mid, end, depth + 1));
                    stack.push((left, start, start + mid, depth + 1));
                }
                None => {
                    bvh.nodes[id].first = start as u32;
                    bvh.nodes[id].count = (end - start) as u32;
                }
            }
        }
        bvh
    }

    /// Whether the open segment from `a` to `b` (parameters in (`T_EPS`, 1 - `T_EPS`)) hits any
    /// polygon other than `skip0` and `skip1`.
    pub fn occluded(&self, a: DVec3, b: DVec3, skip0: u32, skip1: u32) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let d = b - a;
        let inv = DVec3::ONE / d;
        // A binned-SAH tree over polygons is far shallower than 32 levels for any scene this
        // tool handles; a deeper tree would skip subtrees here (a missed occluder, never a panic).
        let mut stack = [0u32; 64];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = self.nodes[stack[sp] as usize];
            if !slab_hit(&node.bounds, a, inv) {
                continue;
            }
            if node.count > 0 {
                let s = node.first as usize;
                for &pi in &self.order[s..s + node.count as usize] {
                    if pi == skip0 || pi == skip1 {
                        continue;
                    }
                    if self.hits(pi as usize, a, d) {
                        return true;
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.first;
                stack[sp + 1] = node.first + 1;
                sp += 2;
            }
        }
        false
    }

    /// Calls `f` with the index of every polygon whose bounding box overlaps `b`, in a
    /// deterministic order.
    pub fn for_each_overlapping(&self, b: &Aabb, mut f: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        // Fixed stack as in `occluded` (no allocation per query; same depth argument).
        let mut stack = [0u32; 64];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = self.nodes[stack[sp] as usize];
            if !node.bounds.overlaps(b) {
                continue;
            }
            if node.count > 0 {
                let s = node.first as usize;
                for &pi in &self.order[s..s + node.count as usize] {
                    if self.boxes[pi as usize].overlaps(b) {
                        f(pi);
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.first + 1;
                stack[sp + 1] = node.first;
                sp += 2;
            }
        }
    }

    /// Calls `f` with the index of every polygon whose bounding box overlaps `b` and is not
    /// entirely outside any of the half-spaces `planes`, in the order of
    /// [`Bvh::for_each_overlapping`] (the same traversal with more subtrees skipped).
    ///
    /// A plane `(n, p0, tol)` keeps the points with `n . (p - p0) >= -tol`: a node (or polygon)
    /// box whose every point has `n . (p - p0) < -tol` is skipped. Callers whose own per-polygon
    /// tests reject everything outside the same half-spaces see exactly the polygons they would
    /// have accepted from the plain box query, found with far fewer node visits.
    pub fn for_each_in(&self, b: &Aabb, planes: &[(DVec3, DVec3, f64)], mut f: impl FnMut(u32)) {
        self.try_for_each_in(b, planes, |q| {
            f(q);
            ControlFlow::Continue(())
        });
    }

    /// [`Bvh::for_each_in`] that stops at the first call of `f` that breaks (a caller that has
    /// found what it looks for need not walk the rest of the tree).
    pub fn try_for_each_in(
        &self,
        b: &Aabb,
        planes: &[(DVec3, DVec3, f64)],
        mut f: impl FnMut(u32) -> ControlFlow<()>,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let outside = |bx: &Aabb| {
            let c = 0.5 * (bx.lo + bx.hi);
            let h = 0.5 * (bx.hi - bx.lo);
            planes
                .iter()
                .any(|(n, p0, tol)| n.dot(c - *p0) + n.abs().dot(h) < -*tol)
        };
        let mut stack = [0u32; 64];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = self.nodes[stack[sp] as usize];
            if !node.bounds.overlaps(b) || outside(&node.bounds) {
                continue;
            }
            if node.count > 0 {
                let s = node.first as usize;
                for &pi in &self.order[s..s + node.count as usize] {
                    let pb = &self.boxes[pi as usize];
                    if pb.overlaps(b) && !outside(pb) && f(pi).is_break() {
                        return;
                    }
                }
            } else if sp + 2 <= stack.len() {
                stack[sp] = node.first + 1;
                stack[sp + 1] = node.first;
                sp += 2;
            }
        }
    }

    /// The first polygon other than `skip` that the open segment a + t d, t in (`T_EPS`,
    /// 1 - `T_EPS`), hits, and its t; ties at equal t go to the smaller index, so the answer
    /// does not depend on the traversal.
    pub fn first_hit(&self, a: DVec3, d: DVec3, skip: u32) -> Option<(u32, f64)> {
        self.first_hit_skipping(a, d, [skip, u32::MAX])
    }

    /// [`Bvh::first_hit`] skipping both polygons of `skip` (`u32::MAX` skips nothing).
    pub fn first_hit_skipping(&self, a: DVec3, d: DVec3, skip: [u32; 2]) -> Option<(u32, f64)> {
        self.first_hit_from(a, d, T_EPS, skip)
    }

    /// The first hit of a ray cast as the segment a + t d, t in (`t0`, 1 - `T_EPS`), skipping
    /// both polygons of `skip`: a ray whose length is set by how far it must reach (across a
    /// backdrop a million times the room's size) and whose blind zone at its origin by the
    /// scale of the geometry around it (`t0` = `T_EPS` times that scale over the length).
    /// [`Bvh::first_hit_skipping`] is the case `t0` = `T_EPS`, the same bits.
    pub fn first_hit_from(
        &self,
        a: DVec3,
        d: DVec3,
        t0: f64,
        skip: [u32; 2],
    ) -> Option<(u32, f64)> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv = DVec3::ONE / d;
        let mut best: Option<(u32, f64)> = None;
        // Front to back: the nearer child is visited first and a node entered beyond the best
        // hit so far is skipped (entry parameters ride on the stack).
        let mut stack = [(0u32, 0.0f64); 64];
        let mut sp = 0usize;
        if let Some(t) = slab_entry(&self.nodes[0].bounds, a, inv, 1.0) {
            stack[0] = (0, t);
            sp = 1;
        }
        while sp > 0 {
            sp -= 1;
            let (id, entry) = stack[sp];
            let tmax = best.map_or(1.0, |b| b.1);
            if entry > tmax {
                continue;
            }
            let node = self.nodes[id as usize];
            if node.count > 0 {
                let s = node.first as usize;
                for &pi in &self.order[s..s + node.count as usize] {
                    if pi == skip[0] || pi == skip[1] || self.hidden_from(pi, d) {
                        continue;
                    }
                    if let Some(t) = self.hit_t(pi, a, d, t0) {
                        let better = match best {
                            None => true,
                            Some((bi, bt)) => t < bt || (t == bt && pi < bi),
                        };
                        if better {
                            best = Some((pi, t));
                        }
                    }
                }
            } else if sp + 2 <= stack.len() {
                let (l, r) = (node.first, node.first + 1);
                let tl = slab_entry(&self.nodes[l as usize].bounds, a, inv, tmax);
                let tr = slab_entry(&self.nodes[r as usize].bounds, a, inv, tmax);
                match (tl, tr) {
                    (Some(x), Some(y)) => {
                        // Farther pushed first, so the nearer pops next.
                        let (near, far) = if y < x {
                            ((r, y), (l, x))
                        } else {
                            ((l, x), (r, y))
                        };
                        stack[sp] = far;
                        stack[sp + 1] = near;
                        sp += 2;
                    }
                    (Some(x), None) => {
                        stack[sp] = (l, x);
                        sp += 1;
                    }
                    (None, Some(y)) => {
                        stack[sp] = (r, y);
                        sp += 1;
                    }
                    (None, None) => {}
                }
            }
        }
        best
    }

    /// Whether polygon `pi` is hidden from a ray along `d`: by faces lying over its front if
    /// the ray comes from in front, by a face back to back with it if from behind.
    #[inline]
    fn hidden_from(&self, pi: u32, d: DVec3) -> bool {
        let (front, back) = self.hidden[pi as usize];
        (front || back) && {
            let c = &self.tris[pi as usize];
            let towards = (c[1] - c[0]).cross(c[2] - c[0]).dot(d);
            if towards < 0.0 {
                front
            } else {
                back && towards > 0.0
            }
        }
    }

    /// The parameter at which the segment a + t d, t in (`t0`, 1 - `T_EPS`), meets polygon
    /// `pi` (the nearer of a quad's two triangles).
    #[inline]
    fn hit_t(&self, pi: u32, a: DVec3, d: DVec3, t0: f64) -> Option<f64> {
        let c = &self.tris[pi as usize];
        let t = segment_triangle_in(a, d, [c[0], c[1], c[2]], t0);
        if self.shapes[pi as usize] != Shape::Quad {
            return t;
        }
        match (t, segment_triangle_in(a, d, [c[0], c[2], c[3]], t0)) {
            (Some(x), Some(y)) => Some(x.min(y)),
            (x, y) => x.or(y),
        }
    }

    /// The first hit of the segment a + t d, t in (0, 1 - `T_EPS`), among the polygons `only`
    /// (no blind zone at its origin: for faces known to lie in front of it however close,
    /// `crate::seal`); ties by index.
    pub fn first_hit_among(&self, a: DVec3, d: DVec3, only: &[u32]) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        for &pi in only {
            if pi as usize >= self.tris.len() {
                continue;
            }
            if let Some(t) = self.hit_t(pi, a, d, 0.0) {
                if best.is_none_or(|(bi, bt)| t < bt || (t == bt && pi < bi)) {
                    best = Some((pi, t));
                }
            }
        }
        best
    }

    /// Whether the open segment a + t d, t in (`T_EPS`, 1 - `T_EPS`), hits polygon `i`.
    pub fn hits(&self, i: usize, a: DVec3, d: DVec3) -> bool {
        let c = &self.tris[i];
        if segment_triangle(a, d, c[0], c[1], c[2]) {
            return true;
        }
        self.shapes[i] == Shape::Quad && segment_triangle(a, d, c[0], c[2], c[3])
    }
}

/// Segment parameters closer than this to either end do not count as hits: the segment starts on a
/// receiver and ends on a shooter, and polygons touching either end (a wall meeting the floor) must
/// not shadow it.
pub const T_EPS: f64 = 1e-7;

#[inline]
fn slab_hit(b: &Aabb, a: DVec3, inv: DVec3) -> bool {
    let t0 = (b.lo - a) * inv;
    let t1 = (b.hi - a) * inv;
    // NaN (0 * inf on a slab boundary) is dropped by min/max, keeping the test conservative.
    let tmin = t0.min(t1).max_element().max(0.0);
    let tmax = t0.max(t1).min_element().min(1.0);
    tmin <= tmax || tmin.is_nan() || tmax.is_nan()
}

/// Where the segment a + t (1 / inv), t in [0, `tmax`], enters box `b` (its parameter), if it
/// meets it; conservative like [`slab_hit`] (a NaN from a slab boundary counts as a meeting at
/// t = 0).
#[inline]
fn slab_entry(b: &Aabb, a: DVec3, inv: DVec3, tmax: f64) -> Option<f64> {
    let t0 = (b.lo - a) * inv;
    let t1 = (b.hi - a) * inv;
    let lo = t0.min(t1).max_element().max(0.0);
    let hi = t0.max(t1).min_element().min(tmax);
    if lo.is_nan() || hi.is_nan() {
        return Some(0.0);
    }
    (lo <= hi).then_some(lo)
}

/// [`segment_triangle`] returning the hit's parameter t.
#[inline]
fn segment_triangle_t(a: DVec3, d: DVec3, p0: DVec3, p1: DVec3, p2: DVec3) -> Option<f64> {
    segment_triangle_in(a, d, [p0, p1, p2], T_EPS)
}

/// [`segment_triangle_t`] with the blind zone at the segment's start `t0` instead of `T_EPS`.
#[inline]
fn segment_triangle_in(a: DVec3, d: DVec3, [p0, p1, p2]: [DVec3; 3], t0: f64) -> Option<f64> {
    let e1 = p1 - p0;
    let e2 = p2 - p0;
    let pv = d.cross(e2);
    let det = e1.dot(pv);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv = 1.0 / det;
    let tv = a - p0;
    let u = tv.dot(pv) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = tv.cross(e1);
    let v = d.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > t0 && t < 1.0 - T_EPS).then_some(t)
}

/// Moller-Trumbore, double-sided, segment a + t d with t in (T_EPS, 1 - T_EPS).
#[inline]
fn segment_triangle(a: DVec3, d: DVec3, p0: DVec3, p1: DVec3, p2: DVec3) -> bool {
    segment_triangle_t(a, d, p0, p1, p2).is_some()
}

/// Partitions `idx` by the best binned-SAH plane; returns the split position, or `None` when a
/// leaf is cheaper or no plane separates the centroids.
/// Splits `idx` (more than [`LEAF_SIZE`] polygons) into halves by centroid along the axis where
/// the centroids spread widest (ties by polygon index, so deterministic); `None` where every
/// centroid coincides (one leaf holds them all).
fn median_split(idx: &mut [u32], cents: &[DVec3]) -> Option<usize> {
    let cb = idx
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.grow(cents[i as usize]));
    let ext = cb.hi - cb.lo;
    if ext.max_element() <= 0.0 {
        return None;
    }
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    idx.sort_by(|&a, &b| {
        cents[a as usize][axis]
            .total_cmp(&cents[b as usize][axis])
            .then(a.cmp(&b))
    });
    Some(idx.len() / 2)
}

fn sah_split(idx: &mut [u32], boxes: &[Aabb], cents: &[DVec3]) -> Option<usize> {
    let cb = idx
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.grow(cents[i as usize]));
    let mut best: Option<(f64, usize, f64)> = None; // (cost, axis, plane)
    for axis in 0..3 {
        let lo = cb.lo[axis];
        let ext = cb.hi[axis] - lo;
        if ext <= 0.0 {
            continue;
        }
        let mut bins = [(Aabb::EMPTY, 0usize); BINS];
        let bin_of = |c: f64| (((c - lo) / ext * BINS as f64) as usize).min(BINS - 1);
        for &i in idx.iter() {
            let b = &mut bins[bin_of(cents[i as usize][axis])];
            b.0 = b.0.union(boxes[i as usize]);
            b.1 += 1;
        }
        // Boxes and counts of bins[k..], then one sweep from the left: the same unions (min and
        // max, exact in any order) as folding each side afresh, in linear time.
        let mut right = [(Aabb::EMPTY, 0usize); BINS];
        let mut acc = (Aabb::EMPTY, 0usize);
        for k in (1..BINS).rev() {
            acc = (acc.0.union(bins[k].0), acc.1 + bins[k].1);
            right[k] = acc;
        }
        let (mut lb, mut ln) = (Aabb::EMPTY, 0usize);
        for k in 1..BINS {
            lb = lb.union(bins[k - 1].0);
            ln += bins[k - 1].1;
            let (rb, rn) = right[k];
            if ln == 0 || rn == 0 {
                continue;
            }
            let cost = lb.half_area() * ln as f64 + rb.half_area() * rn as f64;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, lo + ext * k as f64 / BINS as f64));
            }
        }
    }
    let (cost, axis, plane) = best?;
    let all = idx
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.union(boxes[i as usize]));
    if idx.len() <= LEAF_SIZE * 4 && cost >= all.half_area() * idx.len() as f64 {
        return None;
    }
    // Stable partition: left keeps centroids below the plane, both sides keep index order.
    let (mut left, mut right): (Vec<u32>, Vec<u32>) =
        idx.iter().partition(|&&i| cents[i as usize][axis] < plane);
    let mid = left.len();
    if mid == 0 || mid == idx.len() {
        return None;
    }
    left.append(&mut right);
    idx.copy_from_slice(&left);
    Some(mid)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(n: usize) -> Vec<Polygon> {
        let mut v = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let (x, y) = (i as f64, j as f64);
                let z = ((i * 7 + j * 3) % 5) as f64;
                v.push(
                    Polygon::quad(
                        [
                            DVec3::new(x, y, z),
                            DVec3::new(x + 0.8, y, z),
                            DVec3::new(x + 0.8, y + 0.8, z),
                            DVec3::new(x, y + 0.8, z),
                        ],
                        0,
                        0,
                    )
                    .unwrap(),
                );
            }
        }
        v
    }

    /// The BVH must answer exactly like a brute-force loop over all polygons.
    #[test]
    fn matches_brute_force() {
        let polys = grid(12);
        let bvh = Bvh::build(&polys);
        let mut rng = base::rng::Rng::new(7);
        for _ in 0..3000 {
            let a = DVec3::new(
                rng.next_f64() * 13.0 - 0.5,
                rng.next_f64() * 13.0 - 0.5,
                -1.0,
            );
            let b = DVec3::new(
                rng.next_f64() * 13.0 - 0.5,
                rng.next_f64() * 13.0 - 0.5,
                6.0,
            );
            let brute = (0..polys.len()).any(|i| bvh.hits(i, a, b - a));
            assert_eq!(bvh.occluded(a, b, u32::MAX, u32::MAX), brute);
        }
        let mut n = 0;
        bvh.for_each_overlapping(
            &Aabb::of(&[DVec3::new(2.1, 2.1, -9.0), DVec3::new(3.5, 2.5, 9.0)]),
            |_| n += 1,
        );
        assert_eq!(n, 2);
    }

    /// Depth of the deepest leaf under node `id` (the root at 0).
    fn depth(bvh: &Bvh, id: usize) -> usize {
        let n = bvh.nodes[id];
        if n.count > 0 || bvh.nodes.len() == 1 {
            0
        } else {
            1 + depth(bvh, n.first as usize).max(depth(bvh, n.first as usize + 1))
        }
    }

    /// Regression: squares whose sizes and places grow geometrically made every SAH split cut
    /// off the largest, a chain one level per square, past the queries' 64-entry stacks, so
    /// a query silently skipped the deepest squares. The build now halves nodes past
    /// `SAH_DEPTH` levels, and every query finds what a brute-force loop finds.
    #[test]
    fn geometrically_spaced_polygons_stay_within_the_stack() {
        // Each square 8x farther out and larger than the one before: its centroid alone in the
        // last of the SAH's 12 bins, so every split cuts off one square.
        let polys: Vec<Polygon> = (0..100)
            .map(|k| {
                let s = 8f64.powi(k);
                let (x, y) = (s, 0.5 * s);
                Polygon::quad(
                    [
                        DVec3::new(x, y, 0.0),
                        DVec3::new(x + 0.5 * s, y, 0.0),
                        DVec3::new(x + 0.5 * s, y + 0.5 * s, 0.0),
                        DVec3::new(x, y + 0.5 * s, 0.0),
                    ],
                    0,
                    0,
                )
                .unwrap()
            })
            .collect();
        let bvh = Bvh::build(&polys);
        let d = depth(&bvh, 0);
        assert!(d <= MAX_TREE_DEPTH, "depth {d}");
        // Every square's centre, seen along z: one hit each, and the box query finds them all.
        for (k, p) in polys.iter().enumerate() {
            let c = 0.25 * p.vertices().iter().copied().sum::<DVec3>();
            let (a, b) = (c - DVec3::Z, c + DVec3::Z);
            assert!(bvh.occluded(a, b, u32::MAX, u32::MAX), "square {k} missed");
            let brute = (0..polys.len()).any(|i| i != k && bvh.hits(i, a, b - a));
            assert_eq!(bvh.occluded(a, b, k as u32, u32::MAX), brute, "square {k}");
        }
        let all = Aabb::of(&[DVec3::splat(-1.0), DVec3::splat(1e300)]);
        let mut n = 0;
        bvh.for_each_overlapping(&all, |_| n += 1);
        assert_eq!(n, polys.len());
    }

    /// `try_for_each_in` visits what `for_each_in` visits, in the same order, and stops at the
    /// first call that breaks: the k-th polygon found is the last one seen.
    #[test]
    fn a_query_that_breaks_stops_there() {
        let polys = grid(12);
        let bvh = Bvh::build(&polys);
        let b = Aabb::of(&[DVec3::new(1.5, 1.5, -9.0), DVec3::new(8.5, 7.5, 9.0)]);
        let planes = [(DVec3::new(1.0, 1.0, 0.0), DVec3::new(6.0, 6.0, 0.0), 1e-9)];
        let mut all = Vec::new();
        bvh.for_each_in(&b, &planes, |q| all.push(q));
        assert!(all.len() > 10, "{} found", all.len());
        for k in [1, 5, all.len()] {
            let mut seen = Vec::new();
            bvh.try_for_each_in(&b, &planes, |q| {
                seen.push(q);
                if seen.len() == k {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            });
            assert_eq!(seen, all[..k]);
        }
    }

    /// `first_hit` finds the nearest polygon a brute-force loop finds (smallest t, ties to the
    /// smaller index), skipping the one it is told to, on segments that cross the staggered
    /// grid obliquely (so several polygons lie on most of them).
    #[test]
    fn first_hit_matches_brute_force() {
        let polys = grid(12);
        let bvh = Bvh::build(&polys);
        let mut rng = base::rng::Rng::new(11);
        let mut found = 0;
        for k in 0..3000 {
            let a = DVec3::new(rng.next_f64() * 13.0, rng.next_f64() * 13.0, -1.0);
            let b = DVec3::new(rng.next_f64() * 13.0, rng.next_f64() * 13.0, 6.0);
            let skip = (k % 7) as u32 * 20;
            let d = b - a;
            let mut brute: Option<(u32, f64)> = None;
            for (i, p) in polys.iter().enumerate() {
                if i as u32 == skip {
                    continue;
                }
                let c = p.corners;
                let t = [(c[0], c[1], c[2]), (c[0], c[2], c[3])]
                    .iter()
                    .filter_map(|&(p0, p1, p2)| segment_triangle_t(a, d, p0, p1, p2))
                    .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.min(t))));
                if let Some(t) = t {
                    if brute.is_none_or(|(_, bt)| t < bt) {
                        brute = Some((i as u32, t));
                    }
                }
            }
            assert_eq!(bvh.first_hit(a, d, skip), brute, "segment {k}");
            found += usize::from(brute.is_some());
        }
        assert!(found > 1000, "{found}");
    }

    #[test]
    fn segment_ends_and_skips() {
        let polys = grid(1);
        let bvh = Bvh::build(&polys);
        let z = polys[0].corners[0].z;
        let a = DVec3::new(0.4, 0.4, z - 1.0);
        let b = DVec3::new(0.4, 0.4, z + 1.0);
        assert!(bvh.occluded(a, b, u32::MAX, u32::MAX));
        assert!(!bvh.occluded(a, b, 0, u32::MAX));
        // A segment ending on the polygon is not blocked by it.
        assert!(!bvh.occluded(a, DVec3::new(0.4, 0.4, z), u32::MAX, u32::MAX));
        // A segment beside it is not blocked.
        assert!(!bvh.occluded(a + DVec3::X * 2.0, b + DVec3::X * 2.0, u32::MAX, u32::MAX));
    }
}
