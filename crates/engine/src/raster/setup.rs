//! Setup: the second stage of the renderer. It snaps each screen polygon's vertices to a fixed-point
//! grid of `SUBPIXEL_BITS` bits and turns its edges into integer edge functions, then packs the
//! per-pixel expressions and the bilinear-inverse constants the region rasterizer evaluates.
//!
//! Watertightness comes from exact integer arithmetic: a vertex shared by two polygons snaps to the
//! same integer point in both, an edge function `E(X, Y) = dx (Y - y0) - dy (X - x0)` is evaluated
//! exactly in `i64` (coordinates stay below 2^26 thanks to the guard band, so products stay below
//! 2^54), and the top-left rule decides the samples exactly on an edge: after orienting every
//! polygon so its interior has E > 0 (screen y points down), an edge owns its samples when it is a
//! left edge (dy < 0) or a top edge (dy == 0, dx > 0). The same edge traversed by the neighbour
//! has the opposite direction and does not own them, so every sample on a shared edge is covered
//! exactly once. The rule is folded into a bias (0 for owning edges, -1 otherwise) so the inner loop
//! only tests `E + bias >= 0`, a sign bit.
//!
//! Convex polygons are rasterized whole, with one edge function per edge (up to `MAX_EDGES`
//! after clipping), rather than split into triangles: no internal edges, no fan seams. Snapping can
//! make a grazing polygon very slightly non-convex; the half-plane intersection then loses at most
//! the samples within 1/512 pixel of the snapped vertex, a documented approximation.

use super::geometry::{Plane, ScreenPolygon, CLIP_CAPACITY, GUARD_BAND};

/// Subpixel bits of the fixed-point vertex grid.
pub(crate) const SUBPIXEL_BITS: u32 = 8;
/// One pixel in fixed point.
pub const ONE: i64 = 1 << SUBPIXEL_BITS;
/// Most edges a clipped convex polygon can have: 4 corners + 1 near plane + 4 guard-band sides.
pub(crate) const MAX_EDGES: usize = 9;

/// An integer edge function `E(X, Y) = dx (Y - y0) - dy (X - x0) + bias` over fixed-point sample
/// positions; the sample is on the inner side when `E >= 0`. Stored in 32 bits (coordinates and
/// differences stay below 2^27 thanks to the guard band) and evaluated in 64 (products below
/// 2^54): 20 bytes per edge instead of 40 keeps a primitive record small.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Edge {
    /// X1 - X0.
    pub dx: i32,
    /// Y1 - Y0.
    pub dy: i32,
    /// Start vertex X0.
    pub x0: i32,
    /// Start vertex Y0.
    pub y0: i32,
    /// 0 when the edge owns samples exactly on it (top-left rule), -1 otherwise.
    pub bias: i32,
}

impl Edge {
    /// The edge function at fixed-point sample position (X, Y).
    #[inline(always)]
    pub fn at(&self, x: i64, y: i64) -> i64 {
        self.dx as i64 * (y - self.y0 as i64) - self.dy as i64 * (x - self.x0 as i64)
            + self.bias as i64
    }
}

/// How the polygon's (u, v) is recovered from its 2-D plane coordinates (s, t).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BilinearInverse {
    /// c1 - c0 in the plane frame.
    pub b: [f32; 2],
    /// c3 - c0 (quads) or the apex c2 - c0 (triangles).
    pub c: [f32; 2],
    /// c0 - c1 + c2 - c3 (quads; zero for parallelograms).
    pub d: [f32; 2],
    /// cross(b, c) (triangles: the barycentric determinant; quads: part of k1).
    pub bc: f32,
    /// Whether the polygon is a triangle (collapsed quad, c3 == c2).
    pub triangle: bool,
}

/// Which closed form the rasterizer uses for (u, v).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InverseKind {
    #[default]
    /// Parallelogram (|d| below 1e-7 of the sides): (u, v) is affine in the plane coordinates,
    /// so the setup folds it into the per-pixel expressions: u = Ua + w Ub, v = Va + w Vb.
    Linear,
    /// Triangle: the barycentric U = u (1 - v) and v are folded the same way; u = U / (1 - v).
    Triangle,
    /// General convex quad: the quadratic of [`invert_bilinear`].
    General,
}

