//! Triangles for a polygon whose texture lives in its (u, v) parameter square.
//!
//! The texture methods look a pixel's texture up at the polygon's bilinear parameters (u, v)
//! (`scene::Polygon::point`); an engine interpolates texture coordinates linearly over each
//! triangle. The two agree exactly on a parallelogram (the bilinear map is affine there), which
//! is drawn as two triangles. A triangle (a quad whose last two corners coincide) is drawn as
//! itself: its chart is laid out affinely (`super::atlas`), so linear interpolation is exact.
//! Any other quad is drawn as a k x k grid of cells in (u, v), each split in two, with k the
//! smallest power of two (up to the texture's longer side) for which the interpolated lookup lands
//! within [`MAX_SHIFT`] texel widths of the bilinear one at every cell's test points; the
//! largest shift left is reported.

use glam::DVec3;

use scene::{Polygon, Shape};

/// Largest distance, in texel widths on the polygon, between where an engine's linear
/// interpolation and the bilinear parameterization put the same texel.
pub const MAX_SHIFT: f64 = 0.1;

/// Largest grid a polygon is cut into per side.
const MAX_GRID: u32 = 64;

/// A polygon's triangles: vertices by their (u, v) parameters, triangles by vertex index.
#[derive(Debug, Clone, PartialEq)]
pub struct Tessellation {
    /// Parameters of each vertex.
    pub uv: Vec<[f64; 2]>,
    /// Three vertex indices per triangle, counter-clockwise seen from the polygon's front.
    pub triangles: Vec<[u32; 3]>,
    /// The largest shift measured, in texel widths.
    pub shift: f64,
}

/// Whether the bilinear map of `p` is affine (a parallelogram), to a relative 1e-9.
fn affine(p: &Polygon) -> bool {
    let c = &p.corners;
    p.shape == Shape::Quad
        && ((c[0] + c[2]) - (c[1] + c[3])).length()
            <= 1e-9 * (c[2] - c[0]).length().max((c[3] - c[1]).length())
}

/// The grid of `k` x `k` cells over the square, cells of zero area left out.
fn grid(p: &Polygon, k: u32) -> Tessellation {
    let step = 1.0 / k as f64;
    let mut uv = Vec::with_capacity(((k + 1) * (k + 1)) as usize);
    for j in 0..=k {
        for i in 0..=k {
            uv.push([i as f64 * step, j as f64 * step]);
        }
    }
    let at = |i: u32, j: u32| j * (k + 1) + i;
    let area = |t: [u32; 3]| {
        let q = t.map(|v| p.point(uv[v as usize][0], uv[v as usize][1]));
        (q[1] - q[0]).cross(q[2] - q[0]).length()
    };
    let tiny = 1e-12 * p.area;
    let mut triangles = Vec::with_capacity(2 * (k * k) as usize);
    for j in 0..k {
        for i in 0..k {
            for t in [
                [at(i, j), at(i + 1, j), at(i + 1, j + 1)],
                [at(i, j), at(i + 1, j + 1), at(i, j + 1)],
            ] {
                if area(t) > tiny {
                    triangles.push(t);
                }
            }
        }
    }
    Tessellation {
        uv,
        triangles,
        shift: 0.0,
    }
}

/// The largest distance, in texel widths (`texel` scene units), between the point an engine
/// draws a triangle's test parameters at and the polygon's point with those parameters: for
/// each triangle, the points at barycentric (1/3, 1/3, 1/3) and at its edges' midpoints, found
/// on the polygon by the bilinear map and then located in the triangle (barycentrics in its
/// plane), whose interpolated parameters are mapped back to the polygon.
fn largest_shift(p: &Polygon, t: &Tessellation, texel: f64) -> f64 {
    let mut worst: f64 = 0.0;
    for tri in &t.triangles {
        let uv = tri.map(|v| t.uv[v as usize]);
        let q = uv.map(|a| p.point(a[0], a[1]));
        for w in [
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
            [0.5, 0.5, 0.0],
            [0.0, 0.5, 0.5],
            [0.5, 0.0, 0.5],
        ] {
            let a = [
                w[0] * uv[0][0] + w[1] * uv[1][0] + w[2] * uv[2][0],
                w[0] * uv[0][1] + w[1] * uv[1][1] + w[2] * uv[2][1],
            ];
            let x = p.point(a[0], a[1]);
            let b = barycentric(x, q);
            let drawn = [
                b[0] * uv[0][0] + b[1] * uv[1][0] + b[2] * uv[2][0],
                b[0] * uv[0][1] + b[1] * uv[1][1] + b[2] * uv[2][1],
            ];
            worst = worst.max((p.point(drawn[0], drawn[1]) - x).length() / texel);
        }
    }
    worst
}

