//! T-junctions whose lattices do not line up, cut through so that neighbours share whole sides.
//!
//! Every polygon's radiosity lives on a dyadic lattice over its (u, v) square (the quadtree's
//! corners, `base::quadtree::LATTICE`), and the reconstruction joins two coplanar neighbours
//! of one material into one C1 function only where their lattices line up along the shared
//! segment ([`crate::adjacency::SharedEdge::lattice_link`]): its ends lattice points of both
//! sides, one side's step a power of two times the other's. A square standing on a third of a
//! strip's side (an L whose shared edge is split 1/3 : 2/3), or a wall cut at a door a third of
//! the way along, does not line up: the two sides keep their own reconstructions, and the light
//! steps and kinks along the seam.
//!
//! So the loader cuts the longer polygon through each such T-vertex, along the neighbour's side
//! that ends there (the line across the polygon that the neighbour's border continues): the
//! strip becomes a third and two thirds, the square shares the whole of the third's side, and
//! every side along the seam is whole. The cut is the contact lines' (`crate::contact::cut`):
//! a line across the polygon, its pieces convex, planar and wound like it. A cut may leave a new
//! T-vertex where it leaves the polygon on the far side; that one is cut on the next pass, at
//! most [`MAX_PASSES`] passes.
//!
//! A seam that a third polygon stands on (a wall on the line where two floor polygons meet)
//! is not cut for: its two sides keep their own light anyway.
//!
//! Invariants: nothing is cut where the lattices line up (a dyadic split, the usual case of a
//! modelled surface), so a scene without such T-junctions loads as before; the result depends
//! only on the polygons (adjacency is sorted, lines are applied in a fixed order).

use glam::DVec3;

use crate::adjacency::{side_endpoints, Adjacency, SharedEdge, Tracked};
use crate::coincident::diameter;
use crate::contact::{self, ContactLine, Cuts};
use crate::{Material, Polygon};

/// Passes of finding and cutting: each cut may leave one T-vertex on the far side of the polygon
/// it crosses, which the next pass cuts (a staggered course of tiles needs one pass per course
/// it runs through).
pub const MAX_PASSES: usize = 4;

/// A T-vertex closer than this fraction of its side to the side's end is at the end.
const END_TOL: f64 = 1e-6;

/// Cuts every polygon through its T-vertices whose lattices do not line up (see the module
/// docs), keeping `origins` aligned; what was cut, over all passes (polygon indices in it are
/// those before each pass), and the adjacency of the polygons as they are after it (`None`
/// when the last pass cut and no adjacency was found after it).
pub fn cut<T: Clone>(
    polygons: &mut Vec<Polygon>,
    origins: &mut Vec<T>,
    materials: &[Material],
) -> (Cuts, Option<Adjacency>) {
    let mut all = Cuts::default();
    let mut tracked = Tracked::new(polygons);
    let mut adjacency = Adjacency::of(polygons);
    let mut current = true;
    for pass in 0..MAX_PASSES {
        let lines = lines(&adjacency, polygons, materials);
        if lines.is_empty() {
            break;
        }
        let c = contact::cut(polygons, origins, lines);
        if c.pieces.is_empty() {
            // Every line snapped onto a corner (slivers): the next pass would find them again.
            break;
        }
        if pass + 1 < MAX_PASSES {
            // Only the pieces have new neighbours: a million-polygon model's passes cost what
            // its cuts do, not a whole adjacency each.
            adjacency = adjacency.after_cut(polygons, &c.pieces, &mut tracked);
        } else {
            current = false;
        }
        all.lines.extend(c.lines);
        all.pieces.extend(c.pieces);
        all.skipped += c.skipped;
    }
    (all, current.then_some(adjacency))
}

