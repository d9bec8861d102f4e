//! Contact lines: where one polygon stands on or passes through another (a wall on a floor, a
//! table leg on the floor, a box on a table, two walls crossing), the light of the receiving
//! polygon steps from one side of the line to the other: one side is lit, the other sees the
//! light through the standing polygon or not at all. Such a line is a discontinuity of the
//! radiosity itself (D0, in the terms of Heckbert 1992 and Lischinski, Tampieri and Greenberg
//! 1992), which no smooth reconstruction over the polygon can follow: a C1 patch that spans it
//! carries the lit side's light under the wall.
//!
//! So the loader cuts the receiving polygon along every contact line, as Baum, Mann, Smith and
//! Winget (1991) split polygons at their intersections: each side becomes polygons of its own,
//! solved, reconstructed, textured, meshed and exported from its own samples, and every method
//! honours the line because no patch, texel or triangle of one side reaches the other. The
//! pieces of one polygon meet along the rest of the cut lines (their extensions, and the
//! diagonals that make the pieces triangles and quads), where the light is continuous; those
//! edges are whole shared edges of coplanar polygons of one material, which the reconstruction
//! joins into one C1 function (`reconstruction::seam`). Along the lines themselves it leaves
//! them apart: a polygon stands there, or the line is in [`Cuts::lines`].
//!
//! How: for every polygon P, the polygons whose boxes meet P's are tested; one that reaches
//! P's front side and meets P's plane (a side standing on it, or a face crossing it) meets it
//! along a segment, which is clipped to P. Segments on P's border (a wall meeting a floor at the
//! floor's edge) cut nothing. Each distinct line through a segment then cuts P, and every piece
//! of P it crosses, along its whole length inside P (an arrangement of lines): two pieces side
//! by side always share whole edges, never a T-junction. Pieces with more than four corners
//! are cut into quads (and a triangle) along diagonals.
//!
//! A polygon lying close over another without touching it (a lamp hung a centimetre under the
//! ceiling, a picture on a wall, a rug on a floor) makes the same kind of step: the receiver
//! under it sees almost nothing, the receiver beside it sees the room, and the light between
//! the two changes within a few gaps' width of the outline. A smooth patch or a texel across
//! that outline blends the two sides (a bright ring of the hidden ceiling drawn beside a lamp).
//! So a polygon nearly parallel to a receiver and in front of it, by at most [`OUTLINE_GAP`] of
//! its half-width, cuts the receiver along its outline projected onto the receiver's plane, as
//! a contact line does ([`LineKind::Outline`]; a lamp modelled as a fan of triangles counts as
//! one polygon, module `outline`). Farther away the step widens into a penumbra the quadtree
//! follows by refinement.
//!
//! Invariants: the cut depends only on the polygons (candidates are sorted, lines are applied
//! in a fixed order), so the scene is the same for any thread count; every piece is planar
//! (its corners lie in P's plane), convex, and wound like P; the pieces tile P. A vertex within
//! [`SNAP`] of P's size from a cut line counts as on it, so no piece is a sliver thinner than
//! that.

use glam::{DVec2, DVec3};

use crate::bvh::{Aabb, Bvh};
use crate::coincident::{diameter, Stacking};
use crate::Polygon;

/// Points within this fraction of a polygon's size of its plane lie on it (the tolerance of
/// [`crate::adjacency::EDGE_TOL`]: far above the rounding of modelled coordinates, far below
/// any gap a viewer could see).
pub const PLANE_TOL: f64 = 1e-6;

/// A cut line passing within this fraction of the polygon's size of a corner of a piece passes
/// through it: no piece is thinner than this.
pub const SNAP: f64 = 1e-4;

/// Most distinct cut lines one polygon takes (its pieces grow with their square); a polygon
/// touched along more lines is cut along the longest of them and the rest are counted in
/// [`Cuts::skipped`].
pub const MAX_LINES: usize = 48;

pub use outline::{OUTLINE_GAP, OUTLINE_OVER};

/// Why a line cuts its receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LineKind {
    /// A polygon stands on the receiver or passes through it.
    Contact,
    /// A polygon lies close over the receiver ([`OUTLINE_GAP`]); the line is a side of its
    /// outline projected onto the receiver, and `gap` that side's mean distance from the
    /// receiver's plane: the width over which the light beside the line changes.
    Outline {
        /// See the variant.
        gap: f64,
    },
    /// A corner of a coplanar neighbour meets the receiver's side inside it (a T-junction,
    /// `crate::junctions`).
    Junction,
}

