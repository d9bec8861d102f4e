//! Shading normals: the normals a model gives its vertices (OBJ `vn`, glTF `NORMAL`), for the
//! surfaces a modeller marked smooth (a cylinder of 32 facets, a sphere, a rounded cushion).
//!
//! A polygon with a [`Shading`] receives light as the smooth surface it approximates would: the
//! receiving cosine at a point uses the normal interpolated from its corners' normals (linearly
//! over a triangle, bilinearly over a quad), not the facet's. Two facets that share an edge and
//! the normals at its ends then receive the same light along it, so their radiosity meets
//! there (the reconstruction joins such gentle folds, see `reconstruction::seam`); facets whose
//! corner normals differ at a shared corner (a crease the model keeps sharp: an unsmoothed edge,
//! a box's corner) keep their step.
//!
//! Only the receiving cosine changes. What a point sees (visibility, the horizon of its
//! hemisphere) is the facet's geometry, and light leaves an emitter by its facet's normal: the
//! geometry the renderers draw is the facets, and light that left a flat emitter by a tilted
//! normal would not be conserved.
//!
//! Invariants: a frame holds unit normals on the front side of its polygon (a normal behind
//! it, as a flipped face or a broken export gives, is dropped at load and the facet stays
//! flat); [`Shading::at`] returns a unit vector within [`MAX_TILT_DEGREES`] of the polygon's
//! normal, turned to its front side, so a polygon flipped at load (orientation repair) keeps
//! its smooth light. A frame is shared (`Arc`) by the pieces a polygon is cut into, and
//! interpolates by position, so a cut changes nothing of the light.

use glam::DVec3;

/// Largest angle between a shading normal and its facet's normal, in degrees. Beyond it the
/// normal is bent back to this angle: a vertex normal far off its face (an export averaging
/// across a sharp edge) would otherwise make the receiving cosine meaningless (light from
/// behind the facet counted, light in front of it lost).
pub const MAX_TILT_DEGREES: f64 = 60.0;

/// Normals equal within this angle (radians) are the same normal: a flat facet's corners with
/// its own normal need no frame.
const SAME_NORMAL: f64 = 1e-7;

/// The corner normals of a facet, by position: a triangle or a convex planar quad.
#[derive(Debug, Clone, PartialEq)]
pub struct Shading {
    /// The facet's corners (a triangle repeats its third: `corners[3] == corners[2]`).
    corners: [DVec3; 4],
    /// Unit normals at the corners.
    normals: [DVec3; 4],
    triangle: bool,
}

impl Shading {
    /// The frame of a facet with `corners` (3 or 4, planar, convex, as in the scene) whose
    /// geometric unit normal is `face`, given a normal per corner. Normals all behind the face
    /// (a face wound against its normals) are turned to its front. `None` when every normal is
    /// the face's (a flat facet), or when one is not finite or zero, or some are in front of
    /// the face and some behind it.
    pub fn new(corners: &[DVec3], normals: &[DVec3], face: DVec3) -> Option<Shading> {
        if corners.len() != normals.len() || !(3..=4).contains(&corners.len()) {
            return None;
        }
        let front = normals.iter().filter(|n| n.dot(face) > 0.0).count();
        let sign = match front {
            f if f == normals.len() => 1.0,
            0 if normals.iter().all(|n| n.dot(face) < 0.0) => -1.0,
            _ => return None,
        };
        let mut unit = [DVec3::ZERO; 4];
        for (u, n) in unit.iter_mut().zip(normals) {
            let len = n.length();
            if !(len.is_finite() && len > 0.0) {
                return None;
            }
            *u = sign * *n / len;
        }
        let n = corners.len();
        if unit[..n]
            .iter()
            .all(|u| u.cross(face).length() <= SAME_NORMAL && u.dot(face) > 0.0)
        {
            return None;
        }
        let triangle = n == 3;
        let mut c = [corners[0]; 4];
        c[..n].copy_from_slice(corners);
        if triangle {
            c[3] = c[2];
            unit[3] = unit[2];
        }
        Some(Shading {
            corners: c,
            normals: unit,
            triangle,
        })
    }

