//! Scenes built in code for the tests, and the statistics the tests judge estimates by.

use glam::DVec3;
use scene::{Camera, Material, Polygon, Projection, Scene, SpotLight};

/// A material named `name`.
pub(crate) fn material(name: &str, reflectance: DVec3, emission: DVec3) -> Material {
    Material {
        name: name.to_string(),
        reflectance,
        emission,
    }
}

/// The quad through `corners`, turned (corner order reversed) so that its normal points to the
/// side of `toward`.
pub(crate) fn quad_facing(corners: [DVec3; 4], toward: DVec3, material: u32) -> Polygon {
    let q = Polygon::quad(corners, material, 0).expect("a valid quad");
    if q.normal.dot(toward - q.centroid()) > 0.0 {
        return q;
    }
    let [a, b, c, d] = corners;
    Polygon::quad([d, c, b, a], material, 0).expect("a valid quad")
}

/// A horizontal square of side `side` centred at (`x`, `y`, `z`), facing up (+y) or down.
pub(crate) fn square(centre: DVec3, side: f64, up: bool, material: u32) -> Polygon {
    let h = 0.5 * side;
    let c = |dx: f64, dz: f64| centre + DVec3::new(dx, 0.0, dz);
    let toward = centre + if up { DVec3::Y } else { -DVec3::Y };
    quad_facing([c(-h, -h), c(h, -h), c(h, h), c(-h, h)], toward, material)
}

/// A perspective camera at `eye` looking at `look_at`.
pub(crate) fn camera(eye: DVec3, look_at: DVec3) -> Camera {
    Camera {
        eye,
        look_at,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 60.0 },
    }
}

/// The unit cube's six faces, facing in, all of material 0; a camera inside looking at the
/// back face.
pub(crate) fn furnace(reflectance: DVec3, emission: DVec3) -> Scene {
    let v = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let centre = DVec3::splat(0.5);
    let faces = [
        [v(0., 0., 0.), v(1., 0., 0.), v(1., 0., 1.), v(0., 0., 1.)],
        [v(0., 1., 0.), v(1., 1., 0.), v(1., 1., 1.), v(0., 1., 1.)],
        [v(0., 0., 0.), v(0., 1., 0.), v(0., 1., 1.), v(0., 0., 1.)],
        [v(1., 0., 0.), v(1., 1., 0.), v(1., 1., 1.), v(1., 0., 1.)],
        [v(0., 0., 0.), v(1., 0., 0.), v(1., 1., 0.), v(0., 1., 0.)],
        [v(0., 0., 1.), v(1., 0., 1.), v(1., 1., 1.), v(0., 1., 1.)],
    ];
    let polygons = faces.iter().map(|c| quad_facing(*c, centre, 0)).collect();
    Scene::new(
        camera(v(0.5, 0.5, 0.9), v(0.5, 0.5, 0.0)),
        16,
        16,
        vec![material("wall", reflectance, emission)],
        polygons,
    )
}

/// A spot light at `position` pointing straight down.
pub(crate) fn spot_down(
    position: DVec3,
    intensity: f64,
    half_angle_deg: f64,
    falloff: f64,
) -> SpotLight {
    SpotLight {
        position,
        direction: -DVec3::Y,
        intensity: DVec3::splat(intensity),
        half_angle: half_angle_deg.to_radians(),
        falloff,
    }
}

/// The mean of the squared z-scores: about 1 when the standard errors are honest.
pub(crate) fn mean_square(z: &[f64]) -> f64 {
    z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64
}

/// The midpoint rule over the square of side `side` centred at (`cx`, `cz`) with `n` x `n`
/// cells: the average of `f(x, z)`.
pub(crate) fn square_average(
    cx: f64,
    cz: f64,
    side: f64,
    n: usize,
    f: impl Fn(f64, f64) -> f64,
) -> f64 {
    let mut s = 0.0;
    for i in 0..n {
        for j in 0..n {
            let x = cx + side * ((i as f64 + 0.5) / n as f64 - 0.5);
            let z = cz + side * ((j as f64 + 0.5) / n as f64 - 0.5);
            s += f(x, z);
        }
    }
    s / (n * n) as f64
}
