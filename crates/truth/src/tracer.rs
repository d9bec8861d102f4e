//! The path estimator: one unbiased sample of the light a surface point reflects, rho * H
//! (W/m^2), split into its direct part (light that comes straight from an emitter or a spot) and
//! its indirect part (light reflected at least once more on the way).
//!
//! At each vertex x of a path (on the front side of polygon p, normal n: the interpolated
//! vertex normal of a smooth surface, `scene::shading`, with directions behind the facet itself
//! seeing nothing; path weight beta, the product of the reflectances met so far, rescaled by
//! Russian roulette):
//! - every spot light adds beta * I(w) cos_x / r^2 when x is in front of it, inside its cone
//!   and unoccluded (a point light: next-event estimation is its only strategy);
//! - one emitter point y (emitter by power, point uniform by area, density p_A) adds
//!   beta * (E_j / pi) cos_x / (p_light + p_bsdf), the light strategy's sample with its
//!   balance-heuristic weight folded in, where p_light = p_A r^2 / cos_y and p_bsdf = cos_x / pi
//!   are both densities over directions at x;
//! - a cosine-distributed direction finds the next vertex; if it is an emitter's front face, the
//!   bounce adds beta * E_k * p_bsdf / (p_bsdf + p_light), the bounce's weighted sample (a
//!   cosine-sampled direction estimates irradiance as pi * L, and pi * L_e = E);
//! - the path goes on with beta * rho_k; after [`RR_START`] reflections Russian roulette keeps
//!   it with probability q = max(beta) (at most 1) and divides beta by q, so every channel's
//!   weight stays at most 1 and the expected value is unchanged.
//!
//! A path ends at a miss (the background emits nothing), at a back face (black: surfaces are
//! one-sided, as the solver treats them: receivers gather on their front side, emitters shoot
//! from it), at a black surface, by roulette, or at the optional bounce limit. Both sampling
//! strategies cover exactly the same set of emitter points (front faces, in front of x, visible),
//! so the weights sum to one and the estimate is unbiased; each sample's contribution is bounded
//! (at most E_j / (pi p_bsdf) cos_x = E_j for the light sample), which keeps the variance finite
//! even at a point touching an emitter's edge.
//!
//! Rays leave a point offset along its normal by [`OFFSET`] times the diagonal of the scene's
//! core (`Scene::core_diagonal`: its bounds without backdrops) and skip the polygon they leave
//! (the BVH's `skip`); a ray ignores hits within `T_EPS` of twice that diagonal of its origin
//! and a segment between two points within `T_EPS` of either end, so features smaller than
//! about 1e-7 of the scene's size are not resolved, the resolution of the solver's own shadow
//! rays. Both scale with the core, not the whole bounds: a ground plane a million times the
//! room's size must not blind every ray to what lies within a metre of its origin.

use std::f64::consts::PI;

use glam::DVec3;

use crate::lights::Lights;
use base::rng::Rng;
use scene::bvh::Bvh;
use scene::Scene;

/// Reflections before Russian roulette starts.
pub(crate) const RR_START: u32 = 3;

/// Ray origins are moved this far off their polygon, relative to the scene's diagonal.
pub(crate) const OFFSET: f64 = 1e-9;

/// Two hits whose segment parameters differ by at most this are at the same place (coincident
/// faces): a bounce segment is twice the scene's diagonal, so this is 2e-12 of it.
const COINCIDENT_T: f64 = 1e-12;

/// One sample of the reflected radiosity at a point, split by where the light came from.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Reflected {
    /// Light from emitters and spots reflected once, at the point itself.
    pub direct: DVec3,
    /// Light reflected at least once before it reaches the point.
    pub indirect: DVec3,
}

/// The first surface along a ray.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Surface {
    /// Nothing: the background.
    Miss,
    /// The back of a polygon: black.
    Back,
    /// The front of polygon `polygon`, at `point`.
    Front {
        /// The polygon hit.
        polygon: u32,
        /// The hit point.
        point: DVec3,
    },
}

/// Everything a path needs, built once per run.
pub(crate) struct Tracer<'a> {
    scene: &'a Scene,
    bvh: Bvh,
    lights: Lights,
    /// Length of the normal offset of a ray origin.
    offset: f64,
    /// Length of a bounce ray's segment: longer than any distance inside the scene.
    reach: f64,
    /// The scene's bounding box centre and diagonal (camera rays' reach).
    centre: DVec3,
    diagonal: f64,
    /// The segment parameter a ray's hits start from ([`Scene::ray_t0`]).
    t0: f64,
    /// The sealed polygons (`scene::seal`; none in most scenes): a polygon wholly covered by
    /// faces lying over it closer than rays resolve exchanges light only with those that face
    /// it, as in the solver.
    sealed: std::sync::Arc<scene::seal::Seals>,
    max_bounces: u32,
}

