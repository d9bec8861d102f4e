//! Closed forms over a floor: a square Lambertian emitter and a spot light, each above small
//! floor probes. The probes reflect (rho = 0.5) but nothing else does (the emitter is black and
//! the probes lie in one plane), so the light the probes reflect is all direct and known exactly:
//! B = rho E F for the emitter, F the exact form factor from a point to a parallel rectangle,
//! and B = rho I cos^f(theta) cos(theta) / r^2 for the spot; each probe's area average is
//! integrated numerically from the exact point formula.

use std::f64::consts::PI;

use glam::DVec3;

use crate::common::{camera, material, quad_facing, spot_down, square, square_average};
use base::progress::SILENT;
use scene::Scene;
use truth::{polygons, TruthOptions};

const RHO: f64 = 0.5;

/// The form factor from a point to the rectangle [0, a] x [0, b] in a parallel plane at height
/// h, one corner straight above the point.
fn corner_form_factor(a: f64, b: f64, h: f64) -> f64 {
    let (x, y) = (a / h, b / h);
    let sx = (1.0 + x * x).sqrt();
    let sy = (1.0 + y * y).sqrt();
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * PI)
}

/// The form factor from the point (px, 0, pz), facing up, to the rectangle
/// [x0, x1] x [z0, z1] at height h facing down: four corner rectangles with signs.
fn form_factor(px: f64, pz: f64, x: [f64; 2], z: [f64; 2], h: f64) -> f64 {
    let g =
        |dx: f64, dz: f64| dx.signum() * dz.signum() * corner_form_factor(dx.abs(), dz.abs(), h);
    let (x0, x1, z0, z1) = (x[0] - px, x[1] - px, z[0] - pz, z[1] - pz);
    g(x1, z1) - g(x0, z1) - g(x1, z0) + g(x0, z0)
}

fn probes_scene(probes: &[(f64, f64, f64)]) -> Scene {
    let mut polygons: Vec<_> = probes
        .iter()
        .map(|&(x, z, side)| square(DVec3::new(x, 0.0, z), side, true, 0))
        .collect();
    polygons.push(square(DVec3::new(0.0, 1.0, 0.0), 0.5, false, 1));
    Scene::new(
        camera(DVec3::new(0.0, 3.0, 3.0), DVec3::ZERO),
        8,
        8,
        vec![
            material("floor", DVec3::splat(RHO), DVec3::ZERO),
            material("emitter", DVec3::ZERO, DVec3::new(3.0, 2.0, 1.0)),
        ],
        polygons,
    )
}

/// The path tracer's estimates of `scene`'s polygons at 16,384 samples each (seed 11).
fn trace_probes(scene: &Scene) -> Vec<truth::PolygonEstimate> {
    let opts = TruthOptions {
        seed: 11,
        samples_per_polygon: 16384,
        ..TruthOptions::new(scene)
    };
    polygons(scene, &opts, &SILENT).unwrap()
}

/// Asserts that probe `k` of [`probes_scene`] (its centre `x`, `z` and side) reads within four
/// standard errors of `RHO E F`, its mean form factor to the emitter (emission `e`); returns
/// that light.
fn assert_probe_lit_exactly(
    k: usize,
    (x, z, side): (f64, f64, f64),
    got: &truth::PolygonEstimate,
    e: DVec3,
) -> DVec3 {
    let f = square_average(x, z, side, 64, |px, pz| {
        form_factor(px, pz, [-0.25, 0.25], [-0.25, 0.25], 1.0)
    });
    let want = RHO * e * f;
    let z = (got.radiosity - want) / got.radiosity_se;
    assert!(
        z.abs().max_element() < 4.0,
        "probe {k}: {} +- {}, want {want} (F = {f})",
        got.radiosity,
        got.radiosity_se
    );
    want
}

