//! Coincident polygons: a surface listed twice is counted once, surfaces that overlap in one
//! plane are named, and [`Stacking`] says which of them lies on top.
//!
//! A polygon reflects and receives on its front side, so two copies of one wall reflect its
//! light twice: measured against a path tracer, a wall listed twice put x2.05 of its light on
//! the floor, and real assets carry such copies (the public Cornell box OBJ repeats two faces).
//! The loader therefore drops a polygon whose corners repeat an earlier polygon's (the same
//! cycle of corners, the same facing, each corner within [`SAME_POINT`] of the polygon's size)
//! with a warning naming both lines, and warns (keeping both) about polygons that lie in one
//! plane, face the same way and overlap by more than [`OVERLAP_WARN`] of the smaller one's
//! area. Left as they are, both would take and reflect the light of the overlap (a lamp
//! snapped onto a ceiling's plane: 19.5 % of its light created in a test room, and drawn as the
//! ceiling wherever the depth tie went to it), so one of them is taken to lie on top
//! ([`Stacking`]): the contact pass cuts the other along its outline and the piece under it is
//! buried (module `seal`), as under a face a hair in front of it.
//!
//! Invariants: the first polygon of a group of copies is kept, so polygon order, materials and
//! objects of the rest are unchanged; the result depends only on the polygons (candidates come
//! from a BVH box query, visited in index order); back-to-back polygons (a thin wall's two
//! sides) are never merged: they face opposite ways.

use glam::{DVec2, DVec3};

use crate::bvh::{Aabb, Bvh};
use crate::{Material, Polygon};
use base::error::Location;

/// Which of two polygons overlapping in one plane and facing one way lies on top: what a
/// modeller means by such data. An emitter lies over a surface that does not emit (a light
/// panel snapped onto a ceiling); else the polygon of the smaller object (its polygons' total
/// area: a rug over a floor, a poster over a wall); else the polygon listed later (drawn last,
/// as in a drawing program). The order survives the loader's cuts: pieces keep their object and
/// material, an object's area is compared to a relative [`SAME_AREA`], and cut pieces keep
/// their place in the list.
#[derive(Debug, Clone, Default)]
pub(crate) struct Stacking {
    /// Per polygon: whether it emits, and its object's area.
    key: Vec<(bool, f64)>,
}

/// Objects whose areas agree to this share are the same size to [`Stacking`] (cutting an
/// object into pieces changes the sum of its areas by rounding).
pub(crate) const SAME_AREA: f64 = 1e-9;

impl Stacking {
    /// The stacking order of `polygons`, whose materials are `materials`.
    pub(crate) fn of(polygons: &[Polygon], materials: &[Material]) -> Stacking {
        let objects = polygons.iter().map(|p| p.object as usize + 1).max();
        let mut area = vec![0.0; objects.unwrap_or(0)];
        for p in polygons {
            area[p.object as usize] += p.area;
        }
        let emits = |p: &Polygon| {
            materials
                .get(p.material as usize)
                .is_some_and(Material::is_emitter)
        };
        Stacking {
            key: polygons
                .iter()
                .map(|p| (emits(p), area[p.object as usize]))
                .collect(),
        }
    }

    /// Whether polygon `q` lies over polygon `p` where they overlap in one plane (false for
    /// polygons this order was not made for).
    pub(crate) fn over(&self, q: usize, p: usize) -> bool {
        let (Some(&(eq, aq)), Some(&(ep, ap))) = (self.key.get(q), self.key.get(p)) else {
            return false;
        };
        if eq != ep {
            return eq;
        }
        if (aq - ap).abs() > SAME_AREA * aq.max(ap) {
            return aq < ap;
        }
        q > p
    }
}

/// Corners closer than this fraction of the polygon's diameter are the same point.
pub(crate) const SAME_POINT: f64 = 1e-6;

/// Coplanar, same-facing polygons overlapping by more than this fraction of the smaller one's
/// area are reported. Neighbours that share an edge overlap by rounding only (~1e-12).
pub(crate) const OVERLAP_WARN: f64 = 1e-4;