/// The cut lines of one pass: one per T-vertex of an unaligned continuous seam, across the
/// polygon whose side it lies inside, by receiver.
fn lines(adjacency: &Adjacency, polygons: &[Polygon], materials: &[Material]) -> Vec<ContactLine> {
    let stands = adjacency.standing();
    let mut out = Vec::new();
    for (e, &stands) in adjacency.edges.iter().zip(&stands) {
        if e.is_full()
            || stands
            || !Adjacency::continuous(e, polygons, materials)
            || e.lattice_link().is_some()
        {
            continue;
        }
        t_vertex_lines(e, polygons, &mut out);
    }
    out.sort_by(|a, b| {
        (a.receiver, a.by)
            .cmp(&(b.receiver, b.by))
            .then(a.a.to_array().partial_cmp(&b.a.to_array()).unwrap())
    });
    out.dedup_by(|a, b| a.receiver == b.receiver && a.a == b.a && a.b == b.b);
    out
}

/// The cuts through the T-vertices of shared edge `e`: each end of the shared segment inside
/// one polygon's side is a corner of the other polygon, whose side away from the seam there
/// continues across the first.
fn t_vertex_lines(e: &SharedEdge, polygons: &[Polygon], out: &mut Vec<ContactLine>) {
    let sides = [(e.a, e.a_range, e.b), (e.b, e.b_range, e.a)];
    for (side, range, other) in sides {
        let p = &polygons[side.polygon as usize];
        let q = &polygons[other.polygon as usize];
        let (s0, s1) = side_endpoints(p, side.side);
        for s in range {
            if s <= END_TOL || s >= 1.0 - END_TOL {
                continue;
            }
            let x = s0 + (s1 - s0) * s;
            let Some(dir) = side_away(q, x, s1 - s0) else {
                continue;
            };
            let reach = 2.0 * diameter(p);
            let tol = contact::PLANE_TOL * diameter(p);
            if let Some((a, b)) = contact::clip_to_polygon(p, x - dir * reach, x + dir * reach, tol)
            {
                out.push(ContactLine {
                    receiver: side.polygon,
                    by: other.polygon,
                    a,
                    b,
                    kind: contact::LineKind::Junction,
                });
            }
        }
    }
}