impl<'a> Tracer<'a> {
    /// The tracer of `scene`; paths follow at most `max_bounces` reflections (`None`: no
    /// limit but Russian roulette).
    pub(crate) fn new(scene: &'a Scene, max_bounces: Option<u32>) -> Tracer<'a> {
        let (lo, hi) = scene.bounds();
        let diagonal = (hi - lo).length();
        let diagonal = if diagonal > 0.0 && diagonal.is_finite() {
            diagonal
        } else {
            1.0
        };
        let core = scene.core_diagonal();
        let core = if core > 0.0 && core <= diagonal {
            core
        } else {
            diagonal
        };
        Tracer {
            scene,
            bvh: Bvh::build(&scene.polygons),
            lights: Lights::new(scene),
            offset: OFFSET * core,
            reach: 2.0 * diagonal,
            centre: 0.5 * (lo + hi),
            diagonal,
            t0: scene.ray_t0(),
            sealed: scene.seals(),
            max_bounces: max_bounces.unwrap_or(u32::MAX),
        }
    }

    /// The first surface the ray from `origin` along the unit `dir` meets (no polygon skipped).
    pub(crate) fn trace_from_outside(&self, origin: DVec3, dir: DVec3) -> Surface {
        let reach = (origin - self.centre).length() + self.diagonal * 1.01;
        self.first_surface(origin, dir, reach, u32::MAX).0
    }

    /// The first surface from `origin` along unit `dir` within `reach`, skipping `skip`, and
    /// the distance to it.
    ///
    /// A back face with a front face at the same distance behind it (a two-sided emitter's
    /// reversed twin, `two_sided`, or any pair of coincident opposite faces) is the front
    /// face: the BVH breaks the tie by index, and the twin comes after the face it copies, so
    /// without this a bounce would never reach the twin's light.
    fn first_surface(&self, origin: DVec3, dir: DVec3, reach: f64, skip: u32) -> (Surface, f64) {
        let back = |k: u32| self.scene.polygons[k as usize].normal.dot(dir) >= 0.0;
        let (d, t0) = (dir * reach, self.t0);
        let hit = self
            .bvh
            .first_hit_from(origin, d, t0, [skip, u32::MAX])
            .map(|(k, t)| {
                if !back(k) {
                    return (k, t);
                }
                match self.bvh.first_hit_from(origin, d, t0, [skip, k]) {
                    Some((k2, t2)) if (t2 - t).abs() <= COINCIDENT_T && !back(k2) => (k2, t2),
                    _ => (k, t),
                }
            });
        match hit {
            None => (Surface::Miss, 0.0),
            Some((k, t)) => {
                let dist = t * reach;
                if back(k) {
                    (Surface::Back, dist)
                } else {
                    let point = origin + dir * dist;
                    (Surface::Front { polygon: k, point }, dist)
                }
            }
        }
    }

    /// The face the ray from `x` on sealed polygon `p` along unit `dir` meets among its
    /// partners, and the distance to it: they lie in front of `x` closer than the rays' blind
    /// zone (and than the origin offset), so they are intersected from `x` itself. A ray that
    /// leaves past their edge (they cover all but rounding of `p`) meets nothing.
    fn partner_surface(&self, p: u32, x: DVec3, dir: DVec3) -> (Surface, f64) {
        let d = dir * self.reach;
        match self.bvh.first_hit_among(x, d, self.sealed.partners(p)) {
            Some((k, t)) if self.scene.polygons[k as usize].normal.dot(dir) < 0.0 => {
                let dist = t * self.reach;
                let point = x + dir * dist;
                (Surface::Front { polygon: k, point }, dist)
            }
            _ => (Surface::Miss, 0.0),
        }
    }

    /// Where the rays from `x` on polygon `p` (front normal `face`) start: off the polygon by
    /// the offset, except on a sealed polygon, whose partners may lie closer than that.
    fn origin(&self, p: u32, x: DVec3, face: DVec3) -> DVec3 {
        if !self.sealed.is_sealed(p) {
            x + face * self.offset
        } else {
            x
        }
    }

    /// Whether the segment from `o` (off polygon `p`) to `y` on the light `e` is blocked: not
    /// between sealed partners, which face each other with nothing between.
    fn blocked(&self, p: u32, o: DVec3, y: DVec3, e: u32) -> bool {
        if self.sealed.is_sealed(p) {
            return false;
        }
        self.bvh.occluded(o, y, p, e)
    }

    /// One sample of rho * H at `x` on the front of polygon `p`.
    pub(crate) fn reflected(&self, p: u32, x: DVec3, rng: &mut Rng) -> Reflected {
        let mut out = Reflected::default();
        let mut beta = self.scene.material_of(p as usize).reflectance;
        let (mut p, mut x) = (p, x);
        let mut depth = 0u32;
        while beta.max_element() > 0.0 {
            let poly = &self.scene.polygons[p as usize];
            let n = Normals {
                face: poly.normal,
                shading: poly.shading_normal(x),
            };
            let o = self.origin(p, x, n.face);
            let mut h = self.spots(p, o, n) + self.emitter(p, o, n, rng);
            let next = self.bounce(p, o, n, rng);
            if let Some((_, _, emitted)) = next {
                h += emitted;
            }
            if depth == 0 {
                out.direct += beta * h;
            } else {
                out.indirect += beta * h;
            }
            let Some((k, y, _)) = next else { break };
            if depth >= self.max_bounces {
                break;
            }
            depth += 1;
            beta *= self.scene.material_of(k as usize).reflectance;
            if depth >= RR_START {
                let q = beta.max_element().min(1.0);
                if rng.next_f64() >= q {
                    break;
                }
                beta /= q;
            }
            (p, x) = (k, y);
        }
        out
    }

    /// The share of the direct irradiance at `x` on the front of polygon `p` that arrives
    /// unblocked, in [0, 1], and `None` where no light reaches the point's plane at all.
    ///
    /// Deterministic: every spot light is one point, every area emitter is sampled at the
    /// centres of a `grid` x `grid` lattice in its (u, v) parameters, each weighted by its
    /// unblocked irradiance (the bilinear map's area element included). So a point sees
    /// exactly 1 where no occluder hides any lattice point and exactly 0 where all are hidden:
    /// a penumbra's edges are located to one lattice cell of the light.
    pub(crate) fn unblocked_share(&self, p: u32, x: DVec3, grid: u32) -> Option<f64> {
        let poly = &self.scene.polygons[p as usize];
        let n = Normals {
            face: poly.normal,
            shading: poly.shading_normal(x),
        };
        let o = self.origin(p, x, n.face);
        let (mut all, mut seen) = (0.0, 0.0);
        let mut add = |w: f64, blocked: &dyn Fn() -> bool| {
            if w > 0.0 && w.is_finite() {
                all += w;
                if !blocked() {
                    seen += w;
                }
            }
        };
        let spots = if !self.sealed.is_sealed(p) {
            &self.scene.spots[..]
        } else {
            &[]
        };
        for s in spots {
            let d = s.position - o;
            let r2 = d.length_squared();
            let w = d / r2.sqrt();
            let i = crate::luminance(s.intensity_towards(-w));
            add(i * n.cos(w) / r2, &|| {
                self.bvh.occluded(o, s.position, p, u32::MAX)
            });
        }
        let step = 1.0 / grid as f64;
        for &e in self.lights.emitters() {
            if e == p || !self.sealed.may_exchange(p, e) {
                continue;
            }
            let light = &self.scene.polygons[e as usize];
            let radiance = crate::luminance(self.scene.material_of(e as usize).emission) / PI;
            for i in 0..grid {
                for j in 0..grid {
                    let (u, v) = ((i as f64 + 0.5) * step, (j as f64 + 0.5) * step);
                    let y = light.point(u, v);
                    let area = light.area_element(u, v) * step * step;
                    let d = y - o;
                    let r2 = d.length_squared();
                    let w = d / r2.sqrt();
                    let cos_y = (-light.normal.dot(w)).max(0.0);
                    add(radiance * n.cos(w) * cos_y * area / r2, &|| {
                        self.blocked(p, o, y, e)
                    });
                }
            }
        }
        (all > 0.0).then(|| (seen / all).clamp(0.0, 1.0))
    }

    /// The spot lights' irradiance at `o` (normals `n`, on polygon `p`).
    fn spots(&self, p: u32, o: DVec3, n: Normals) -> DVec3 {
        let mut h = DVec3::ZERO;
        if self.sealed.is_sealed(p) {
            return h;
        }
        for s in &self.scene.spots {
            let d = s.position - o;
            let r2 = d.length_squared();
            if r2 <= 0.0 {
                continue;
            }
            let w = d / r2.sqrt();
            let cos_x = n.cos(w);
            if cos_x <= 0.0 {
                continue;
            }
            let i = s.intensity_towards(-w);
            if i.max_element() <= 0.0 || self.bvh.occluded(o, s.position, p, u32::MAX) {
                continue;
            }
            h += i * (cos_x / r2);
        }
        h
    }

    /// One light-strategy sample of the area emitters' irradiance at `o`, MIS-weighted.
    fn emitter(&self, p: u32, o: DVec3, n: Normals, rng: &mut Rng) -> DVec3 {
        let Some(s) = self.lights.sample(self.scene, rng) else {
            return DVec3::ZERO;
        };
        if s.polygon == p || !self.sealed.may_exchange(p, s.polygon) {
            return DVec3::ZERO;
        }
        let d = s.point - o;
        let r2 = d.length_squared();
        if r2 <= 0.0 {
            return DVec3::ZERO;
        }
        let w = d / r2.sqrt();
        let cos_x = n.cos(w);
        let cos_y = -self.scene.polygons[s.polygon as usize].normal.dot(w);
        if cos_x <= 0.0 || cos_y <= 0.0 || self.blocked(p, o, s.point, s.polygon) {
            return DVec3::ZERO;
        }
        let p_light = s.pdf_area * r2 / cos_y;
        let p_bsdf = cos_x / PI;
        let e = self.scene.material_of(s.polygon as usize).emission;
        e * (cos_x / (PI * (p_light + p_bsdf)))
    }

    /// The cosine-distributed bounce from `o`: the front face it reaches, the point, and the
    /// MIS-weighted emission it sees there (as irradiance at `o`); `None` at a miss or a back
    /// face.
    fn bounce(&self, p: u32, o: DVec3, n: Normals, rng: &mut Rng) -> Option<(u32, DVec3, DVec3)> {
        let w = cosine_direction(n.shading, rng.next_f64(), rng.next_f64());
        if n.face.dot(w) <= 0.0 {
            // Below the facet (a shading normal leaning off it): the facet sees nothing there.
            return None;
        }
        let (surface, dist) = if !self.sealed.is_sealed(p) {
            self.first_surface(o, w, self.reach, p)
        } else {
            self.partner_surface(p, o, w)
        };
        let Surface::Front { polygon: k, point } = surface else {
            return None;
        };
        let e = self.scene.material_of(k as usize).emission;
        let mut emitted = DVec3::ZERO;
        if e.max_element() > 0.0 {
            let cos_y = -self.scene.polygons[k as usize].normal.dot(w);
            let p_light = self.lights.pdf_area(k) * dist * dist / cos_y;
            let p_bsdf = n.cos(w) / PI;
            if p_bsdf + p_light > 0.0 {
                emitted = e * (p_bsdf / (p_bsdf + p_light));
            }
        }
        Some((k, point, emitted))
    }
}

/// The normals at a path vertex: the facet's (which side is in front, where rays start) and the
/// one its light is received by (the interpolated vertex normal of a smooth surface,
/// `scene::shading`, else the facet's).
#[derive(Clone, Copy)]
struct Normals {
    face: DVec3,
    shading: DVec3,
}

impl Normals {
    /// The receiving cosine of direction `w`: by the shading normal, 0 below either plane
    /// (the facet sees nothing behind itself, whatever its shading normal).
    fn cos(&self, w: DVec3) -> f64 {
        if self.face.dot(w) <= 0.0 {
            return 0.0;
        }
        self.shading.dot(w).max(0.0)
    }
}

/// A direction about the unit normal `n` with density cos(theta) / pi, from two uniform numbers.
pub(crate) fn cosine_direction(n: DVec3, u1: f64, u2: f64) -> DVec3 {
    // An orthonormal basis around n without a division by a small number (Duff et al. 2017).
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let s = DVec3::new(b, sign + n.y * n.y * a, -n.y);
    let r = u1.sqrt();
    let phi = 2.0 * PI * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    (t * (r * phi.cos()) + s * (r * phi.sin()) + n * z).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cosine sampling: unit directions in the hemisphere with E[cos] = 2/3 and E[cos^2] = 1/2
    /// (the moments of the cosine density), about normals in every octant and along the poles.
    #[test]
    fn cosine_directions_have_the_cosine_moments() {
        let mut rng = Rng::new(9);
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            DVec3::new(-1.0, 2.0, -0.5).normalize(),
            DVec3::new(0.3, -0.1, 0.9).normalize(),
        ] {
            let count = 50_000;
            let (mut m1, mut m2) = (0.0, 0.0);
            for _ in 0..count {
                let w = cosine_direction(n, rng.next_f64(), rng.next_f64());
                assert!((w.length() - 1.0).abs() < 1e-12);
                let c = n.dot(w);
                assert!(c >= -1e-12);
                m1 += c;
                m2 += c * c;
            }
            // sd of cos is sqrt(1/2 - 4/9) = 0.236: the mean's sd is 0.0011; 5 sd.
            assert!((m1 / count as f64 - 2.0 / 3.0).abs() < 0.0055, "{n}: {m1}");
            assert!((m2 / count as f64 - 0.5).abs() < 0.006, "{n}: {m2}");
        }
    }
}