/// A primitive ready for the region rasterizer.
#[derive(Clone, Debug, Default)]
pub struct Prim {
    /// Scene polygon id (the stable tie-break of every depth comparison).
    pub id: u32,
    /// Edge functions; the first `n_edges` are used.
    pub edges: [Edge; MAX_EDGES],
    /// Number of edges.
    pub n_edges: usize,
    /// Pixel bounding box, inclusive: x0, y0, x1, y1 (clamped to the image).
    pub bbox: [u32; 4],
    /// Q, Sa, Sb, Ta, Tb as in [`super::geometry::plane`] (f64; converted to f32 per region).
    pub planes: [super::geometry::Plane; 5],
    /// Inverse of the bilinear map.
    pub inverse: BilinearInverse,
    /// Which closed form applies. For `Linear` and `Triangle`, `planes[SA..=TB]` hold
    /// (Ua, Ub, Va, Vb) instead of (Sa, Sb, Ta, Tb).
    pub kind: InverseKind,
    /// Whether Q is 1/w.
    pub perspective: bool,
    /// Whether every edge-function value the region walk computes fits in `i32` (small
    /// primitives: `edges_fit_i32`), so the rasterizer may use 32-bit edge lanes.
    pub i32_edges: bool,
}

impl Prim {
    /// Whether this is the empty record of a polygon that reaches no sample (no edges): see
    /// [`super::build_primitives_into`]. Empty records are never binned or rasterized.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.n_edges == 0
    }
}

/// Whether every value of the first `n` edge functions at the sample positions the region walk
/// visits for a primitive with pixel box `bbox` fits in `i32`. The walk visits
/// X in [(x0 - 8) ONE, (x1 + 17) ONE] (blocks aligned to 8, lanes and the step past the last
/// block included) and Y in [y0 ONE, (y1 + 1) ONE]; on that rectangle
/// |E| <= |dx| max|Y - Y0| + |dy| max|X - X0| + 1, with (X0, Y0) the edge's start vertex
/// (which may lie far outside the clamped box).
pub(crate) fn edges_fit_i32(edges: &[Edge], bbox: [u32; 4]) -> bool {
    let [x0, y0, x1, y1] = bbox.map(|c| c as i64);
    let (xa, xb) = ((x0 - 8) * ONE, (x1 + 17) * ONE);
    let (ya, yb) = (y0 * ONE, (y1 + 1) * ONE);
    // In i64: coordinates stay below 2^26 within the guard band, so |dx|, |dy| and the
    // distances stay below 2^27, each product below 2^54 and the bound below 2^55.
    edges.iter().all(|e| {
        let (ex, ey) = (e.x0 as i64, e.y0 as i64);
        let my = (ya - ey).abs().max((yb - ey).abs());
        let mx = (xa - ex).abs().max((xb - ex).abs());
        let bound = (e.dx as i64).abs() * my + (e.dy as i64).abs() * mx + 1;
        bound < i32::MAX as i64
    })
}

/// `x` in fixed point, rounded to the nearest grid point, halfway cases away from zero: the
/// value of `(x * ONE).round() as i64`, without the call to the C library's `round` that the
/// baseline x86-64 target makes of it (no SSE4.1 rounding instruction there). Truncation is one
/// instruction and the fraction `y - trunc(y)` is exact (both below 2^53 in magnitude), so the
/// comparisons with 1/2 decide exactly as `round` does; non-finite input saturates as the cast
/// does.
pub(super) fn snap(x: f64) -> i64 {
    let y = x * ONE as f64;
    let t = y as i64;
    let f = y - t as f64;
    t.saturating_add((f >= 0.5) as i64 - (f <= -0.5) as i64)
}

/// Snaps and sets up a screen polygon for a `width` x `height` image; `None` if it covers no
/// sample (zero area after snapping, or entirely off screen).
pub fn setup(sp: &ScreenPolygon, width: u32, height: u32) -> Option<Prim> {
    let mut prim = Prim::default();
    setup_into(sp, width, height, &mut prim).then_some(prim)
}