/// One contact line: where polygon `by` touches or crosses polygon `receiver` (indices of the
/// polygons before cutting), from `a` to `b`, inside the receiver.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactLine {
    /// The polygon whose light steps along the line.
    pub receiver: u32,
    /// The polygon standing on it or passing through it; for an outline, the polygon whose
    /// side it is.
    pub by: u32,
    /// The segment's ends.
    pub a: DVec3,
    /// See `a`.
    pub b: DVec3,
    /// Why it cuts.
    pub kind: LineKind,
}

/// What cutting along the contact lines did to a scene.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cuts {
    /// Every contact line found, by receiver then `by` (polygon indices before cutting).
    pub lines: Vec<ContactLine>,
    /// Per polygon cut (index before cutting): the number of pieces it became.
    pub pieces: Vec<(u32, u32)>,
    /// Contact lines not cut along (a polygon touched along more than [`MAX_LINES`] lines).
    pub skipped: usize,
    /// Per polygon cut (aligned with `pieces`, filled by `Scene::cut_contacts`): where it was
    /// written, for reports; kept here because later cuts move the pieces' indices.
    pub places: Vec<String>,
}

impl Cuts {
    /// Total length of the contact lines.
    pub fn length(&self) -> f64 {
        self.lines.iter().map(|l| (l.b - l.a).length()).sum()
    }

    /// How many lines are the outlines of polygons lying close over their receivers.
    pub fn outlines(&self) -> usize {
        self.lines
            .iter()
            .filter(|l| matches!(l.kind, LineKind::Outline { .. }))
            .count()
    }

    /// Polygons cut, and the pieces they became.
    pub fn counts(&self) -> (usize, usize) {
        let pieces = self.pieces.iter().map(|(_, n)| *n as usize).sum();
        (self.pieces.len(), pieces)
    }

    /// The note a load that cut along contact lines gives (`None` if it cut nothing).
    pub fn note(&self) -> Option<String> {
        let (cut, pieces) = self.counts();
        if cut == 0 {
            return None;
        }
        let skipped = if self.skipped > 0 {
            format!(
                "; {} more lines not cut along (more than {MAX_LINES} on one polygon)",
                self.skipped
            )
        } else {
            String::new()
        };
        let outlines = self.outlines();
        let outlines = if outlines > 0 {
            format!(
                ", {outlines} of them sides of polygons lying close over another, as a lamp \
                 under a ceiling"
            )
        } else {
            String::new()
        };
        Some(format!(
            "{} contact lines (where a polygon stands on or passes through another{outlines}, \
             {:.3} long in all) cut {cut} polygons into {pieces} pieces, so that no patch, \
             texel or triangle carries light across them{skipped} (radiosity.cut_contacts = \
             false keeps them whole)",
            self.lines.len(),
            self.length()
        ))
    }
}

/// Every contact line of `polygons` (see the module docs), ordered by receiver, then `by`;
/// `stacking` says which of two polygons overlapping in one plane lies on top.
pub(crate) fn find(polygons: &[Polygon], stacking: &Stacking) -> Vec<ContactLine> {
    let bvh = Bvh::build(polygons);
    let mut lines = Vec::new();
    for (pi, p) in polygons.iter().enumerate() {
        let tol = PLANE_TOL * diameter(p);
        let b = Aabb::of(p.vertices());
        let b = Aabb {
            lo: b.lo - DVec3::splat(tol),
            hi: b.hi + DVec3::splat(tol),
        };
        let mut near = Vec::new();
        bvh.for_each_overlapping(&b, |q| {
            if q as usize != pi {
                near.push(q);
            }
        });
        near.sort_unstable();
        for q in near {
            let qp = &polygons[q as usize];
            let tol = PLANE_TOL * diameter(p).max(diameter(qp));
            if let Some((a, b)) = contact(p, qp, tol) {
                lines.push(ContactLine {
                    receiver: pi as u32,
                    by: q,
                    a,
                    b,
                    kind: LineKind::Contact,
                });
            }
        }
    }
    outline::outlines(polygons, &bvh, stacking, &mut lines);
    // Stable: a pair's contact lines stay ahead of its outline's.
    lines.sort_by_key(|l| (l.receiver, l.by));
    lines
}