/// Barycentric coordinates of `x` projected into the plane of triangle `q`.
fn barycentric(x: DVec3, q: [DVec3; 3]) -> [f64; 3] {
    let (e1, e2, d) = (q[1] - q[0], q[2] - q[0], x - q[0]);
    let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (p1, p2) = (d.dot(e1), d.dot(e2));
    let det = a * c - b * b;
    if det.abs() <= f64::MIN_POSITIVE {
        return [1.0, 0.0, 0.0];
    }
    let s = (c * p1 - b * p2) / det;
    let t = (a * p2 - b * p1) / det;
    [1.0 - s - t, s, t]
}

/// The triangles of polygon `p`, whose texture has `width` x `height` texels over its square.
pub fn tessellate(p: &Polygon, (width, height): (u32, u32)) -> Tessellation {
    if affine(p) {
        return grid(p, 1);
    }
    if p.shape == Shape::Triangle {
        // Corners c0, c1, c2 at (u, v) = (0, 0), (1, 0), (1, 1) (any u is c2 at v = 1).
        return Tessellation {
            uv: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]],
            triangles: vec![[0, 1, 2]],
            shift: 0.0,
        };
    }
    // A texel's width on the polygon: the square root of its area (the texels are about
    // square in the scene, their sides in the ratio of the polygon's).
    let texel = (p.area / (width.max(1) as f64 * height.max(1) as f64)).sqrt();
    let side = width.max(height);
    let mut k = 1;
    loop {
        let mut t = grid(p, k);
        t.shift = largest_shift(p, &t, texel);
        if t.shift <= MAX_SHIFT || k >= side.clamp(1, MAX_GRID) {
            return t;
        }
        k *= 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(c: [[f64; 3]; 4]) -> Polygon {
        Polygon::quad(c.map(DVec3::from_array), 0, 0).unwrap()
    }

    /// A rectangle is two triangles and draws its texture where the parameters put it.
    #[test]
    fn a_parallelogram_is_two_exact_triangles() {
        let p = quad([[0.0; 3], [2.0, 0.0, 0.0], [3.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
        let t = tessellate(&p, (64, 64));
        assert_eq!((t.uv.len(), t.triangles.len()), (4, 2));
        assert!(largest_shift(&p, &t, 1.0 / 64.0) < 1e-12);
    }

    /// A trapezoid's bilinear parameters are not linear in its plane: the grid is refined
    /// until the shift is within the bound, and it covers the quad exactly.
    #[test]
    fn a_trapezoid_is_refined_until_the_shift_is_bounded() {
        let p = quad([[0.0; 3], [1.0, 0.0, 0.0], [0.7, 1.0, 0.0], [0.0, 1.0, 0.0]]);
        let t = tessellate(&p, (16, 16));
        assert!(t.shift <= MAX_SHIFT, "{}", t.shift);
        let k = (t.uv.len() as f64).sqrt() as u32 - 1;
        assert!(k > 1, "one cell cannot follow a trapezoid's parameters");
        assert_eq!(t.triangles.len() as u32, 2 * k * k);
        let drawn: f64 = t
            .triangles
            .iter()
            .map(|tri| {
                let q = tri.map(|v| p.point(t.uv[v as usize][0], t.uv[v as usize][1]));
                0.5 * (q[1] - q[0]).cross(q[2] - q[0]).length()
            })
            .sum();
        assert!((drawn - p.area).abs() < 1e-12, "{drawn} vs {}", p.area);
    }

    /// A triangle is drawn as itself: its chart is affine, nothing to refine.
    #[test]
    fn a_triangle_is_one_triangle() {
        let p = Polygon::triangle(
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]].map(DVec3::from_array),
            0,
            0,
        )
        .unwrap();
        let t = tessellate(&p, (16, 16));
        assert_eq!((t.uv.len(), t.triangles.len(), t.shift), (3, 1, 0.0));
        for (uv, c) in t.uv.iter().zip(p.vertices()) {
            assert_eq!(p.point(uv[0], uv[1]), *c);
        }
    }
}