/// [`setup`] written into `out` (the frame's record for the polygon, set up in place); returns
/// whether the polygon covers a sample. When it does not, `out` is left partly written and the
/// caller marks it empty.
pub(crate) fn setup_into(sp: &ScreenPolygon, width: u32, height: u32, out: &mut Prim) -> bool {
    debug_assert!(sp
        .verts
        .iter()
        .all(|p| p[0].abs() <= GUARD_BAND + 2.0e4 + width as f64));
    let Some(pts) = snapped_ccw(sp) else {
        return false;
    };
    let n = pts.len();
    let mut edges = [Edge::default(); MAX_EDGES];
    for i in 0..n {
        edges[i] = edge(pts[i], pts[(i + 1) % n]);
    }
    let Some(bbox) = pixel_box(&pts, width, height) else {
        return false;
    };
    let mut planes = sp.planes;
    let (inverse, kind) = if sp.barycentric {
        let inverse = BilinearInverse {
            triangle: true,
            ..BilinearInverse::default()
        };
        (inverse, InverseKind::Triangle)
    } else {
        let (inverse, kind) = inverse_of(sp);
        if kind != InverseKind::General && !fold_linear_inverse(&mut planes, &inverse_frame(sp)) {
            return false;
        }
        (inverse, kind)
    };
    // Field by field: the record is written in place, not built on the stack and copied.
    out.id = sp.id;
    out.edges = edges;
    out.n_edges = n;
    out.bbox = bbox;
    out.i32_edges = edges_fit_i32(&edges[..n], bbox);
    out.planes = planes;
    out.inverse = inverse;
    out.kind = kind;
    out.perspective = sp.perspective;
    true
}

/// Vertices snapped to the fixed-point grid, repeats dropped, counter-clockwise in screen
/// coordinates (interior on the side where every edge function is positive); `None` when fewer
/// than 3 or more than [`MAX_EDGES`] remain, or the snapped area is zero.
fn snapped_ccw(sp: &ScreenPolygon) -> Option<smallvec::SmallVec<[[i64; 2]; CLIP_CAPACITY]>> {
    let mut pts: smallvec::SmallVec<[[i64; 2]; CLIP_CAPACITY]> = smallvec::SmallVec::new();
    for p in &sp.verts {
        let q = [snap(p[0]), snap(p[1])];
        if pts.last() != Some(&q) {
            pts.push(q);
        }
    }
    while pts.len() > 1 && pts.first() == pts.last() {
        pts.pop();
    }
    if pts.len() < 3 || pts.len() > MAX_EDGES {
        return None;
    }
    let n = pts.len();
    let area2: i128 = (0..n)
        .map(|i| {
            let (a, b) = (pts[i], pts[(i + 1) % n]);
            a[0] as i128 * b[1] as i128 - b[0] as i128 * a[1] as i128
        })
        .sum();
    if area2 == 0 {
        return None;
    }
    if area2 < 0 {
        pts.reverse();
    }
    Some(pts)
}

/// The edge function from snapped vertex `a` to `b`, owning the samples exactly on it when it
/// is a left or top edge (the top-left rule).
pub(super) fn edge(a: [i64; 2], b: [i64; 2]) -> Edge {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let owns = dy < 0 || (dy == 0 && dx > 0);
    // Within the guard band every coordinate is below 2^26 and every difference below 2^27 in
    // magnitude, so the narrowing is exact.
    Edge {
        dx: dx as i32,
        dy: dy as i32,
        x0: a[0] as i32,
        y0: a[1] as i32,
        bias: if owns { 0 } else { -1 },
    }
}

/// The inclusive pixel box of the snapped vertices clamped to the image, `None` when off
/// screen. Samples of pixel i lie in [i * ONE, (i + 1) * ONE): pixels whose square meets the box.
#[inline]
pub(super) fn pixel_box(pts: &[[i64; 2]], width: u32, height: u32) -> Option<[u32; 4]> {
    let (mut lo_x, mut lo_y, mut hi_x, mut hi_y) = (i64::MAX, i64::MAX, i64::MIN, i64::MIN);
    for p in pts {
        lo_x = lo_x.min(p[0]);
        hi_x = hi_x.max(p[0]);
        lo_y = lo_y.min(p[1]);
        hi_y = hi_y.max(p[1]);
    }
    let px0 = lo_x.div_euclid(ONE).max(0);
    let py0 = lo_y.div_euclid(ONE).max(0);
    let px1 = hi_x.div_euclid(ONE).min(width as i64 - 1);
    let py1 = hi_y.div_euclid(ONE).min(height as i64 - 1);
    if px0 > px1 || py0 > py1 {
        return None;
    }
    Some([px0 as u32, py0 as u32, px1 as u32, py1 as u32])
}