/// Drops every polygon that repeats an earlier one (keeping `origins` aligned) and returns the
/// messages as (notes, warnings): a note per polygon dropped that repeats one of its material (a
/// repair that changes nothing the image shows), a warning per polygon dropped that repeats one
/// of another material and per overlapping pair kept.
pub(crate) fn merge(
    polygons: &mut Vec<Polygon>,
    origins: &mut Vec<Location>,
) -> (Vec<String>, Vec<String>) {
    let bvh = Bvh::build(polygons);
    let mut dropped = vec![false; polygons.len()];
    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    for j in 0..polygons.len() {
        let pj = &polygons[j];
        let tol = SAME_POINT * diameter(pj);
        let b = Aabb::of(pj.vertices());
        let b = Aabb {
            lo: b.lo - DVec3::splat(tol),
            hi: b.hi + DVec3::splat(tol),
        };
        let mut earlier = Vec::new();
        bvh.for_each_overlapping(&b, |i| {
            if (i as usize) < j && !dropped[i as usize] {
                earlier.push(i as usize);
            }
        });
        earlier.sort_unstable();
        for i in earlier {
            let pi = &polygons[i];
            if same_corners(pi, pj, tol) {
                dropped[j] = true;
                let same = pi.material == pj.material;
                let material = if same {
                    ""
                } else {
                    ", with another material: the first one's is kept"
                };
                let to = if same { &mut notes } else { &mut warnings };
                to.push(format!(
                    "{}: this polygon repeats the one at {} (same corners, same side{material}): \
                     counted once (a surface listed twice would reflect its light twice)",
                    origins[j], origins[i]
                ));
                break;
            }
            if let Some(f) = coplanar_overlap(pi, pj) {
                warnings.push(format!(
                    "{}: this polygon overlaps the one at {} in the same plane, facing the \
                     same way ({:.1} % of the smaller one's area): where they overlap, one is \
                     taken to lie on top (an emitter over a surface, else the smaller object, \
                     else the one listed later) and the part of the other under it is hidden; \
                     move or remove one of them if another is meant",
                    origins[j],
                    origins[i],
                    100.0 * f
                ));
            }
        }
    }
    let mut k = 0;
    polygons.retain(|_| {
        k += 1;
        !dropped[k - 1]
    });
    let mut k = 0;
    origins.retain(|_| {
        k += 1;
        !dropped[k - 1]
    });
    (notes, warnings)
}

/// The share of the largest coordinate below which a height over a plane counts as on it when
/// telling whether a face lies in front: a few ulps, what rounding alone can make of a gap.
pub(crate) const ROUNDING: f64 = 1e-12;

/// [`ROUNDING`] of the largest coordinate of `pts`.
pub(crate) fn rounding_tolerance(pts: impl Iterator<Item = DVec3>) -> f64 {
    ROUNDING
        * pts
            .map(|p| p.abs().max_element())
            .fold(f64::MIN_POSITIVE, f64::max)
}

/// Largest distance between two corners of `p`.
pub(crate) fn diameter(p: &Polygon) -> f64 {
    let vs = p.vertices();
    let mut d = 0.0f64;
    for a in vs {
        for b in vs {
            d = d.max((*a - *b).length());
        }
    }
    d
}

/// Whether `a` and `b` have the same corners in the same cyclic order (so the same facing),
/// each pair within `tol`.
fn same_corners(a: &Polygon, b: &Polygon, tol: f64) -> bool {
    let (va, vb) = (a.vertices(), b.vertices());
    if va.len() != vb.len() || a.normal.dot(b.normal) <= 0.0 {
        return false;
    }
    let n = va.len();
    (0..n).any(|shift| (0..n).all(|k| (va[k] - vb[(k + shift) % n]).length() <= tol))
}