#[test]
fn a_square_emitter_lights_the_floor_by_the_exact_form_factor() {
    // Probes: under the centre, off to one side, one large and one under the emitter's edge.
    let probes = [
        (0.0, 0.0, 0.05),
        (0.6, 0.3, 0.05),
        (-0.3, 0.4, 0.6),
        (0.25, 0.0, 0.1),
    ];
    let scene = probes_scene(&probes);
    let e = scene.materials[1].emission;
    let est = trace_probes(&scene);
    for (k, &probe) in probes.iter().enumerate() {
        let got = &est[k];
        // Nothing reflects light back: the indirect part is exactly zero.
        assert_eq!(got.indirect, DVec3::ZERO);
        assert_eq!(got.radiosity, got.direct);
        let want = assert_probe_lit_exactly(k, probe, got, e);
        // Four standard errors are at most 1 % of the value: the check resolves a 1 % error.
        assert!(
            (got.radiosity_se / want).max_element() < 0.0025,
            "{}",
            got.radiosity_se
        );
    }
    // The emitter reflects nothing and emits E.
    assert_eq!(est[probes.len()].radiosity, e);
    // The formula itself: a point under the centre of a large square sees nearly all of it.
    assert!((form_factor(0.0, 0.0, [-1e4, 1e4], [-1e4, 1e4], 1.0) - 1.0).abs() < 1e-3);
}

/// Regression: a backdrop ten million times the room's size (a plane 2e7 wide, behind the
/// room and facing away from it) set the length of every bounce ray, and the BVH ignores hits
/// within 1e-7 of a segment's length from its start: the rays were blind to everything within
/// 5.6 m of their origins, so a probe's bounces never met the emitter 1 m above it and its
/// light read 7 % low. The rays' blind zone now scales with the scene's core; the probes
/// receive the exact form factor's light as without the backdrop.
#[test]
fn a_huge_backdrop_does_not_blind_the_rays() {
    let probes = [(0.0, 0.0, 0.05), (0.6, 0.3, 0.05)];
    let mut scene = probes_scene(&probes);
    let c = DVec3::new;
    let backdrop = quad_facing(
        [
            c(-1e7, -1e7, -5.0),
            c(1e7, -1e7, -5.0),
            c(1e7, 1e7, -5.0),
            c(-1e7, 1e7, -5.0),
        ],
        c(0.0, 0.0, -10.0),
        0,
    );
    scene.polygons.push(backdrop);
    let e = scene.materials[1].emission;
    let est = trace_probes(&scene);
    for (k, &probe) in probes.iter().enumerate() {
        assert_probe_lit_exactly(k, probe, &est[k], e);
    }
}

/// Regression: a two-sided emitter is a face and its reversed twin in the same place; the
/// BVH broke the tie at equal distance by index, so a bounce always met the face's black back
/// and never the twin's light (a ceiling over a Blender panel read 0.62 of its light). A probe
/// facing down above the emitter now receives the twin's light by the exact form factor, as
/// the probes below receive the face's.
#[test]
fn a_two_sided_emitter_lights_both_sides_by_the_exact_form_factor() {
    let probes = [(0.0, 0.0, 0.05), (0.6, 0.3, 0.05), (-0.3, 0.4, 0.6)];
    let mut scene = probes_scene(&probes);
    // Probes mirrored above the emitter (at y = 2, facing down), and the emitter's twin.
    let n = probes.len();
    for (k, &(x, z, side)) in probes.iter().enumerate() {
        scene
            .polygons
            .insert(n + k, square(DVec3::new(x, 2.0, z), side, false, 0));
    }
    let emitter = scene.polygons[2 * n].clone();
    let [a, b, c, d] = emitter.corners;
    let twin = scene::Polygon::quad([d, c, b, a], 1, 0).unwrap();
    scene.polygons.push(twin);
    let scene = Scene::new(
        scene.camera,
        8,
        8,
        scene.materials.clone(),
        scene.polygons.clone(),
    );
    let e = scene.materials[1].emission;
    let opts = TruthOptions {
        seed: 5,
        samples_per_polygon: 16384,
        ..TruthOptions::new(&scene)
    };
    let est = polygons(&scene, &opts, &SILENT).unwrap();
    for (k, &(x, z, side)) in probes.iter().enumerate() {
        let f = square_average(x, z, side, 64, |px, pz| {
            form_factor(px, pz, [-0.25, 0.25], [-0.25, 0.25], 1.0)
        });
        let want = RHO * e * f;
        for (which, got) in [("below", &est[k]), ("above", &est[n + k])] {
            let z = (got.radiosity - want) / got.radiosity_se;
            assert!(
                z.abs().max_element() < 4.0,
                "probe {k} {which}: {} +- {}, want {want}",
                got.radiosity,
                got.radiosity_se
            );
        }
    }
}

