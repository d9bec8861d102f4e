//! Triangle pairs merged into quads: a triangulated model drawn as the quads it was made of.
//!
//! Modelling tools export triangles (Blender's "Triangulated Mesh", every glTF file), and a quad
//! cut along its diagonal is two polygons to this project: two quadtrees, two RRPs, two lightmap
//! charts, and a seam along the diagonal that is slanted to both triangles' axes, so it can be
//! joined in value only (C0) and the light's slope jumps across it. The loader therefore merges
//! two triangles into the quad they form when they share a whole edge (the same two points,
//! traversed in opposite directions, so both face the same way), lie in one plane, have one
//! material and one object, and the quad is convex with every corner well away from a straight
//! angle (its sine at least [`MIN_CORNER_SINE`]: a corner at 180 degrees is a triangle with an
//! extra point, whose bilinear map is singular there).
//!
//! Which pairs: a triangle may pair with up to three neighbours; candidate pairs are taken
//! best first, by the quad's smallest corner sine (a rectangle scores 1, so the two halves of
//! a quad that was triangulated win over a parallelogram across two quads), ties by the
//! triangles' indices, each triangle used once (a greedy matching). A fan of eight triangles
//! around a square's centre becomes its four quarters: the pairs that would put a corner on a
//! side's midpoint are straight there and refused.
//!
//! Invariants: the result depends only on the polygons, in order (shared points are matched
//! by exact coordinates, which every indexed export repeats bit for bit); the merged quad takes
//! the place and the origin of the first triangle, the second is removed, and every other
//! polygon keeps its order; the area and the plane of the surface are unchanged.

use std::collections::HashMap;

use glam::DVec3;

use crate::{Polygon, Shape};
use base::error::Location;

/// Smallest sine of a merged quad's corner angles: below it (a corner within about 3 degrees of
/// straight, or of folding back) the pair stays two triangles.
pub const MIN_CORNER_SINE: f64 = 0.05;

/// Largest distance of the fourth corner from the first triangle's plane, as a fraction of the
/// quad's diameter, for the pair to count as coplanar (the loader's own tolerance for a planar
/// quad is looser; this one keeps any visible fold apart).
pub const PLANE_TOLERANCE: f64 = 1e-6;

/// What [`merge`] did: the pairs merged, and the triangles there were.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Merged {
    /// Triangles before merging.
    pub triangles: usize,
    /// Pairs merged into quads (each removes one polygon).
    pub pairs: usize,
}

impl Merged {
    /// The loader's note, or `None` when nothing was merged.
    pub fn note(&self) -> Option<String> {
        (self.pairs > 0).then(|| {
            format!(
                "{} pairs of the {} triangles merged into quads (coplanar, one material, sharing \
                 a whole edge): one patch and no seam where a quad was split along its diagonal \
                 (radiosity.merge_triangles = false keeps them apart)",
                self.pairs, self.triangles
            )
        })
    }
}

/// Merges triangle pairs into quads in place, keeping `origins` aligned (when it is as long as
/// `polygons`), and says how many.
pub fn merge(polygons: &mut Vec<Polygon>, origins: &mut Vec<Location>) -> Merged {
    let triangles: Vec<usize> = (0..polygons.len())
        .filter(|&i| polygons[i].shape == Shape::Triangle)
        .collect();
    let mut candidates = candidates(polygons, &triangles);
    // Best quads first; ties by the triangles' indices.
    candidates.sort_by(|a, b| {
        b.score
            .total_cmp(&a.score)
            .then((a.t, a.s).cmp(&(b.t, b.s)))
    });
    let mut used = vec![false; polygons.len()];
    let mut removed = vec![false; polygons.len()];
    let mut pairs = 0;
    for c in candidates {
        if used[c.t] || used[c.s] {
            continue;
        }
        let p = &polygons[c.t];
        let Some(shading) = merged_shading(p, &polygons[c.s], &c.corners) else {
            continue;
        };
        used[c.t] = true;
        used[c.s] = true;
        if let Some(q) = Polygon::quad(c.corners, p.material, p.object) {
            polygons[c.t] = q.with_shading(shading);
            removed[c.s] = true;
            pairs += 1;
        }
    }
    let keep_origins = origins.len() == polygons.len();
    let mut i = 0;
    polygons.retain(|_| {
        i += 1;
        !removed[i - 1]
    });
    if keep_origins {
        let mut i = 0;
        origins.retain(|_| {
            i += 1;
            !removed[i - 1]
        });
    }
    Merged {
        triangles: triangles.len(),
        pairs,
    }
}

/// A pair of triangles `t < s` that would make the quad `corners` (counter-clockwise, starting
/// at a corner of `t`), scored by its smallest corner sine.
struct Candidate {
    t: usize,
    s: usize,
    corners: [DVec3; 4],
    score: f64,
}