/// The area both polygons cover over the smaller one's area, if they lie in one plane, face
/// the same way and that fraction passes [`OVERLAP_WARN`].
fn coplanar_overlap(a: &Polygon, b: &Polygon) -> Option<f64> {
    // The smaller polygon's size sets the tolerance: a floor 1 unit above a 1e6-wide ground
    // plane is 1e-6 of the ground's size away but a whole floor's width, not in its plane.
    let tol = SAME_POINT * diameter(a).min(diameter(b));
    if a.normal.dot(b.normal) < 1.0 - 1e-9 {
        return None;
    }
    let off_plane = |p: &Polygon, q: &Polygon| {
        q.vertices()
            .iter()
            .any(|&v| p.normal.dot(v - p.corners[0]).abs() > tol)
    };
    if off_plane(a, b) || off_plane(b, a) {
        return None;
    }
    // One in front of the other by more than rounding lies over it: the contact cut and the
    // seal (module `seal`) give the surface under it a piece of its own that sees only it.
    let tiny = rounding_tolerance(a.vertices().iter().chain(b.vertices()).copied());
    let in_front = |p: &Polygon, q: &Polygon| {
        q.vertices()
            .iter()
            .all(|&v| p.normal.dot(v - p.corners[0]) > tiny)
    };
    if in_front(a, b) || in_front(b, a) {
        return None;
    }
    let n = a.normal;
    let o = a.corners[0];
    // A frame in the plane; both outlines are counter-clockwise in it (same facing).
    let e1 = (a.corners[1] - a.corners[0]).normalize();
    let e2 = n.cross(e1);
    let flat = |p: &Polygon| -> Vec<DVec2> {
        p.vertices()
            .iter()
            .map(|&q| DVec2::new(e1.dot(q - o), e2.dot(q - o)))
            .collect()
    };
    let common = area(&clip(&flat(a), &flat(b)));
    let f = common / a.area.min(b.area);
    (f > OVERLAP_WARN).then_some(f)
}

/// `subject` clipped to the convex, counter-clockwise `window` (Sutherland-Hodgman).
pub(crate) fn clip(subject: &[DVec2], window: &[DVec2]) -> Vec<DVec2> {
    let mut out = subject.to_vec();
    for i in 0..window.len() {
        let (p, q) = (window[i], window[(i + 1) % window.len()]);
        let e = q - p;
        let side = |x: DVec2| e.perp_dot(x - p);
        let input = std::mem::take(&mut out);
        for k in 0..input.len() {
            let (s, t) = (input[k], input[(k + 1) % input.len()]);
            let (ds, dt) = (side(s), side(t));
            if ds >= 0.0 {
                out.push(s);
            }
            if (ds >= 0.0) != (dt >= 0.0) {
                out.push(s + (t - s) * (ds / (ds - dt)));
            }
        }
        if out.is_empty() {
            break;
        }
    }
    out
}

/// The area of the polygon `f`, wound either way (0 for fewer than three corners).
pub(crate) fn area_abs(f: &[DVec2]) -> f64 {
    if f.len() < 3 {
        return 0.0;
    }
    0.5 * (0..f.len())
        .map(|i| f[i].perp_dot(f[(i + 1) % f.len()]))
        .sum::<f64>()
        .abs()
}