#[test]
fn a_spot_lights_the_floor_by_its_intensity_and_cone() {
    let (h, intensity, cone, falloff) = (1.0, 2.0, 40.0f64, 3.0);
    // Inside the cone, further out, across the cone's edge (at x = tan 40 = 0.839) and outside.
    let probes = [
        (0.0, 0.0, 0.05),
        (0.5, 0.2, 0.05),
        (0.8, 0.0, 0.1),
        (1.3, 0.0, 0.1),
    ];
    let mut scene = probes_scene(&probes);
    scene.polygons.pop();
    scene.spots = vec![spot_down(DVec3::new(0.0, h, 0.0), intensity, cone, falloff)];
    let opts = TruthOptions {
        seed: 2,
        samples_per_polygon: 4096,
        ..TruthOptions::new(&scene)
    };
    let est = polygons(&scene, &opts, &SILENT).unwrap();
    let b = |x: f64, z: f64| {
        let r2 = x * x + h * h + z * z;
        let c = h / r2.sqrt();
        if c < cone.to_radians().cos() {
            0.0
        } else {
            RHO * intensity * c.powf(falloff) * c / r2
        }
    };
    for (k, &(x, z, side)) in probes.iter().enumerate() {
        let n = 2000;
        let want = square_average(x, z, side, n, b);
        // The midpoint rule's error across the cone's edge: at most the cells the edge crosses
        // (about 2n of n^2) times the largest value.
        let quadrature = 2.0 / n as f64 * b(x.abs() - side / 2.0, 0.0);
        let got = &est[k];
        assert_eq!(got.indirect, DVec3::ZERO);
        let err = (got.radiosity.x - want).abs();
        assert!(
            err <= 4.0 * got.radiosity_se.x + quadrature,
            "probe {k}: {} +- {}, want {want}",
            got.radiosity.x,
            got.radiosity_se.x
        );
    }
    // Outside the cone: exactly black.
    assert_eq!(est[3].radiosity, DVec3::ZERO);
    assert_eq!(est[3].radiosity_se, DVec3::ZERO);
    // Under the spot: rho I / h^2 within 0.5 % (the probe is small).
    assert!((est[0].radiosity.x / (RHO * intensity) - 1.0).abs() < 5e-3);
}

/// Surfaces are one-sided: a probe under the back of a lit, reflecting panel and under the back
/// of an emitter receives nothing, and a camera that sees only back faces sees black.
#[test]
fn back_faces_are_black() {
    let mut scene = probes_scene(&[(0.0, 0.0, 0.2)]);
    // The emitter turned to face up, and above it a white panel facing down, lit by it: the
    // panel's front is bright, its back (towards the probe) dark. Then a panel facing up
    // between them and the probe, its back to the probe.
    scene.polygons[1] = square(DVec3::new(0.0, 1.0, 0.0), 0.5, true, 1);
    scene
        .materials
        .push(material("white", DVec3::splat(0.8), DVec3::ZERO));
    scene
        .polygons
        .push(square(DVec3::new(0.0, 1.5, 0.0), 3.0, false, 2));
    let opts = TruthOptions {
        seed: 4,
        samples_per_polygon: 4096,
        ..TruthOptions::new(&scene)
    };
    let est = polygons(&scene, &opts, &SILENT).unwrap();
    assert!(
        est[2].radiosity.x > 0.01,
        "the panel is lit: {}",
        est[2].radiosity
    );
    // The probe sees the emitter's back, and beside it the panel's front (light it reflects).
    assert!(est[0].radiosity.x > 0.0);
    let lit = est[0].radiosity;
    // A screen facing up just above the probe: the probe sees only its back.
    scene
        .polygons
        .push(square(DVec3::new(0.0, 0.5, 0.0), 6.0, true, 2));
    let est = polygons(&scene, &opts, &SILENT).unwrap();
    assert_eq!(
        est[0].radiosity,
        DVec3::ZERO,
        "was {lit} without the screen"
    );
    // The camera (above, looking down) sees the panel's back and the screen's: all black.
    scene.camera = camera(DVec3::new(0.0, 3.0, 0.01), DVec3::ZERO);
    let img = truth::render(
        &scene,
        &TruthOptions {
            samples_per_pixel: 2,
            ..opts
        },
        &SILENT,
    )
    .unwrap();
    assert!(img.mean.pixels.iter().all(|p| *p == glam::Vec3::ZERO));
    assert_eq!(img.back_face_samples, 2 * 64);
}
