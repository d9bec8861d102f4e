//! Ear clipping: the triangles of a simple polygon given by its corners in a plane.
//!
//! Faces from modelling tools are often concave n-gons (an L-shaped floor, a wall with a notch);
//! the scene's polygons are convex triangles and quads, so the loader cuts such a face into
//! triangles here. The polygon is projected onto its best-fit plane by the caller and handed over
//! as 2D points in counter-clockwise order (seen from the front). An ear is a corner whose
//! triangle with its two neighbours turns left and holds no other remaining corner; removing it
//! leaves a simple polygon with one corner fewer, so a simple polygon of n corners always yields
//! n - 2 triangles (Meisters' two-ears theorem). Corners on a straight line between their
//! neighbours are dropped without a triangle (they add no area).
//!
//! Invariants: for a simple polygon ([`is_simple`], which the caller checks first: ear clipping
//! a polygon that crosses itself returns overlapping triangles) every triangle returned turns left
//! (positive area), the triangles' areas sum to the polygon's, and the corner indices refer to
//! the input. Each step scans the remaining corners for an
//! ear and each test scans them again, so the cost is O(n^3) at worst: at most 256^3 steps for the
//! largest face the loader accepts, milliseconds. Ties (several ears) take the lowest index, so
//! the result is a function of the input alone.

use glam::DVec2;

/// Twice the signed area of the triangle (a, b, c): positive when it turns left.
fn cross(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    (b - a).perp_dot(c - a)
}

/// Twice the signed area of the polygon `p` (positive when counter-clockwise).
pub(crate) fn area2(p: &[DVec2]) -> f64 {
    let n = p.len();
    (0..n).map(|i| p[i].perp_dot(p[(i + 1) % n])).sum()
}

/// Whether the closed polygon `p` is simple: no two of its edges that are not neighbours
/// touch or cross (neighbouring edges share only their common corner unless they fold back).
/// O(n^2) segment tests.
pub(crate) fn is_simple(p: &[DVec2]) -> bool {
    let n = p.len();
    let seg = |i: usize| (p[i], p[(i + 1) % n]);
    for i in 0..n {
        for j in i + 1..n {
            let adjacent = j == i + 1 || (i == 0 && j == n - 1);
            let (a, b) = seg(i);
            let (c, d) = seg(j);
            if adjacent {
                // Neighbours meet at one corner; they overlap only if they fold back on a line.
                let (shared, u, w) = if j == i + 1 { (b, a, d) } else { (a, b, c) };
                let folded = cross(shared, u, w) == 0.0 && (u - shared).dot(w - shared) > 0.0;
                if folded {
                    return false;
                }
            } else if segments_touch(a, b, c, d) {
                return false;
            }
        }
    }
    true
}

/// Whether the closed segments ab and cd share a point.
fn segments_touch(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: DVec2, q: DVec2, r: DVec2, side: f64| {
        side == 0.0
            && r.x >= p.x.min(q.x)
            && r.x <= p.x.max(q.x)
            && r.y >= p.y.min(q.y)
            && r.y <= p.y.max(q.y)
    };
    on(a, b, c, d1) || on(a, b, d, d2) || on(c, d, a, d3) || on(c, d, b, d4)
}

/// Whether `q` is inside or on the triangle (a, b, c), which turns left.
fn in_triangle(q: DVec2, a: DVec2, b: DVec2, c: DVec2) -> bool {
    cross(a, b, q) >= 0.0 && cross(b, c, q) >= 0.0 && cross(c, a, q) >= 0.0
}

