//! Closed forms of radiative transfer, derived independently of the solver, and the small scenes
//! they hold for: the solver's accuracy is measured against these (the `closed_form` tests and
//! the `settings_error` example), never against its own output. Everything is f64.
//!
//! - [`lambert`]: the form factor from a point to a polygon by Lambert's contour formula,
//!   F = 1/(2 pi) sum_i theta_i n . (R_i x R_i+1) / |R_i x R_i+1| (R_i from the point to the
//!   polygon's corners, theta_i the angle between consecutive ones); exact for any polygon the
//!   point sees whole;
//! - [`point_view_factor`]: the view factor from a small source to a rectangle below it;
//! - [`lit_receiver`]: a grey receiver under a black emitter, the scene both are exact for
//!   (nothing else reflects).

use glam::DVec3;
use reconstruction::Reconstruction;
use scene::{Camera, Material, Polygon, Projection, Scene};

/// A material of reflectance `rho` and emission `e`.
pub fn material(name: &str, rho: [f64; 3], e: [f64; 3]) -> Material {
    Material {
        name: name.into(),
        reflectance: DVec3::from_array(rho),
        emission: DVec3::from_array(e),
    }
}

/// A camera looking down at the origin from (0, -3, 3).
pub fn camera() -> Camera {
    Camera {
        eye: DVec3::new(0.0, -3.0, 3.0),
        look_at: DVec3::ZERO,
        up: DVec3::Z,
        projection: Projection::Perspective { fov_y_deg: 50.0 },
    }
}

/// A quad whose normal points along `facing` (its winding reversed if needed). Panics on a
/// degenerate quad: the cases are fixed shapes.
pub fn quad(mut c: [DVec3; 4], facing: DVec3, material: u32) -> Polygon {
    let p = Polygon::quad(c, material, 0).expect("a valid quad");
    if p.normal.dot(facing) > 0.0 {
        return p;
    }
    c.reverse();
    Polygon::quad(c, material, 0).expect("a valid quad")
}

/// Axis-aligned rectangle [x0, x1] x [y0, y1] at height z, facing `facing`.
pub fn rect(x0: f64, x1: f64, y0: f64, y1: f64, z: f64, facing: DVec3, m: u32) -> Polygon {
    let c = [
        DVec3::new(x0, y0, z),
        DVec3::new(x1, y0, z),
        DVec3::new(x1, y1, z),
        DVec3::new(x0, y1, z),
    ];
    quad(c, facing, m)
}

/// Lambert's form factor from a point `x` with normal `n` to the polygon `v`.
pub fn lambert(x: DVec3, n: DVec3, v: &[DVec3]) -> f64 {
    let mut sum = 0.0;
    for i in 0..v.len() {
        let (a, b) = (v[i] - x, v[(i + 1) % v.len()] - x);
        let c = a.cross(b);
        let theta = (a.dot(b) / (a.length() * b.length()))
            .clamp(-1.0, 1.0)
            .acos();
        sum += theta * n.dot(c) / c.length();
    }
    (sum / (2.0 * std::f64::consts::PI)).abs()
}

/// The view factor from a small downward source at height `h` over the origin to the rectangle
/// [x0, x1] x [y0, y1] of the plane below it: the sum over the four quadrants of the corner
/// formula for a differential area parallel to a rectangle (Howell's catalogue, configuration
/// B-3), F = (1 / 2 pi) (A atan(Y A') + B atan(X B')) with X = a / h, Y = b / h,
/// A = X / sqrt(1 + X^2), A' = 1 / sqrt(1 + X^2) and B, B' likewise in Y.
pub fn point_view_factor(h: f64, x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let corner = |a: f64, b: f64| {
        let (x, y) = (a.abs() / h, b.abs() / h);
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        let f =
            (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI);
        f * a.signum() * b.signum()
    };
    corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)
}

/// A grey receiver (reflectance `rho`) lit by a black emitter (emission `e`).
pub fn lit_receiver(receiver: Polygon, rho: f64, light: Polygon, e: f64) -> Scene {
    let materials = vec![
        material("receiver", [rho; 3], [0.0; 3]),
        material("light", [0.0; 3], [e; 3]),
    ];
    Scene::new(camera(), 64, 64, materials, vec![receiver, light])
}

/// The mean of channel 0 of what the reconstruction draws over polygon `polygon`'s (u, v)
/// domain, by an `n` x `n` midpoint rule: times the polygon's area (a parallelogram's), the
/// energy it draws per unit of radiosity.
pub fn drawn_mean(rec: &Reconstruction, polygon: u32, n: u32) -> f64 {
    let mut sum = 0.0;
    for j in 0..n {
        for i in 0..n {
            let (a, b) = ((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
            sum += rec.eval(polygon, a as f32, b as f32).x as f64;
        }
    }
    sum / (n as f64 * n as f64)
}