/// Exact key of a point: its coordinates' bits (-0 and 0 are one point).
type Key = [u64; 3];

fn key(p: DVec3) -> Key {
    let b = |x: f64| (x + 0.0).to_bits();
    [b(p.x), b(p.y), b(p.z)]
}

/// Every pair of triangles that share a whole edge in opposite directions and would merge.
fn candidates(polygons: &[Polygon], triangles: &[usize]) -> Vec<Candidate> {
    // Directed edge (from, to) -> the triangle and its corner opposite the edge.
    let mut edges: HashMap<(Key, Key), (usize, DVec3)> = HashMap::new();
    for &t in triangles {
        let c = &polygons[t].corners;
        for k in 0..3 {
            let (a, b, opp) = (c[k], c[(k + 1) % 3], c[(k + 2) % 3]);
            edges.entry((key(a), key(b))).or_insert((t, opp));
        }
    }
    let mut out = Vec::new();
    for &t in triangles {
        let c = polygons[t].corners;
        for k in 0..3 {
            let (a, b, p) = (c[k], c[(k + 1) % 3], c[(k + 2) % 3]);
            let Some(&(s, q)) = edges.get(&(key(b), key(a))) else {
                continue;
            };
            if s <= t || !compatible(&polygons[t], &polygons[s]) {
                continue;
            }
            // t runs a -> b -> p, s runs b -> a -> q: together a -> q -> b -> p, turned to
            // start at t's first corner so the quad's (u, v) axes follow the author's order.
            let mut corners = [a, q, b, p];
            corners.rotate_left([0, 3, 2][k]);
            if let Some(score) = quad_score(&corners, polygons[t].normal) {
                out.push(Candidate {
                    t,
                    s,
                    corners,
                    score,
                });
            }
        }
    }
    out
}

/// The shading frame of the quad with `corners` that triangles `a` and `b` merge into: none
/// when both are flat; the corner normals of their smooth surface when the two agree at the
/// corners they share; `None` (do not merge) when they do not (a crease the model keeps along
/// the diagonal) or one is smooth and the other flat.
fn merged_shading(
    a: &Polygon,
    b: &Polygon,
    corners: &[DVec3; 4],
) -> Option<Option<std::sync::Arc<crate::shading::Shading>>> {
    match (&a.shading, &b.shading) {
        (None, None) => return Some(None),
        (Some(_), Some(_)) => {}
        _ => return None,
    }
    let on = |p: &Polygon, x: DVec3| p.vertices().iter().any(|v| key(*v) == key(x));
    let mut normals = [DVec3::ZERO; 4];
    for (n, &x) in normals.iter_mut().zip(corners) {
        let (na, nb) = (
            on(a, x).then(|| a.shading_normal(x)),
            on(b, x).then(|| b.shading_normal(x)),
        );
        *n = match (na, nb) {
            (Some(na), Some(nb)) if na.distance(nb) <= 1e-9 => na,
            (Some(_), Some(_)) => return None,
            (Some(n), None) | (None, Some(n)) => n,
            (None, None) => return None,
        };
    }
    let face = crate::newell_normal(corners).normalize_or_zero();
    Some(crate::shading::Shading::new(corners, &normals, face).map(std::sync::Arc::new))
}

/// One material, one object, facing the same way.
fn compatible(a: &Polygon, b: &Polygon) -> bool {
    a.material == b.material && a.object == b.object && a.normal.dot(b.normal) > 0.0
}