/// Area of a simple polygon (shoelace; positive counter-clockwise).
fn area(p: &[DVec2]) -> f64 {
    let mut s = 0.0;
    for i in 0..p.len() {
        s += p[i].perp_dot(p[(i + 1) % p.len()]);
    }
    0.5 * s.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(c: [[f64; 3]; 4]) -> Polygon {
        Polygon::quad(c.map(DVec3::from), 0, 0).unwrap()
    }

    fn origins(n: usize) -> Vec<Location> {
        (1..=n)
            .map(|l| Location::file("s.obj").at_line(l))
            .collect()
    }

    const FLOOR: [[f64; 3]; 4] = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];

    #[test]
    fn a_repeated_polygon_is_kept_once_whatever_its_first_corner() {
        let shifted = [FLOOR[2], FLOOR[3], FLOOR[0], FLOOR[1]];
        let other = [
            [3.0, 0.0, 0.0],
            [4.0, 0.0, 0.0],
            [4.0, 1.0, 0.0],
            [3.0, 1.0, 0.0],
        ];
        let mut ps = vec![quad(FLOOR), quad(other), quad(shifted)];
        let mut o = origins(3);
        let (w, warnings) = merge(&mut ps, &mut o);
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(ps.len(), 2);
        assert_eq!(o.len(), 2);
        assert_eq!(
            o[1].line,
            Some(2),
            "the first copy and the other polygon stay"
        );
        assert_eq!(w.len(), 1);
        assert!(
            w[0].starts_with("s.obj:3: this polygon repeats the one at s.obj:1"),
            "{w:?}"
        );
    }

    #[test]
    fn back_to_back_polygons_are_two_surfaces() {
        let back = [FLOOR[0], FLOOR[3], FLOOR[2], FLOOR[1]];
        let mut ps = vec![quad(FLOOR), quad(back)];
        let w = merge(&mut ps, &mut origins(2));
        assert_eq!(ps.len(), 2);
        assert!(w.0.is_empty() && w.1.is_empty(), "{w:?}");
    }

    #[test]
    fn neighbours_sharing_an_edge_are_not_overlaps() {
        let next = [
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [2.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
        ];
        let mut ps = vec![quad(FLOOR), quad(next)];
        let w = merge(&mut ps, &mut origins(2));
        assert!(w.0.is_empty() && w.1.is_empty(), "{w:?}");
    }

    #[test]
    fn a_coplanar_overlap_is_reported_with_its_share() {
        // The second square covers the right half of the first: 50 % of either.
        let half = [
            [0.5, 0.0, 0.0],
            [1.5, 0.0, 0.0],
            [1.5, 1.0, 0.0],
            [0.5, 1.0, 0.0],
        ];
        let mut ps = vec![quad(FLOOR), quad(half)];
        let (notes, w) = merge(&mut ps, &mut origins(2));
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(ps.len(), 2);
        assert_eq!(w.len(), 1);
        assert!(
            w[0].contains("overlaps the one at s.obj:1") && w[0].contains("(50.0 %"),
            "{w:?}"
        );
    }

    /// What broke: a floor 1 unit above a ground plane 2e6 wide was reported as overlapping
    /// it "in the same plane" (the tolerance followed the larger polygon's size).
    #[test]
    fn a_huge_plane_a_floor_width_away_is_not_the_floors_plane() {
        let g = 1e6;
        let ground = [[-g, -1.0, g], [g, -1.0, g], [g, -1.0, -g], [-g, -1.0, -g]];
        let floor = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, -1.0],
            [0.0, 0.0, -1.0],
        ];
        for pair in [[ground, floor], [floor, ground]] {
            let mut ps = vec![quad(pair[0]), quad(pair[1])];
            let w = merge(&mut ps, &mut origins(2));
            assert!(w.0.is_empty() && w.1.is_empty(), "{w:?}");
        }
        // In its plane, the floor is reported, whichever comes first.
        let lowered = floor.map(|[x, _, z]| [x, -1.0, z]);
        let mut ps = vec![quad(ground), quad(lowered)];
        assert_eq!(merge(&mut ps, &mut origins(2)).1.len(), 1);
    }

    #[test]
    fn corners_within_the_tolerance_are_the_same_point() {
        let nudged = FLOOR.map(|c| [c[0] + 1e-9, c[1] - 1e-9, c[2]]);
        let mut ps = vec![quad(FLOOR), quad(nudged)];
        merge(&mut ps, &mut origins(2));
        assert_eq!(ps.len(), 1);
        let moved = FLOOR.map(|c| [c[0] + 1e-3, c[1], c[2]]);
        let mut ps = vec![quad(FLOOR), quad(moved)];
        let w = merge(&mut ps, &mut origins(2));
        assert_eq!(
            ps.len(),
            2,
            "1e-3 of the size apart: an overlap, not a copy"
        );
        assert_eq!(w.1.len(), 1);
    }
}