/// The polygon's bilinear map in its plane frame: b = c1 - c0, c = c3 - c0 (the apex c2 - c0
/// for triangles), d = c0 - c1 + c2 - c3.
struct InverseFrame {
    b: [f64; 2],
    c: [f64; 2],
    d: [f64; 2],
}

fn inverse_frame(sp: &ScreenPolygon) -> InverseFrame {
    let [p0, p1, p2, p3] = sp.corners;
    let sub = |a: [f64; 2], b: [f64; 2]| [a[0] - b[0], a[1] - b[1]];
    InverseFrame {
        b: sub(p1, p0),
        c: if sp.triangle {
            sub(p2, p0)
        } else {
            sub(p3, p0)
        },
        d: [p0[0] - p1[0] + p2[0] - p3[0], p0[1] - p1[1] + p2[1] - p3[1]],
    }
}

/// The (u, v) inverse's constants and the closed form that applies: triangles, parallelograms
/// (|d| below 1e-7 of the sides: linear) and general quads.
fn inverse_of(sp: &ScreenPolygon) -> (BilinearInverse, InverseKind) {
    let InverseFrame { b, c, d } = inverse_frame(sp);
    let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
    let f = |v: [f64; 2]| [v[0] as f32, v[1] as f32];
    let inverse = BilinearInverse {
        b: f(b),
        c: f(c),
        d: if sp.triangle { [0.0; 2] } else { f(d) },
        bc: cross(b, c) as f32,
        triangle: sp.triangle,
    };
    let dn = (d[0] * d[0] + d[1] * d[1]).sqrt();
    let side = (b[0] * b[0] + b[1] * b[1]).sqrt() + (c[0] * c[0] + c[1] * c[1]).sqrt();
    let kind = if sp.triangle {
        InverseKind::Triangle
    } else if dn <= 1e-7 * side {
        InverseKind::Linear
    } else {
        InverseKind::General
    };
    (inverse, kind)
}

/// Folds a linear (u, v) inverse into the per-pixel expressions: h = u' b + v c (u' = u for
/// parallelograms, U for triangles), by Cramer's rule u' = cross(h, c) / cross(b, c),
/// v = cross(b, h) / cross(b, c), linear in h = (s, t); s and t are each `A + w B`, so u' and v
/// are too. Returns whether every folded expression is finite.
fn fold_linear_inverse(planes: &mut [Plane; 5], m: &InverseFrame) -> bool {
    use super::geometry::plane as pl;
    let (b, c) = (m.b, m.c);
    let det = b[0] * c[1] - b[1] * c[0];
    let comb = |x: f64, p: Plane, y: f64, q: Plane| Plane {
        a: (x * p.a + y * q.a) / det,
        b: (x * p.b + y * q.b) / det,
        c: (x * p.c + y * q.c) / det,
    };
    let (sa, sb, ta, tb) = (
        planes[pl::SA],
        planes[pl::SB],
        planes[pl::TA],
        planes[pl::TB],
    );
    planes[pl::SA] = comb(c[1], sa, -c[0], ta);
    planes[pl::SB] = comb(c[1], sb, -c[0], tb);
    planes[pl::TA] = comb(-b[1], sa, b[0], ta);
    planes[pl::TB] = comb(-b[1], sb, b[0], tb);
    planes
        .iter()
        .all(|p| p.a.is_finite() && p.b.is_finite() && p.c.is_finite())
}