/// The smallest corner sine of the quad `c` (counter-clockwise about `normal`), or `None` if it
/// is not planar, not convex or has a corner too near a straight angle.
fn quad_score(c: &[DVec3; 4], normal: DVec3) -> Option<f64> {
    let diameter = (0..4)
        .flat_map(|i| (0..4).map(move |j| (i, j)))
        .map(|(i, j)| c[i].distance(c[j]))
        .fold(0.0, f64::max);
    // Every corner against the plane of the first triangle (three of them lie in it).
    if c.iter()
        .any(|x| (*x - c[0]).dot(normal).abs() > PLANE_TOLERANCE * diameter)
    {
        return None;
    }
    let mut worst = f64::INFINITY;
    for i in 0..4 {
        let into = c[i] - c[(i + 3) % 4];
        let out = c[(i + 1) % 4] - c[i];
        let sine = into.cross(out).dot(normal) / (into.length() * out.length());
        worst = worst.min(sine);
    }
    (worst >= MIN_CORNER_SINE).then_some(worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Polygon {
        let v = |p: [f64; 3]| DVec3::from_array(p);
        Polygon::triangle([v(a), v(b), v(c)], 0, 0).unwrap()
    }

    #[test]
    fn a_square_split_along_its_diagonal_is_one_quad_again() {
        let mut p = vec![
            tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]),
            tri([0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]),
        ];
        let m = merge(&mut p, &mut Vec::new());
        assert_eq!(
            m,
            Merged {
                triangles: 2,
                pairs: 1
            }
        );
        assert_eq!(p.len(), 1);
        assert_eq!(p[0].shape, Shape::Quad);
        assert!((p[0].area - 1.0).abs() < 1e-12);
        assert!((p[0].normal - DVec3::Z).length() < 1e-12);
    }

    /// Smooth triangles merge when their normals agree along the diagonal, and the quad keeps
    /// them; a diagonal the normals keep sharp, or a smooth triangle beside a flat one, stays.
    #[test]
    fn smooth_halves_merge_with_their_normals_and_sharp_diagonals_stay() {
        let lean = |x: f64, y: f64| DVec3::new(x, y, 1.0).normalize();
        let c = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        let n = [
            lean(-0.2, -0.2),
            lean(0.2, -0.2),
            lean(0.2, 0.2),
            lean(-0.2, 0.2),
        ];
        let halves = |n2: DVec3, smooth_second: bool| {
            let mut a = vec![
                Polygon::triangle([c[0], c[1], c[2]], 0, 0).unwrap(),
                Polygon::triangle([c[0], c[2], c[3]], 0, 0).unwrap(),
            ];
            crate::shading::shade_pieces(&mut a[..1], &[c[0], c[1], c[2]], &[n[0], n[1], n[2]]);
            if smooth_second {
                crate::shading::shade_pieces(&mut a[1..], &[c[0], c[2], c[3]], &[n[0], n2, n[3]]);
            }
            a
        };
        let mut p = halves(n[2], true);
        assert_eq!(merge(&mut p, &mut Vec::new()).pairs, 1);
        assert_eq!(p.len(), 1);
        for k in 0..4 {
            let got = p[0].shading_normal(c[k]);
            assert!((got - n[k]).length() < 1e-12, "corner {k}: {got}");
        }
        for (n2, smooth) in [(lean(0.0, 0.3), true), (n[2], false)] {
            let mut p = halves(n2, smooth);
            assert_eq!(merge(&mut p, &mut Vec::new()).pairs, 0);
            assert_eq!(p.len(), 2);
        }
    }

    #[test]
    fn a_fan_of_eight_becomes_four_quarters() {
        // Boundary points of the square [-1, 1]^2, counter-clockwise: corners and midpoints.
        let b = [
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [-1.0, 1.0],
            [-1.0, 0.0],
            [-1.0, -1.0],
            [0.0, -1.0],
            [1.0, -1.0],
        ];
        let mut p: Vec<Polygon> = (0..8)
            .map(|i| {
                let (u, v) = (b[i], b[(i + 1) % 8]);
                tri([0.0, 0.0, 0.0], [u[0], u[1], 0.0], [v[0], v[1], 0.0])
            })
            .collect();
        let m = merge(&mut p, &mut Vec::new());
        assert_eq!(m.pairs, 4);
        assert!(p.iter().all(|q| q.shape == Shape::Quad));
        for q in &p {
            assert!((q.area - 1.0).abs() < 1e-12, "a quarter of area 4");
        }
    }

    #[test]
    fn folds_materials_objects_and_facings_stay_apart() {
        let flat = || {
            vec![
                tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]),
                tri([0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]),
            ]
        };
        let mut folded = flat();
        folded[1] = tri([0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.01]);
        let mut material = flat();
        material[1].material = 1;
        let mut object = flat();
        object[1].object = 1;
        // The second triangle reversed: the shared edge runs the same way in both.
        let mut facing = flat();
        facing[1] = tri([0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]);
        for (name, mut p) in [
            ("fold", folded),
            ("material", material),
            ("object", object),
            ("facing", facing),
        ] {
            assert_eq!(merge(&mut p, &mut Vec::new()).pairs, 0, "{name}");
            assert_eq!(p.len(), 2, "{name}");
        }
    }

    #[test]
    fn the_halves_of_each_quad_win_over_pairs_across_quads() {
        // Two unit squares side by side, each split along its rising diagonal: the triangles
        // on either side of x = 1 would also make a parallelogram.
        let mut p = Vec::new();
        for x in [0.0, 1.0] {
            p.push(tri([x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x + 1.0, 1.0, 0.0]));
            p.push(tri([x, 0.0, 0.0], [x + 1.0, 1.0, 0.0], [x, 1.0, 0.0]));
        }
        let mut origins: Vec<Location> = (0..4)
            .map(|i| Location::file("m.obj").at_line(i + 1))
            .collect();
        assert_eq!(merge(&mut p, &mut origins).pairs, 2);
        assert_eq!(origins.len(), 2);
        for (q, x) in p.iter().zip([0.0, 1.0]) {
            let lo = q.corners.iter().map(|c| c.x).fold(f64::INFINITY, f64::min);
            assert_eq!(lo, x, "each quad is one of the squares");
            assert!((q.area - 1.0).abs() < 1e-12);
        }
    }
}
