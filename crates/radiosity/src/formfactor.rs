//! Form factors: the geometric kernel of the radiosity solve. Every transfer of light from a
//! shooter (a polygon or a sub-patch of one) to a receiver point goes through
//! [`point_to_polygon`], the exact unoccluded differential-area-to-polygon form factor of
//! Lambert's formula:
//!
//! F = (1 / 2 pi) * sum over edges of angle(r_i, r_{i+1}) * (n . normalize(r_i x r_{i+1})).
//!
//! Invariants: the result is finite and in [0, 1]; it is zero when the receiver is not strictly in
//! front of the shooter's plane (a diffuse shooter emits only to its front) and when nothing of the
//! shooter is in front of the receiver. A shooter that straddles the receiver's tangent plane is
//! first clipped to the receiver's front half-space, because Lambert's formula counts the part
//! below the horizon with the wrong sign. Everything is `f64`: near-grazing configurations
//! (receivers next to a perpendicular wall) lose digits quickly in `f32`.

use glam::DVec3;

/// Most vertices a convex polygon can have after one clip of a quad by a plane.
pub(crate) const MAX_CLIPPED: usize = 8;

/// A small convex polygon on the stack (at most [`MAX_CLIPPED`] vertices).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SmallPoly {
    /// Vertices; only the first `len` are meaningful.
    pub v: [DVec3; MAX_CLIPPED],
    /// Number of vertices.
    pub len: usize,
}

impl SmallPoly {
    /// Builds a polygon from 3 or 4 corners, dropping consecutive duplicates (a collapsed quad
    /// corner of a triangle) so that the result has no zero-length edge.
    pub(crate) fn from_corners(c: &[DVec3]) -> SmallPoly {
        let mut p = SmallPoly {
            v: [DVec3::ZERO; MAX_CLIPPED],
            len: 0,
        };
        for &x in c.iter().take(MAX_CLIPPED) {
            if p.len == 0 || p.v[p.len - 1] != x {
                p.v[p.len] = x;
                p.len += 1;
            }
        }
        while p.len > 1 && p.v[p.len - 1] == p.v[0] {
            p.len -= 1;
        }
        p
    }

    /// The vertices as a slice.
    pub(crate) fn verts(&self) -> &[DVec3] {
        &self.v[..self.len]
    }

    /// Clips the polygon to the closed half-space `n . (p - x) >= 0` (Sutherland-Hodgman).
    pub(crate) fn clip_to_front(&self, x: DVec3, n: DVec3) -> SmallPoly {
        let mut out = SmallPoly {
            v: [DVec3::ZERO; MAX_CLIPPED],
            len: 0,
        };
        let vs = self.verts();
        for i in 0..vs.len() {
            let a = vs[i];
            let b = vs[(i + 1) % vs.len()];
            let da = n.dot(a - x);
            let db = n.dot(b - x);
            if da >= 0.0 && out.len < MAX_CLIPPED {
                out.v[out.len] = a;
                out.len += 1;
            }
            if ((da >= 0.0) != (db >= 0.0)) && out.len < MAX_CLIPPED {
                let t = da / (da - db);
                out.v[out.len] = a + (b - a) * t;
                out.len += 1;
            }
        }
        out
    }
}

/// Exact unoccluded form factor from a differential area at `x` with unit normal `n` to the convex
/// polygon `poly` whose front side faces along `poly_normal`.
///
/// Returns 0 when `x` is not strictly in front of the polygon's plane, or when the polygon lies
/// entirely behind the receiver's tangent plane. A polygon that straddles the tangent plane is
/// clipped first. The result is clamped to [0, 1] (rounding can push a full-hemisphere polygon a
/// few ulps above 1).
pub(crate) fn point_to_polygon(x: DVec3, n: DVec3, poly: &SmallPoly, poly_normal: DVec3) -> f64 {
    if poly.len < 3 || poly_normal.dot(x - poly.v[0]) <= 0.0 {
        return 0.0;
    }
    let mut behind = false;
    let mut front = false;
    for p in poly.verts() {
        let d = n.dot(*p - x);
        behind |= d < 0.0;
        front |= d > 0.0;
    }
    if !front {
        return 0.0;
    }
    let clipped;
    let p = if behind {
        clipped = poly.clip_to_front(x, n);
        &clipped
    } else {
        poly
    };
    lambert(x, n, p.verts())
}