/// The segment along which `q` meets `p`'s plane inside `p`, if `q` reaches `p`'s front there
/// and the segment is longer than `tol` and not on `p`'s border.
fn contact(p: &Polygon, q: &Polygon, tol: f64) -> Option<(DVec3, DVec3)> {
    let n = p.normal;
    let p0 = p.corners[0];
    let d: Vec<f64> = q.vertices().iter().map(|v| n.dot(*v - p0)).collect();
    // Only a polygon reaching p's front can change p's light; one in p's plane is a coplanar
    // neighbour or an overlap, for other checks.
    if d.iter().all(|&x| x <= tol) {
        return None;
    }
    let dir = n.cross(q.normal);
    if dir.length() <= 1e-9 {
        return None;
    }
    let dir = dir.normalize();
    let qv = q.vertices();
    let mut pts: Vec<DVec3> = Vec::new();
    for i in 0..qv.len() {
        let (a, b) = (qv[i], qv[(i + 1) % qv.len()]);
        let (da, db) = (d[i], d[(i + 1) % qv.len()]);
        if da.abs() <= tol {
            pts.push(a - n * da);
        }
        if (da > tol && db < -tol) || (da < -tol && db > tol) {
            pts.push(a + (b - a) * (da / (da - db)));
        }
    }
    if pts.len() < 2 {
        return None;
    }
    let t = |x: &DVec3| dir.dot(*x);
    let lo = pts.iter().copied().min_by(|a, b| t(a).total_cmp(&t(b)))?;
    let hi = pts.iter().copied().max_by(|a, b| t(a).total_cmp(&t(b)))?;
    let (a, b) = clip_to_polygon(p, lo, hi, tol)?;
    if (b - a).length() <= tol || on_border(p, a, b, tol) {
        return None;
    }
    Some((a, b))
}

/// The part of segment `a`-`b` (in `p`'s plane) inside `p`, if longer than `tol`.
pub(crate) fn clip_to_polygon(p: &Polygon, a: DVec3, b: DVec3, tol: f64) -> Option<(DVec3, DVec3)> {
    let vs = p.vertices();
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    let d = b - a;
    for i in 0..vs.len() {
        let (e0, e1) = (vs[i], vs[(i + 1) % vs.len()]);
        // Inward normal of the edge in p's plane.
        let m = p.normal.cross(e1 - e0).normalize();
        let (fa, fd) = (m.dot(a - e0) + tol, m.dot(d));
        if fd.abs() <= f64::MIN_POSITIVE {
            if fa < 0.0 {
                return None;
            }
            continue;
        }
        let t = -fa / fd;
        if fd > 0.0 {
            t0 = t0.max(t);
        } else {
            t1 = t1.min(t);
        }
    }
    if t1 - t0 <= 0.0 {
        return None;
    }
    let (ca, cb) = (a + d * t0, a + d * t1);
    ((cb - ca).length() > tol).then_some((ca, cb))
}

/// Whether segment `a`-`b` lies along one of `p`'s sides (within `tol`).
pub(crate) fn on_border(p: &Polygon, a: DVec3, b: DVec3, tol: f64) -> bool {
    let vs = p.vertices();
    (0..vs.len()).any(|i| {
        let (e0, e1) = (vs[i], vs[(i + 1) % vs.len()]);
        let e = (e1 - e0).normalize();
        let off = |x: DVec3| (x - e0 - e * e.dot(x - e0)).length();
        off(a) <= tol && off(b) <= tol
    })
}

/// `polygons` with every polygon that has contact lines (`lines`, from the crate's `find` on
/// the same polygons) replaced, in place, by its pieces; `origins` (one per polygon, or empty)
/// kept aligned. What was cut.
pub fn cut<T: Clone>(
    polygons: &mut Vec<Polygon>,
    origins: &mut Vec<T>,
    lines: Vec<ContactLine>,
) -> Cuts {
    let mut cuts = Cuts {
        lines,
        ..Cuts::default()
    };
    if cuts.lines.is_empty() {
        return cuts;
    }
    let old = std::mem::take(polygons);
    let old_origins = std::mem::take(origins);
    let mut k = 0;
    for (i, p) in old.into_iter().enumerate() {
        let start = k;
        while k < cuts.lines.len() && cuts.lines[k].receiver as usize == i {
            k += 1;
        }
        let mine = &cuts.lines[start..k];
        let pieces = if mine.is_empty() {
            vec![p]
        } else {
            let (pieces, skipped) = pieces(&p, mine);
            cuts.skipped += skipped;
            if pieces.len() > 1 {
                cuts.pieces.push((i as u32, pieces.len() as u32));
            }
            pieces
        };
        for piece in pieces {
            if let Some(o) = old_origins.get(i) {
                origins.push(o.clone());
            }
            polygons.push(piece);
        }
    }
    cuts
}