/// The triangles (as corner indices into `p`, each turning left) of the simple polygon `p`,
/// counter-clockwise; `eps` is the twice-area below which a corner counts as collinear with its
/// neighbours (scaled by the caller to the polygon's size). `None` when no ear can be found
/// (the polygon crosses itself or is clockwise).
pub(crate) fn ear_clip(p: &[DVec2], eps: f64) -> Option<Vec<[usize; 3]>> {
    let mut left: Vec<usize> = (0..p.len()).collect();
    let mut out = Vec::with_capacity(p.len().saturating_sub(2));
    while left.len() > 3 {
        let m = left.len();
        let mut clipped = false;
        for k in 0..m {
            let (ia, ib, ic) = (left[(k + m - 1) % m], left[k], left[(k + 1) % m]);
            let (a, b, c) = (p[ia], p[ib], p[ic]);
            let turn = cross(a, b, c);
            if turn.abs() <= eps {
                // A corner on the line through its neighbours: no area to cut, drop it.
                left.remove(k);
                clipped = true;
                break;
            }
            if turn < 0.0 {
                continue;
            }
            let blocked = left.iter().any(|&j| {
                j != ia
                    && j != ib
                    && j != ic
                    && p[j] != a
                    && p[j] != c
                    && in_triangle(p[j], a, b, c)
            });
            if !blocked {
                out.push([ia, ib, ic]);
                left.remove(k);
                clipped = true;
                break;
            }
        }
        if !clipped {
            return None;
        }
    }
    if left.len() == 3 {
        let (a, b, c) = (p[left[0]], p[left[1]], p[left[2]]);
        let turn = cross(a, b, c);
        if turn < -eps {
            return None;
        }
        if turn > eps {
            out.push([left[0], left[1], left[2]]);
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn total_area2(p: &[DVec2], t: &[[usize; 3]]) -> f64 {
        t.iter().map(|&[a, b, c]| cross(p[a], p[b], p[c])).sum()
    }

    #[test]
    fn l_shape_becomes_four_triangles_of_its_area() {
        // An L of area 3 (three unit squares), six corners.
        let p: Vec<DVec2> = [(0., 0.), (2., 0.), (2., 1.), (1., 1.), (1., 2.), (0., 2.)]
            .iter()
            .map(|&(x, y)| DVec2::new(x, y))
            .collect();
        let t = ear_clip(&p, 1e-12).unwrap();
        assert_eq!(t.len(), 4);
        assert!(t.iter().all(|&[a, b, c]| cross(p[a], p[b], p[c]) > 0.0));
        assert!((total_area2(&p, &t) - 6.0).abs() < 1e-12);
    }

    #[test]
    fn collinear_corner_is_dropped() {
        // A square with an extra corner in the middle of its bottom edge: 2 triangles.
        let p: Vec<DVec2> = [(0., 0.), (1., 0.), (2., 0.), (2., 2.), (0., 2.)]
            .iter()
            .map(|&(x, y)| DVec2::new(x, y))
            .collect();
        let t = ear_clip(&p, 1e-12).unwrap();
        assert!((total_area2(&p, &t) - 8.0).abs() < 1e-12);
        assert!(t.len() <= 3);
    }

    #[test]
    fn crossing_polygons_are_not_simple() {
        let pts = |v: &[(f64, f64)]| v.iter().map(|&(x, y)| DVec2::new(x, y)).collect::<Vec<_>>();
        assert!(is_simple(&pts(&[
            (0., 0.),
            (2., 0.),
            (2., 1.),
            (1., 1.),
            (1., 2.),
            (0., 2.)
        ])));
        // Bow tie with unequal lobes.
        assert!(!is_simple(&pts(&[(0., 0.), (2., 0.), (0., 1.), (1., 1.)])));
        // A corner that touches a non-neighbouring edge.
        assert!(!is_simple(&pts(&[
            (0., 0.),
            (2., 0.),
            (2., 2.),
            (1., 0.),
            (0., 2.)
        ])));
        // An edge folding back on its neighbour.
        assert!(!is_simple(&pts(&[(0., 0.), (2., 0.), (1., 0.), (1., 1.)])));
    }

    #[test]
    fn clockwise_polygon_is_refused() {
        let p: Vec<DVec2> = [(0., 0.), (0., 1.), (1., 1.), (1., 0.)]
            .iter()
            .map(|&(x, y)| DVec2::new(x, y))
            .collect();
        assert!(ear_clip(&p, 1e-12).is_none());
    }

    proptest::proptest! {
        /// A random star-shaped polygon (simple by construction: corners at increasing angles
        /// around the origin, random radii) is cut into n - 2 left-turning triangles whose areas
        /// sum to the polygon's, to rounding (each area term is a product of coordinates of at
        /// most 1, so 1e-9 is thousands of rounding steps over at most 64 terms).
        #[test]
        fn star_polygons_are_covered_exactly(radii in proptest::collection::vec(0.05f64..1.0, 3..64)) {
            let n = radii.len();
            let p: Vec<DVec2> = radii
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    DVec2::new(r * a.cos(), r * a.sin())
                })
                .collect();
            proptest::prop_assert!(is_simple(&p));
            let t = ear_clip(&p, 1e-14).unwrap();
            proptest::prop_assert!(t.len() <= n - 2);
            for &[a, b, c] in &t {
                proptest::prop_assert!(cross(p[a], p[b], p[c]) > 0.0);
            }
            proptest::prop_assert!((total_area2(&p, &t) - area2(&p)).abs() < 1e-9);
        }
    }
}