/// (u, v) of the point with plane coordinates (s, t), clamped into [0, 1]^2.
///
/// Quads solve `h = u b + v c + u v d` (h = (s, t)): eliminating u gives
/// `k2 v^2 + k1 v + k0 = 0` with k2 = cross(d, c), k1 = cross(b, c) + cross(h, d),
/// k0 = cross(h, b). Both roots are formed without cancellation, `v1 = k0 / q` and
/// `v2 = q / k2` with q = -(k1 + sign(k1) sqrt(disc)) / 2 (v1 tends to the linear solution
/// -k0/k1 as k2 -> 0, where v2 runs off to infinity), each with
/// `u = (h - v c) . m / |m|^2`, m = b + v d, a least-squares solve over both axes that needs no
/// choice of axis; the root whose (u, v) lies in [0, 1]^2 is taken, or, if neither does (a
/// point rounding put just outside), the one closer to it. Taking v1 alone was wrong where k1
/// changes sign inside the quad: then `sign(k1)` swaps the roots, and a tapered quad whose
/// first side is its short one (a floor cut along a box's side, seen from its narrow end) was
/// drawn with the (u, v) of a point outside it, clamped to one corner (its light constant over
/// the whole piece). The discriminant is clamped at 0 (it is negative only by rounding for
/// points of a convex quad).
///
/// Triangles (collapsed quads, c3 == c2) solve `h = U b + v c` by barycentrics, then
/// `u = U / (1 - v)` = b1 / (b0 + b1), defined as 0.5 at the apex (1 - v < 1e-7) where every u
/// maps to the same point.
///
/// Clamp: samples are covered by the snapped polygon, which may overhang the true one by up to
/// 1/512 pixel, and f32 rounding can push a boundary point slightly out, so (u, v) is clamped into
/// [0, 1]^2 (a NaN, impossible for finite input, would become 0 through `max`/`min`).
#[inline(always)]
pub fn invert_bilinear(inv: &BilinearInverse, s: f32, t: f32) -> (f32, f32) {
    let cross = |a: [f32; 2], b: [f32; 2]| a[0] * b[1] - a[1] * b[0];
    let h = [s, t];
    let (u, v) = if inv.triangle {
        let det = inv.bc;
        let v = cross(inv.b, h) / det;
        let uu = cross(h, inv.c) / det;
        (triangle_u(uu, v), v)
    } else {
        // f64 here: f32 x f32 products are exact in f64, so the discriminant keeps its accuracy
        // when the two roots nearly coincide (points near the short edge of a quad degenerating
        // towards a triangle), where f32 would cancel catastrophically.
        let c64 = |a: [f32; 2]| [a[0] as f64, a[1] as f64];
        let (b, c, d, h) = (c64(inv.b), c64(inv.c), c64(inv.d), c64(h));
        let cross = |a: [f64; 2], b: [f64; 2]| a[0] * b[1] - a[1] * b[0];
        let k2 = cross(d, c);
        let k1 = cross(b, c) + cross(h, d);
        let k0 = cross(h, b);
        let disc = (k1 * k1 - 4.0 * k0 * k2).max(0.0);
        let q = -0.5 * (k1 + disc.sqrt().copysign(k1));
        let u_of = |v: f64| {
            let m = [b[0] + v * d[0], b[1] + v * d[1]];
            let r = [h[0] - v * c[0], h[1] - v * c[1]];
            let mm = (m[0] * m[0] + m[1] * m[1]).max(f64::MIN_POSITIVE);
            (r[0] * m[0] + r[1] * m[1]) / mm
        };
        let outside = |u: f64, v: f64| {
            let o = |x: f64| (-x).max(x - 1.0).max(0.0);
            if u.is_finite() && v.is_finite() {
                o(u).max(o(v))
            } else {
                f64::INFINITY
            }
        };
        let v1 = if q != 0.0 { k0 / q } else { 0.0 };
        let u1 = u_of(v1);
        let v2 = if k2 != 0.0 { q / k2 } else { f64::INFINITY };
        let u2 = if v2.is_finite() { u_of(v2) } else { f64::NAN };
        if outside(u2, v2) < outside(u1, v1) {
            (u2 as f32, v2 as f32)
        } else {
            (u1 as f32, v1 as f32)
        }
    };
    clamp_uv(u, v)
}

/// u of a triangle from its barycentric U = u (1 - v): U / (1 - v), 0.5 at the apex.
#[inline(always)]
pub fn triangle_u(uu: f32, v: f32) -> f32 {
    let rest = 1.0 - v;
    // The quotient is computed whatever `rest` is and then selected (a vector select in the
    // rasterizer's lanes, not a branch); a division by a tiny `rest` is discarded.
    let q = uu / rest;
    if rest > 1e-7 {
        q
    } else {
        0.5
    }
}