/// Most vertices of a convex polygon [`polygon_form_factor`] takes (the visible pieces of exact
/// visibility are bounded by it: an occluder quad clipped by a quad's pyramid has at most 9, a
/// piece gains at most one per cut).
pub(crate) const MAX_VERTS: usize = 12;

/// Exact unoccluded form factor from a differential area at `x` (unit normal `n`) to the convex
/// planar polygon `vs` of any length (at most [`MAX_VERTS`] vertices), which the
/// caller knows `x` to be in front of: clipped to the receiver's front half-space, then
/// Lambert's formula; in [0, 1].
pub(crate) fn polygon_form_factor(x: DVec3, n: DVec3, vs: &[DVec3]) -> f64 {
    const CAP: usize = MAX_VERTS + 1;
    let (mut front, mut behind) = (false, false);
    for p in vs {
        let d = n.dot(*p - x);
        behind |= d < 0.0;
        front |= d > 0.0;
    }
    if !front || vs.len() < 3 {
        return 0.0;
    }
    if !behind {
        return lambert(x, n, vs);
    }
    let mut out = [DVec3::ZERO; CAP];
    let mut len = 0;
    for i in 0..vs.len() {
        let (a, b) = (vs[i], vs[(i + 1) % vs.len()]);
        let (da, db) = (n.dot(a - x), n.dot(b - x));
        if da >= 0.0 && len < CAP {
            out[len] = a;
            len += 1;
        }
        if (da >= 0.0) != (db >= 0.0) && len < CAP {
            out[len] = a + (b - a) * (da / (da - db));
            len += 1;
        }
    }
    lambert(x, n, &out[..len])
}

