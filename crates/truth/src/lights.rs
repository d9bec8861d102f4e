//! The area emitters as a sampling table: next-event estimation picks an emitting polygon with
//! probability proportional to its power (the sum of its exitance's channels times its area)
//! and a point uniformly over its area, and the bounce's multiple importance sampling weight
//! needs the same density at a point it hits.
//!
//! A polygon is sampled over the two triangles (c0, c1, c2) and (c0, c2, c3) the BVH intersects
//! (one for a collapsed-quad triangle), each chosen by its area, so the density a sample has
//! (`select / area`) is the density of every point a bounce ray can hit on that polygon.

use glam::DVec3;

use base::rng::Rng;
use scene::Scene;

/// A point drawn on an emitter.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LightSample {
    /// The emitting polygon.
    pub polygon: u32,
    /// The point.
    pub point: DVec3,
    /// Its density with respect to area (selection probability / polygon area).
    pub pdf_area: f64,
}

/// The emitters and their selection probabilities.
#[derive(Debug, Clone, Default)]
pub(crate) struct Lights {
    /// Emitting polygons, in polygon order.
    polygons: Vec<u32>,
    /// Cumulative selection probability of `polygons` (the last is 1).
    cdf: Vec<f64>,
    /// Per scene polygon: selection probability / area (0 for polygons that do not emit).
    pdf_area: Vec<f64>,
    /// Per emitter: the areas of its two triangles.
    halves: Vec<(f64, f64)>,
}

impl Lights {
    /// The emitters of `scene`.
    pub(crate) fn new(scene: &Scene) -> Lights {
        let mut lights = Lights {
            pdf_area: vec![0.0; scene.polygons.len()],
            ..Lights::default()
        };
        let mut powers = Vec::new();
        for (i, p) in scene.polygons.iter().enumerate() {
            let e = scene.material_of(i).emission;
            let [c0, c1, c2, c3] = p.corners;
            let a1 = 0.5 * (c1 - c0).cross(c2 - c0).length();
            let a2 = 0.5 * (c2 - c0).cross(c3 - c0).length();
            let power = (e.x + e.y + e.z) * (a1 + a2);
            if power > 0.0 && power.is_finite() {
                lights.polygons.push(i as u32);
                lights.halves.push((a1, a2));
                powers.push(power);
            }
        }
        let total: f64 = powers.iter().sum();
        let mut acc = 0.0;
        for (k, &power) in powers.iter().enumerate() {
            acc += power;
            lights.cdf.push(acc / total);
            let (a1, a2) = lights.halves[k];
            lights.pdf_area[lights.polygons[k] as usize] = power / total / (a1 + a2);
        }
        if let Some(last) = lights.cdf.last_mut() {
            *last = 1.0;
        }
        lights
    }

    /// The emitting polygons, in polygon order.
    pub(crate) fn emitters(&self) -> &[u32] {
        &self.polygons
    }

    /// The density with respect to area at which [`Lights::sample`] draws points of polygon
    /// `i` (0 if it does not emit).
    pub(crate) fn pdf_area(&self, i: u32) -> f64 {
        self.pdf_area[i as usize]
    }

    /// A point on an emitter, `None` when the scene has none.
    pub(crate) fn sample(&self, scene: &Scene, rng: &mut Rng) -> Option<LightSample> {
        if self.polygons.is_empty() {
            return None;
        }
        let u = rng.next_f64();
        let k = self
            .cdf
            .partition_point(|&c| c <= u)
            .min(self.cdf.len() - 1);
        let polygon = self.polygons[k];
        let [c0, c1, c2, c3] = scene.polygons[polygon as usize].corners;
        let (a1, a2) = self.halves[k];
        let (b, c) = if rng.next_f64() * (a1 + a2) < a1 {
            (c1, c2)
        } else {
            (c2, c3)
        };
        // Uniform in the triangle (c0, b, c): the square root warps the first coordinate so
        // that area, not parameter, is uniform.
        let s = rng.next_f64().sqrt();
        let t = rng.next_f64();
        let point = c0 * (1.0 - s) + b * (s * (1.0 - t)) + c * (s * t);
        Some(LightSample {
            polygon,
            point,
            pdf_area: self.pdf_area[polygon as usize],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::{Camera, Material, Polygon, Projection};

    fn quad(x: f64, side: f64, material: u32) -> Polygon {
        Polygon::quad(
            [
                DVec3::new(x, 0.0, 0.0),
                DVec3::new(x + side, 0.0, 0.0),
                DVec3::new(x + side, side, 0.0),
                DVec3::new(x, side, 0.0),
            ],
            material,
            0,
        )
        .unwrap()
    }

    /// Emitters are chosen by power and their points are uniform over their area: a bright
    /// small quad and a dim large one, with the same power, are each drawn half the time, and
    /// the points of the large one fill its left half half the time.
    #[test]
    fn emitters_by_power_points_by_area() {
        let m = |e: f64| Material {
            name: format!("e{e}"),
            reflectance: DVec3::ZERO,
            emission: DVec3::splat(e),
        };
        let camera = Camera {
            eye: DVec3::Z,
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            projection: Projection::Perspective { fov_y_deg: 40.0 },
        };
        let scene = Scene::new(
            camera,
            8,
            8,
            vec![m(4.0), m(1.0), m(0.0)],
            vec![quad(0.0, 1.0, 0), quad(2.0, 2.0, 1), quad(5.0, 1.0, 2)],
        );
        let lights = Lights::new(&scene);
        assert_eq!(lights.pdf_area(2), 0.0);
        assert!((lights.pdf_area(0) - 0.5).abs() < 1e-15);
        assert!((lights.pdf_area(1) - 0.125).abs() < 1e-15);
        let mut rng = Rng::new(3);
        let n = 40_000;
        let (mut first, mut left) = (0, 0);
        for _ in 0..n {
            let s = lights.sample(&scene, &mut rng).unwrap();
            if s.polygon == 0 {
                first += 1;
            } else if s.point.x < 3.0 {
                left += 1;
            }
        }
        // Binomial: sd 0.0025 of the fraction; 4 sd.
        assert!((first as f64 / n as f64 - 0.5).abs() < 0.01, "{first}");
        assert!(
            (left as f64 / (n - first) as f64 - 0.5).abs() < 0.015,
            "{left}"
        );
    }
}