/// `p`'s plane as 2-D coordinates: origin `c0`, `e1` along its first side, `e2 = n x e1` (so
/// `p`, counter-clockwise seen from its front, is counter-clockwise in 2-D).
pub(crate) struct Frame {
    o: DVec3,
    e1: DVec3,
    e2: DVec3,
}

impl Frame {
    pub(crate) fn of(p: &Polygon) -> Frame {
        let o = p.corners[0];
        let e1 = (p.corners[1] - o).normalize();
        Frame {
            o,
            e1,
            e2: p.normal.cross(e1),
        }
    }

    pub(crate) fn to2(&self, x: DVec3) -> DVec2 {
        DVec2::new((x - self.o).dot(self.e1), (x - self.o).dot(self.e2))
    }
}

/// A corner of a piece: where it lies in the polygon's plane, and in space.
#[derive(Debug, Clone, Copy)]
struct Corner {
    at: DVec2,
    pos: DVec3,
}

/// The pieces of `p` cut along the lines through `lines` (at most [`MAX_LINES`] distinct
/// lines, the longest segments first), as triangles and quads; and how many segments were not
/// cut along.
fn pieces(p: &Polygon, lines: &[ContactLine]) -> (Vec<Polygon>, usize) {
    let frame = Frame::of(p);
    let size = diameter(p);
    let snap = SNAP * size;
    let mut order: Vec<&ContactLine> = lines.iter().collect();
    order.sort_by(|a, b| (b.b - b.a).length().total_cmp(&(a.b - a.a).length()));
    let mut cut_lines: Vec<(DVec2, DVec2)> = Vec::new();
    let mut skipped = 0;
    let add = |a: DVec2, dir: DVec2, cut_lines: &mut Vec<(DVec2, DVec2)>| {
        let same = |(c, d): &(DVec2, DVec2)| {
            d.perp_dot(dir).abs() * size <= snap && d.perp_dot(a - *c).abs() <= snap
        };
        if cut_lines.iter().any(same) {
            return true;
        }
        if cut_lines.len() == MAX_LINES {
            return false;
        }
        cut_lines.push((a, dir));
        true
    };
    let outline: Vec<DVec2> = p.vertices().iter().map(|v| frame.to2(*v)).collect();
    let segments: Vec<(DVec2, DVec2)> = lines
        .iter()
        .map(|l| (frame.to2(l.a), frame.to2(l.b)))
        .collect();
    // An end of a segment that a segment across it passes through (a corner of a box's
    // footprint) needs no cut across it: that segment's line is one. (A thin wall's two faces
    // give one segment twice, along one line: neither ends the other.)
    let free = |x: DVec2, dir: DVec2| {
        !segments.iter().any(|&(c, d)| {
            let across = (d - c).normalize_or_zero().perp_dot(dir).abs() * size > snap;
            across && distance_to_segment(x, c, d) <= snap
        })
    };
    for l in order {
        let (a, b) = (frame.to2(l.a), frame.to2(l.b));
        let dir = (b - a).normalize();
        let mut ok = add(a, dir, &mut cut_lines);
        // Where the segment ends inside the polygon, a cut across it there too: the piece
        // edges along the line then lie wholly under the standing polygon or wholly off it, so
        // the parts of the line it does not stand on can be joined (a box's sides end where
        // the next side's line already passes).
        for end in [a, b] {
            if inside(&outline, end, snap) && free(end, dir) {
                ok &= add(end, dir.perp(), &mut cut_lines);
            }
        }
        if !ok {
            skipped += 1;
        }
    }
    // Each corner carries its 3-D position, interpolated along the 3-D side it splits: the
    // polygon's own corners stay bit for bit, and a cut's end on a side lies on that side to
    // rounding, at any scale (a round trip through the plane's frame would move every corner
    // by a few ulps, differently at another scale of the same scene).
    let mut faces: Vec<Vec<Corner>> = vec![p
        .vertices()
        .iter()
        .map(|&v| Corner {
            at: frame.to2(v),
            pos: v,
        })
        .collect()];
    for (a, dir) in &cut_lines {
        let mut next = Vec::with_capacity(faces.len() + 1);
        for f in faces {
            let (l, r) = split(&f, *a, *dir, snap);
            next.extend([l, r].into_iter().filter(|x| x.len() >= 3));
        }
        faces = next;
    }
    let u_axis = frame.to2(p.corners[1]) - frame.to2(p.corners[0]);
    let out = faces
        .iter()
        .flat_map(|f| convex_to_polygons(f, u_axis))
        .filter_map(|c| {
            let c3: Vec<DVec3> = c.iter().map(|x| x.pos).collect();
            match c3.len() {
                3 => Polygon::triangle([c3[0], c3[1], c3[2]], p.material, p.object),
                _ => Polygon::quad([c3[0], c3[1], c3[2], c3[3]], p.material, p.object),
            }
            .map(|q| q.with_shading(p.shading.clone()))
        })
        .collect();
    (out, skipped)
}