    /// The shading normal at point `x` of a polygon with unit normal `face` lying in this
    /// frame's plane: interpolated, turned to `face`'s side and held within
    /// [`MAX_TILT_DEGREES`] of it (see the module docs).
    pub fn at(&self, x: DVec3, face: DVec3) -> DVec3 {
        let w = self.weights(x);
        let mut n = DVec3::ZERO;
        for (wi, ni) in w.iter().zip(&self.normals) {
            n += *wi * *ni;
        }
        if n.dot(face) < 0.0 {
            n = -n;
        }
        let len = n.length();
        if !(len.is_finite() && len > 1e-12) {
            return face;
        }
        let n = n / len;
        let cos_max = MAX_TILT_DEGREES.to_radians().cos();
        let c = n.dot(face);
        if c >= cos_max {
            return n;
        }
        // Bend back onto the cone of half-angle MAX_TILT_DEGREES about `face`, in the plane
        // of `face` and `n`.
        let side = (n - c * face).normalize_or_zero();
        if side == DVec3::ZERO {
            return face;
        }
        cos_max * face + (1.0 - cos_max * cos_max).sqrt() * side
    }

    /// Interpolation weights of the corners at `x`: barycentric over a triangle, bilinear over
    /// a quad (its (u, v) found by Newton's method on the bilinear map, which converges for a
    /// convex quad), clamped to the facet so a point on its border (or rounded just outside)
    /// takes the border's normal.
    fn weights(&self, x: DVec3) -> [f64; 4] {
        let [c0, c1, c2, c3] = self.corners;
        if self.triangle {
            let (e1, e2, d) = (c1 - c0, c2 - c0, x - c0);
            let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
            let (p, q) = (d.dot(e1), d.dot(e2));
            let det = a * c - b * b;
            if det == 0.0 || !det.is_finite() {
                return [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.0];
            }
            let s = ((c * p - b * q) / det).clamp(0.0, 1.0);
            let t = ((a * q - b * p) / det).clamp(0.0, 1.0 - s);
            return [1.0 - s - t, s, t, 0.0];
        }
        let (mut u, mut v) = (0.5, 0.5);
        for _ in 0..8 {
            let p = (1.0 - v) * ((1.0 - u) * c0 + u * c1) + v * ((1.0 - u) * c3 + u * c2);
            let du = (1.0 - v) * (c1 - c0) + v * (c2 - c3);
            let dv = (1.0 - u) * (c3 - c0) + u * (c2 - c1);
            let r = x - p;
            let (a, b, c) = (du.dot(du), du.dot(dv), dv.dot(dv));
            let det = a * c - b * b;
            if det == 0.0 || !det.is_finite() {
                break;
            }
            let (p1, q1) = (r.dot(du), r.dot(dv));
            let (su, sv) = ((c * p1 - b * q1) / det, (a * q1 - b * p1) / det);
            u = (u + su).clamp(-0.5, 1.5);
            v = (v + sv).clamp(-0.5, 1.5);
            if su.abs().max(sv.abs()) < 1e-13 {
                break;
            }
        }
        let (u, v) = (u.clamp(0.0, 1.0), v.clamp(0.0, 1.0));
        [(1.0 - u) * (1.0 - v), u * (1.0 - v), u * v, (1.0 - u) * v]
    }
}