/// The unit direction of `q`'s side from its corner at `x` that does not run along `along`
/// (the seam), or `None` if `x` is not a corner of `q`.
fn side_away(q: &Polygon, x: DVec3, along: DVec3) -> Option<DVec3> {
    let vs = q.vertices();
    let tol = 1e-6 * diameter(q);
    let k = (0..vs.len()).find(|&k| vs[k].distance(x) <= tol)?;
    let n = vs.len();
    let along = along.normalize();
    [vs[(k + 1) % n], vs[(k + n - 1) % n]]
        .into_iter()
        .map(|y| (y - vs[k]).normalize())
        .find(|d| d.cross(along).length() > 1e-3)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(c: [[f64; 2]; 4]) -> Polygon {
        let v = |p: [f64; 2]| DVec3::new(p[0], 0.0, -p[1]);
        Polygon::quad([v(c[0]), v(c[1]), v(c[2]), v(c[3])], 0, 0).unwrap()
    }

    fn grey() -> Vec<Material> {
        vec![Material {
            name: "grey".into(),
            reflectance: DVec3::splat(0.5),
            emission: DVec3::ZERO,
        }]
    }

    /// A 3 x 1 strip and a square of side `w` on its top side at its left end.
    fn l_shape(w: f64) -> Vec<Polygon> {
        vec![
            quad([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0], [0.0, 1.0]]),
            quad([[0.0, 1.0], [w, 1.0], [w, 1.0 + w], [0.0, 1.0 + w]]),
        ]
    }

    fn unaligned(polygons: &[Polygon], materials: &[Material]) -> usize {
        Adjacency::of(polygons)
            .edges
            .iter()
            .filter(|e| Adjacency::continuous(e, polygons, materials))
            .filter(|e| e.lattice_link().is_none())
            .count()
    }

    #[test]
    fn a_square_on_a_third_of_a_strip_cuts_the_strip_there() {
        let mut p = l_shape(1.0);
        assert_eq!(unaligned(&p, &grey()), 1);
        let mut origins = vec!["strip", "square"];
        let (cuts, adjacency) = cut(&mut p, &mut origins, &grey());
        assert_eq!(cuts.counts(), (1, 2));
        // The adjacency it ends with is the cut polygons' own.
        assert_eq!(adjacency, Some(Adjacency::of(&p)));
        assert_eq!(p.len(), 3);
        assert_eq!(origins, ["strip", "strip", "square"]);
        assert_eq!(unaligned(&p, &grey()), 0);
        // The strip's pieces: x in [0, 1] and [1, 3], the area kept.
        let area: f64 = p[..2].iter().map(|q| q.area).sum();
        assert!((area - 3.0).abs() < 1e-12);
        let mut widths: Vec<f64> = p[..2].iter().map(|q| q.area).collect();
        widths.sort_by(f64::total_cmp);
        assert!((widths[0] - 1.0).abs() < 1e-12 && (widths[1] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn aligned_t_junctions_and_other_materials_are_left_alone() {
        // A square of side 1.5 on half the strip: its lattice lines up (a step twice the
        // strip's); so does a quarter.
        for w in [1.5, 0.75] {
            let mut p = l_shape(w);
            assert_eq!(unaligned(&p, &grey()), 0, "{w}");
            assert!(cut(&mut p, &mut Vec::<u8>::new(), &grey())
                .0
                .lines
                .is_empty());
            assert_eq!(p.len(), 2);
        }
        // Two materials: the light steps along the seam anyway.
        let mut p = l_shape(1.0);
        p[1].material = 1;
        let mut m = grey();
        m.push(Material {
            name: "red".into(),
            reflectance: DVec3::new(0.6, 0.1, 0.1),
            emission: DVec3::ZERO,
        });
        assert!(cut(&mut p, &mut Vec::<u8>::new(), &m).0.lines.is_empty());
    }

    #[test]
    fn a_cut_that_leaves_a_t_junction_beyond_is_followed() {
        // Two strips one above the other and a square of side 1 on the top one: cutting the
        // top strip at x = 1 leaves a T-vertex on the bottom strip's side, cut on the next pass.
        let mut p = vec![
            quad([[0.0, -1.0], [3.0, -1.0], [3.0, 0.0], [0.0, 0.0]]),
            quad([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0], [0.0, 1.0]]),
            quad([[0.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]]),
        ];
        let (cuts, _) = cut(&mut p, &mut Vec::<u8>::new(), &grey());
        assert_eq!(cuts.lines.len(), 2);
        assert_eq!(p.len(), 5);
        assert_eq!(unaligned(&p, &grey()), 0);
    }

    /// The adjacency carried from pass to pass equals the adjacency found afresh, edge for
    /// edge and in order: on staggered courses of strips (each pass's cut leaves a T-vertex on
    /// the course below, so every pass runs) beside uncut tiles and a far polygon.
    #[test]
    fn the_adjacency_carried_between_passes_is_the_one_found_afresh() {
        let mut p = Vec::new();
        for k in 0..5 {
            let y = -(k as f64);
            p.push(quad([[0.0, y - 1.0], [7.0, y - 1.0], [7.0, y], [0.0, y]]));
        }
        p.push(quad([[0.0, 0.0], [2.3, 0.0], [2.3, 1.0], [0.0, 1.0]]));
        p.push(quad([[2.3, 0.0], [4.0, 0.0], [4.0, 1.0], [2.3, 1.0]]));
        for i in 0..6 {
            let x = 7.0 + i as f64;
            p.push(quad([
                [x, -2.0],
                [x + 1.0, -2.0],
                [x + 1.0, -1.0],
                [x, -1.0],
            ]));
        }
        p.push(quad([[30.0, 0.0], [31.0, 0.0], [31.0, 1.0], [30.0, 1.0]]));
        let materials = grey();
        let mut origins: Vec<usize> = (0..p.len()).collect();
        let mut tracked = Tracked::new(&p);
        let mut adjacency = Adjacency::of(&p);
        let mut passes = 0;
        for _ in 0..MAX_PASSES {
            let lines = lines(&adjacency, &p, &materials);
            if lines.is_empty() {
                break;
            }
            let c = contact::cut(&mut p, &mut origins, lines);
            if c.pieces.is_empty() {
                break;
            }
            passes += 1;
            adjacency = adjacency.after_cut(&p, &c.pieces, &mut tracked);
            assert_eq!(adjacency, Adjacency::of(&p), "after pass {passes}");
        }
        assert!(passes >= 2, "{passes} passes");
    }
}