/// The distance from `x` to the segment `a`-`b`.
fn distance_to_segment(x: DVec2, a: DVec2, b: DVec2) -> f64 {
    let d = b - a;
    let t = ((x - a).dot(d) / d.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
    (a + d * t - x).length()
}

/// Whether `x` lies inside the counter-clockwise convex polygon `f` by more than `margin`.
fn inside(f: &[DVec2], x: DVec2, margin: f64) -> bool {
    (0..f.len()).all(|i| {
        let (a, b) = (f[i], f[(i + 1) % f.len()]);
        (b - a).normalize().perp_dot(x - a) > margin
    })
}

/// The parts of the convex polygon `f` left and right of the line through `a` along `dir`;
/// corners within `snap` of the line lie on it (both parts take them). A part that would hold
/// only corners on the line is empty.
fn split(f: &[Corner], a: DVec2, dir: DVec2, snap: f64) -> (Vec<Corner>, Vec<Corner>) {
    let s: Vec<f64> = f
        .iter()
        .map(|x| {
            let d = dir.perp_dot(x.at - a);
            if d.abs() <= snap {
                0.0
            } else {
                d
            }
        })
        .collect();
    if s.iter().all(|&x| x >= 0.0) || s.iter().all(|&x| x <= 0.0) {
        return (f.to_vec(), Vec::new());
    }
    let (mut l, mut r) = (Vec::new(), Vec::new());
    for i in 0..f.len() {
        let j = (i + 1) % f.len();
        if s[i] >= 0.0 {
            l.push(f[i]);
        }
        if s[i] <= 0.0 {
            r.push(f[i]);
        }
        if (s[i] > 0.0 && s[j] < 0.0) || (s[i] < 0.0 && s[j] > 0.0) {
            let t = s[i] / (s[i] - s[j]);
            let x = Corner {
                at: f[i].at + (f[j].at - f[i].at) * t,
                pos: f[i].pos + (f[j].pos - f[i].pos) * t,
            };
            l.push(x);
            r.push(x);
        }
    }
    (l, r)
}

/// A convex polygon as quads (and one triangle for an odd count) along diagonals from one
/// corner, each starting at the corner whose first side runs most nearly along `u_axis` (so
/// the pieces' parameter axes follow the polygon they came from, as far as their shapes
/// allow).
fn convex_to_polygons(f: &[Corner], u_axis: DVec2) -> Vec<Vec<Corner>> {
    let mut out = Vec::new();
    let n = f.len();
    if n <= 4 {
        out.push(f.to_vec());
    } else {
        let mut k = 0;
        while k + 3 < n {
            out.push(vec![f[0], f[k + 1], f[k + 2], f[k + 3]]);
            k += 2;
        }
        if k + 2 < n {
            out.push(vec![f[0], f[k + 1], f[k + 2]]);
        }
    }
    out.into_iter().map(|c| aligned(c, u_axis)).collect()
}

/// `c` rotated (same cycle, same winding) to start at the corner whose side to the next runs
/// most nearly along `u_axis`; a triangle keeps its corners distinct.
fn aligned(c: Vec<Corner>, u_axis: DVec2) -> Vec<Corner> {
    let n = c.len();
    let u = u_axis.normalize_or_zero();
    let score = |i: usize| (c[(i + 1) % n].at - c[i].at).normalize_or_zero().dot(u);
    let best = (0..n)
        .max_by(|&a, &b| score(a).total_cmp(&score(b)).then(b.cmp(&a)))
        .unwrap_or(0);
    (0..n).map(|i| c[(best + i) % n]).collect()
}

mod outline;

#[cfg(test)]
mod tests;