/// Gives each polygon of `pieces` (what a model's face with `corners` and vertex `normals`
/// became: itself, or the triangles and quads it was split into, whose corners are the
/// face's) the frame of its corners' normals; a piece corner that is not one of the face's
/// takes the nearest corner's normal. Flat pieces get none.
pub fn shade_pieces(pieces: &mut [crate::Polygon], corners: &[DVec3], normals: &[DVec3]) {
    if corners.len() != normals.len() || corners.is_empty() {
        return;
    }
    for p in pieces {
        let own: Vec<DVec3> = p
            .vertices()
            .iter()
            .map(|v| {
                let k = (0..corners.len())
                    .min_by(|&a, &b| corners[a].distance(*v).total_cmp(&corners[b].distance(*v)))
                    .unwrap_or(0);
                normals[k]
            })
            .collect();
        let frame = Shading::new(p.vertices(), &own, p.normal).map(std::sync::Arc::new);
        p.shading = frame;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(x: f64, y: f64, z: f64) -> DVec3 {
        DVec3::new(x, y, z).normalize()
    }

    #[test]
    fn corners_take_their_own_normals_and_edges_interpolate_between_their_ends() {
        // A skewed convex quad in z = 0 (bilinear, not affine): the inverse must be exact.
        let c = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.2, 0.0),
            DVec3::new(2.5, 1.7, 0.0),
            DVec3::new(-0.3, 1.0, 0.0),
        ];
        let n = [
            unit(0.2, 0.0, 1.0),
            unit(-0.2, 0.1, 1.0),
            unit(0.0, -0.3, 1.0),
            unit(0.1, 0.1, 1.0),
        ];
        let s = Shading::new(&c, &n, DVec3::Z).unwrap();
        for k in 0..4 {
            assert!((s.at(c[k], DVec3::Z) - n[k]).length() < 1e-12, "corner {k}");
        }
        // Along each edge the weight is linear in position and depends only on the edge's two
        // ends: the same point of a neighbour sharing the edge gets the same normal.
        for k in 0..4 {
            let (a, b) = (c[k], c[(k + 1) % 4]);
            for t in [0.25, 0.5, 0.9] {
                let want = ((1.0 - t) * n[k] + t * n[(k + 1) % 4]).normalize();
                let got = s.at(a + t * (b - a), DVec3::Z);
                assert!(
                    (got - want).length() < 1e-10,
                    "edge {k} at {t}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn a_triangle_interpolates_barycentrically() {
        let c = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let n = [unit(0.3, 0.0, 1.0), unit(0.0, 0.3, 1.0), DVec3::Z];
        let s = Shading::new(&c, &n, DVec3::Z).unwrap();
        let x = DVec3::new(0.2, 0.3, 0.0);
        let want = (0.5 * n[0] + 0.2 * n[1] + 0.3 * n[2]).normalize();
        assert!((s.at(x, DVec3::Z) - want).length() < 1e-12);
    }

    #[test]
    fn flat_and_broken_normals_make_no_frame_and_flips_and_tilts_are_bounded() {
        let c = [DVec3::ZERO, DVec3::X, DVec3::Y];
        assert!(Shading::new(&c, &[DVec3::Z; 3], DVec3::Z).is_none());
        assert!(Shading::new(&c, &[DVec3::Z, DVec3::Z, -DVec3::Z], DVec3::Z).is_none());
        // Normals all behind the face: the face is wound against them; they are turned.
        let back = [-unit(0.1, 0.0, 1.0); 3];
        let s = Shading::new(&c, &back, DVec3::Z).unwrap();
        assert!((s.at(DVec3::new(0.2, 0.2, 0.0), DVec3::Z) - unit(0.1, 0.0, 1.0)).length() < 1e-12);
        assert!(Shading::new(&c, &[DVec3::Z, DVec3::ZERO, DVec3::Z], DVec3::Z).is_none());
        let nan = DVec3::new(f64::NAN, 0.0, 1.0);
        assert!(Shading::new(&c, &[DVec3::Z, nan, DVec3::Z], DVec3::Z).is_none());
        let tilted = [
            unit(1.0, 0.0, 0.1),
            unit(1.0, 0.0, 0.1),
            unit(1.0, 0.0, 0.1),
        ];
        let s = Shading::new(&c, &tilted, DVec3::Z).unwrap();
        let n = s.at(DVec3::new(0.2, 0.2, 0.0), DVec3::Z);
        let cos = MAX_TILT_DEGREES.to_radians().cos();
        assert!((n.dot(DVec3::Z) - cos).abs() < 1e-12 && n.x > 0.0, "{n}");
        // A polygon flipped after load keeps the frame's normal, turned to its front.
        let s = Shading::new(&c, &[unit(0.1, 0.0, 1.0); 3], DVec3::Z).unwrap();
        let n = s.at(DVec3::new(0.2, 0.2, 0.0), -DVec3::Z);
        assert!((n - -unit(0.1, 0.0, 1.0)).length() < 1e-12, "{n}");
    }
}