/// Lambert's contour integral for a polygon entirely in the closed front half-space of (x, n).
fn lambert(x: DVec3, n: DVec3, vs: &[DVec3]) -> f64 {
    if vs.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..vs.len() {
        let a = vs[i] - x;
        let b = vs[(i + 1) % vs.len()] - x;
        let c = a.cross(b);
        let cl = c.length();
        if cl == 0.0 {
            // x lies on the line of this edge: the edge subtends no area.
            continue;
        }
        let angle = cl.atan2(a.dot(b));
        sum += angle * n.dot(c) / cl;
    }
    // The sign follows the winding as seen from x; the polygon is convex and in front of the
    // receiver, so every term of the projected solid angle has the same orientation.
    let f = sum.abs() / (2.0 * std::f64::consts::PI);
    if f.is_finite() {
        f.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn square(z: f64, size: f64, facing_down: bool) -> (SmallPoly, DVec3) {
        let h = size / 2.0;
        let mut c = vec![
            DVec3::new(-h, -h, z),
            DVec3::new(h, -h, z),
            DVec3::new(h, h, z),
            DVec3::new(-h, h, z),
        ];
        if facing_down {
            c.reverse();
        }
        let n = if facing_down { -DVec3::Z } else { DVec3::Z };
        (SmallPoly::from_corners(&c), n)
    }

    /// Coaxial disk of radius R at height h: F = R^2 / (R^2 + h^2). The disk is approximated by an
    /// inscribed regular N-gon (split into quads/triangles is not needed: Lambert's formula takes
    /// any convex polygon, so we use a fan of N triangles and sum them). The N-gon's area is
    /// A_N = (N / 2) R^2 sin(2 pi / N), smaller than pi R^2 by the relative deficit
    /// 1 - sin(2 pi / N) N / (2 pi) (about 6.6e-4 for N = 100); since F grows with the covered
    /// solid angle at most linearly in the area near the axis, the polygon's F falls below the
    /// disk's by at most that deficit. The tolerance is the deficit plus 1e-9 for rounding, and the
    /// polygon's F must not exceed the disk's (it is inscribed).
    #[test]
    fn coaxial_disk_matches_analytic() {
        let n_sides = 100;
        for &(r, h) in &[(1.0, 1.0), (0.5, 2.0), (3.0, 0.5)] {
            let exact = r * r / (r * r + h * h);
            let mut f = 0.0;
            let c = DVec3::new(0.0, 0.0, h);
            for k in 0..n_sides {
                let a0 = 2.0 * PI * k as f64 / n_sides as f64;
                let a1 = 2.0 * PI * (k + 1) as f64 / n_sides as f64;
                // Clockwise seen from above = counter-clockwise seen from below (the front).
                let p0 = DVec3::new(r * a1.cos(), r * a1.sin(), h);
                let p1 = DVec3::new(r * a0.cos(), r * a0.sin(), h);
                let tri = SmallPoly::from_corners(&[c, p0, p1]);
                f += point_to_polygon(DVec3::ZERO, DVec3::Z, &tri, -DVec3::Z);
            }
            let deficit = 1.0 - (2.0 * PI / n_sides as f64).sin() * n_sides as f64 / (2.0 * PI);
            assert!(
                f <= exact + 1e-12,
                "inscribed polygon exceeds disk: {f} > {exact}"
            );
            assert!(
                (exact - f) / exact <= deficit + 1e-9,
                "r={r} h={h}: {f} vs {exact}, deficit {deficit}"
            );
        }
    }

    /// Integrates the point form factor over a receiver square with an n x n midpoint rule. The
    /// integrand is smooth for parallel squares; for perpendicular squares sharing an edge it has
    /// a logarithmic-free but steep rise near the shared edge, which the midpoint rule with n = 64
    /// resolves to well under 0.1% (checked against n = 128 while writing this test).
    fn area_ff(
        recv: impl Fn(f64, f64) -> DVec3,
        recv_n: DVec3,
        src: &SmallPoly,
        src_n: DVec3,
        n: usize,
    ) -> f64 {
        let mut s = 0.0;
        for j in 0..n {
            for i in 0..n {
                let x = recv((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                s += point_to_polygon(x, recv_n, src, src_n);
            }
        }
        s / (n * n) as f64
    }

    #[test]
    fn parallel_unit_squares() {
        let (src, sn) = square(1.0, 1.0, true);
        let f = area_ff(
            |u, v| DVec3::new(u - 0.5, v - 0.5, 0.0),
            DVec3::Z,
            &src,
            sn,
            48,
        );
        assert!((f - 0.19982).abs() / 0.19982 < 0.01, "{f}");
        // And far tighter than 1 %: the midpoint rule is second order here.
        assert!((f - 0.19982).abs() < 2e-4, "{f}");
    }

    #[test]
    fn perpendicular_unit_squares_sharing_an_edge() {
        // Receiver: floor [0,1] x [0,1] at z = 0, normal +z. Source: wall x in [0,1], z in [0,1]
        // at y = 0, facing +y.
        let src = SmallPoly::from_corners(&[
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 0.0),
        ]);
        let f = area_ff(|u, v| DVec3::new(u, v, 0.0), DVec3::Z, &src, DVec3::Y, 64);
        assert!((f - 0.20004).abs() / 0.20004 < 0.01, "{f}");
    }

    #[test]
    fn back_facing_and_below_horizon_give_zero() {
        let (src, sn) = square(1.0, 1.0, true);
        // Receiver above the source: behind the source's plane.
        assert_eq!(
            point_to_polygon(DVec3::new(0.0, 0.0, 2.0), -DVec3::Z, &src, sn),
            0.0
        );
        // Receiver facing away.
        assert_eq!(point_to_polygon(DVec3::ZERO, -DVec3::Z, &src, sn), 0.0);
        // Straddling: a receiver at the square's height facing +x sees exactly the half x > 0.
        let x = DVec3::new(0.0, 0.0, 0.0);
        let full = point_to_polygon(x, DVec3::Z, &src, sn);
        let tilted = point_to_polygon(DVec3::new(0.0, 0.0, 0.0), DVec3::X, &src, sn);
        assert!(tilted > 0.0 && tilted < full);
    }

    /// A receiver at the centre of a closed cube sees all six faces: the form factors of its
    /// hemisphere sum to exactly 1 (the faces in front) whatever direction it faces.
    #[test]
    fn closed_cube_sums_to_one() {
        let faces = crate::test_scenes::cube_faces(2.0);
        for n in [DVec3::Z, DVec3::new(1.0, 2.0, 3.0).normalize()] {
            let x = DVec3::new(0.1, -0.2, 0.3);
            let s: f64 = faces
                .iter()
                .map(|(c, fnorm)| point_to_polygon(x, n, &SmallPoly::from_corners(c), *fnorm))
                .sum();
            assert!((s - 1.0).abs() < 1e-12, "{s}");
        }
    }
}