/// Clamps (u, v) into [0, 1]^2, NaN to 0 (see [`invert_bilinear`] for why).
#[inline(always)]
#[allow(clippy::manual_clamp)]
pub fn clamp_uv(u: f32, v: f32) -> (f32, f32) {
    (u.max(0.0).min(1.0), v.max(0.0).min(1.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::raster::geometry::Plane;

    #[test]
    fn snap_rounds_as_the_library_round_does() {
        let half = 0.5 / ONE as f64;
        let mut xs = vec![0.0, -0.0, half, -half, 3.0 * half, -3.0 * half, 1e9, -1e9];
        // The neighbours of every halfway point, and the largest double below one half.
        for k in -4i32..=4 {
            let h = (k as f64 + 0.5) / ONE as f64;
            xs.extend([h.next_down(), h, h.next_up()]);
        }
        xs.push(0.49999999999999994 / ONE as f64);
        let mut rng = base::rng::Rng::new(3);
        xs.extend((0..10_000).map(|_| (rng.next_f64() - 0.5) * 1e5));
        for x in xs {
            assert_eq!(snap(x), (x * ONE as f64).round() as i64, "{x:e}");
        }
        assert_eq!(snap(f64::NAN), 0);
        assert_eq!(snap(f64::INFINITY), i64::MAX);
        assert_eq!(snap(f64::NEG_INFINITY), i64::MIN);
    }

    fn screen(verts: Vec<[f64; 2]>, corners: [[f64; 2]; 4], triangle: bool) -> ScreenPolygon {
        ScreenPolygon {
            id: 0,
            verts: verts.into_iter().collect(),
            planes: [Plane::default(); 5],
            corners,
            triangle,
            perspective: false,
            front_facing: true,
            barycentric: false,
        }
    }

    fn bilinear(c: &[[f64; 2]; 4], u: f64, v: f64) -> [f64; 2] {
        let l = |k: usize| {
            (1.0 - v) * ((1.0 - u) * c[0][k] + u * c[1][k])
                + v * ((1.0 - u) * c[3][k] + u * c[2][k])
        };
        [l(0), l(1)]
    }

    /// Checks (u, v) to `tol` where the map is well conditioned, and always that the recovered
    /// parameters map back to the point within `pos_tol` (backward stability).
    fn check_inverse(corners: [[f64; 2]; 4], triangle: bool, tol: f64) {
        check_inverse_pos(corners, triangle, tol, 1e-4);
    }

    fn check_inverse_pos(corners: [[f64; 2]; 4], triangle: bool, tol: f64, pos_tol: f64) {
        let sp = screen(
            vec![[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]],
            corners,
            triangle,
        );
        let prim = setup(&sp, 16, 16).unwrap();
        for i in 0..=10 {
            for j in 0..=10 {
                let (u, v) = (i as f64 / 10.0, j as f64 / 10.0);
                if triangle && j == 10 {
                    continue; // the apex: every u maps there
                }
                let p = bilinear(&corners, u, v);
                let (gu, gv) = invert_bilinear(&prim.inverse, p[0] as f32, p[1] as f32);
                let back = bilinear(&corners, gu as f64, gv as f64);
                let err = ((back[0] - p[0]).powi(2) + (back[1] - p[1]).powi(2)).sqrt();
                assert!(err < pos_tol, "{corners:?} ({u}, {v}) maps back {err} away");
                if tol.is_infinite() {
                    continue;
                }
                assert!(
                    (gu as f64 - u).abs() < tol && (gv as f64 - v).abs() < tol,
                    "{corners:?} ({u}, {v}) -> ({gu}, {gv})"
                );
            }
        }
    }

    #[test]
    fn bilinear_inverse_is_exact_for_quads_parallelograms_and_triangles() {
        // Tolerance: coordinates ~10, f32 relative rounding ~6e-8 through a handful of operations
        // and a division by |m|^2 ~ 100: errors stay well below 1e-5 in (u, v).
        check_inverse(
            [[0.0, 0.0], [10.0, 0.0], [13.0, 7.0], [1.0, 9.0]],
            false,
            1e-5,
        );
        check_inverse(
            [[0.0, 0.0], [10.0, 2.0], [12.0, 9.0], [2.0, 7.0]],
            false,
            1e-5,
        ); // parallelogram
        check_inverse(
            [[0.0, 0.0], [10.0, 0.0], [10.0, 1e-4 + 10.0], [0.0, 10.0]],
            false,
            1e-5,
        );
        check_inverse(
            [[0.0, 0.0], [10.0, 0.0], [4.0, 8.0], [4.0, 8.0]],
            true,
            1e-5,
        );
        // Nearly a triangle: the c2-c3 edge shrinks to 1e-3. Near it u is ill conditioned (every u
        // maps within 1e-3 of the same point), so only the round trip is checked, to 2e-5 units:
        // f32 input rounding (~5e-7 at coordinates ~8) amplified by the near-double root.
        check_inverse_pos(
            [[0.0, 0.0], [10.0, 0.0], [5.0005, 8.0], [4.9995, 8.0]],
            false,
            f64::INFINITY,
            2e-5,
        );
        // Mirrored orientation.
        check_inverse(
            [[0.0, 0.0], [0.0, 10.0], [7.0, 13.0], [9.0, 1.0]],
            false,
            1e-5,
        );
    }

    /// What broke: a tapered quad (a floor piece cut along two sides of a box, narrow at one
    /// end) whose first side is its short one, and whose k1 changes sign inside it: the root
    /// picked by the sign of k1 alone lay outside the quad, and the whole piece was drawn with
    /// the light of one corner. Every rotation and mirror image of it inverts exactly.
    #[test]
    fn a_tapered_quad_inverts_in_every_corner_order() {
        let q = [[0.276, 0.671], [0.53, 0.75], [0.46, 0.99], [0.375, 0.99]];
        for rot in 0..4 {
            for mirror in [false, true] {
                let at = |k: usize| {
                    let p = q[(k + rot) % 4];
                    if mirror {
                        [10.0 * p[1], 10.0 * p[0]]
                    } else {
                        [10.0 * p[0], 10.0 * p[1]]
                    }
                };
                let o = at(0);
                let c = [0, 1, 2, 3].map(|k| [at(k)[0] - o[0], at(k)[1] - o[1]]);
                check_inverse(c, false, 1e-4);
            }
        }
    }

    #[test]
    fn triangle_apex_has_a_defined_u() {
        let c = [[0.0, 0.0], [10.0, 0.0], [4.0, 8.0], [4.0, 8.0]];
        let sp = screen(vec![[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]], c, true);
        let prim = setup(&sp, 16, 16).unwrap();
        assert_eq!(invert_bilinear(&prim.inverse, 4.0, 8.0), (0.5, 1.0));
    }

    #[test]
    fn edges_are_oriented_inward_with_top_left_ownership() {
        // Clockwise on screen (y down) input is reversed; the interior must test positive.
        let sp = screen(
            vec![[0.5, 0.5], [0.5, 4.5], [4.5, 0.5]],
            [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, 1.0]],
            true,
        );
        let prim = setup(&sp, 8, 8).unwrap();
        let inside = (2 * ONE, 2 * ONE);
        for e in &prim.edges[..prim.n_edges] {
            assert!(e.at(inside.0, inside.1) > 0);
        }
        // The vertex (0.5, 0.5) is the sample of pixel (0, 0), on the top and the left edge: owned.
        let s = (ONE / 2, ONE / 2);
        assert!(prim.edges[..3].iter().all(|e| e.at(s.0, s.1) >= 0));
        // The sample of pixel (4, 0) is the vertex on the right: the hypotenuse does not own it.
        let s = (4 * ONE + ONE / 2, ONE / 2);
        assert!(prim.edges[..3].iter().any(|e| e.at(s.0, s.1) < 0));
    }
}

#[cfg(test)]
mod size_tests {
    use super::*;

    #[test]
    fn a_primitive_record_stays_compact() {
        // 9 edges of 20 bytes, 5 f64 plane expressions, the bilinear inverse and the box: the
        // mesh method sets up one record per triangle per frame (it was 544 bytes with 64-bit
        // edges).
        let size = std::mem::size_of::<Prim>();
        assert!(size <= 376, "Prim is {size} bytes");
    }
}
