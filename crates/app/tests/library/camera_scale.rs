//! The camera and clipping hold at any scene scale: the near plane follows the geometry in front
//! of the camera, not the scene's overall size, and degenerate cameras are refused at load.
//! Regression: one huge polygon far away pushed the near plane (a fixed fraction of the scene's
//! extent) past everything near the camera, and the image came out black with exit 0.

use app::context::Context;
use glam::DVec3;

use app::context::Input;
use app::frames::render_frame;
use app::prepare::prepare;
use base::method::{Method, Placement};
use engine::frame::FrameOptions;
use reconstruction::texture::SizePolicy;
use reconstruction::Estimator;
use scene::{parse_scene, Camera, Material, Polygon, Projection, Scene};

fn square(half: f64, z: f64, material: u32) -> Polygon {
    let c = [
        DVec3::new(-half, -half, z),
        DVec3::new(half, -half, z),
        DVec3::new(half, half, z),
        DVec3::new(-half, half, z),
    ];
    let p = Polygon::quad(c, material, 0).unwrap();
    assert!(p.normal.z > 0.0);
    p
}

/// The centre pixel of `scene` drawn by every method but the mesh (the mesh of an undivided
/// emitter is the same constant, checked too).
fn centre_pixels(scene: Scene) -> Vec<(String, f32)> {
    let input = Input {
        path: "scale.toml".into(),
        scene,
        solution_file: None,
        estimator: Estimator::default(),
        sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
        input_limit: base::output::MAX_INPUT_BYTES,
    };
    let p = prepare(
        &Context::default(),
        input,
        SizePolicy::FromDepth,
        Placement::Centre,
    )
    .unwrap();
    let opts = FrameOptions::new(33, 33);
    Method::NAMES
        .iter()
        .map(|name| {
            let f = render_frame(&p, Method::parse(name).unwrap(), &p.scene.camera, &opts).unwrap();
            (name.to_string(), f.pixels[16 * 33 + 16].x)
        })
        .collect()
}

fn scene_at(scale: f64, far_polygon: bool) -> Scene {
    // An emitting unit square (radiosity 1 everywhere) seen from 3 units away, everything
    // multiplied by `scale`; optionally a grey square a million units wide, 1e5 units behind.
    let mut polygons = vec![square(0.5 * scale, 0.0, 1)];
    if far_polygon {
        polygons.push(square(5e5 * scale, -1e5 * scale, 0));
    }
    let camera = Camera {
        eye: DVec3::new(0.0, 0.0, 3.0 * scale),
        look_at: DVec3::ZERO,
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 30.0 },
    };
    let materials = vec![
        Material {
            name: "grey".into(),
            reflectance: DVec3::splat(0.5),
            emission: DVec3::ZERO,
        },
        Material {
            name: "lamp".into(),
            reflectance: DVec3::ZERO,
            emission: DVec3::ONE,
        },
    ];
    Scene::new(camera, 33, 33, materials, polygons)
}

#[test]
fn near_geometry_renders_beside_a_huge_far_polygon_and_at_any_scale() {
    for (scale, far) in [(1.0, true), (1e-6, false), (1e6, false), (1e-3, true)] {
        for (method, v) in centre_pixels(scene_at(scale, far)) {
            // The emitter's radiosity is exactly 1; every method draws a constant exactly (to
            // f32 rounding).
            assert!(
                (v - 1.0).abs() < 1e-5,
                "scale {scale}, far polygon {far}: {method} draws {v} at the centre"
            );
        }
    }
}

#[test]
fn a_vanishing_field_of_view_is_refused_at_load() {
    let text = |fov: &str| {
        format!(
            "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov_y = {fov}\n\n\
             [[materials]]\nname = \"lamp\"\nreflectance = [0, 0, 0]\nemission = [1, 1, 1]\n\n\
             [[polygons]]\nmaterial = \"lamp\"\nvertices = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]\n"
        )
    };
    assert!(parse_scene(&text("40"), std::path::Path::new("ok.toml")).is_ok());
    for fov in ["1e-300", "0.001", "0", "180"] {
        let e = parse_scene(&text(fov), std::path::Path::new("bad.toml")).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let m = e.to_string();
        assert!(m.contains("bad.toml:4: camera.fov_y"), "{fov}: {m}");
    }
}
