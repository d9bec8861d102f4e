//! The camera: a ray through every pixel centre of the Cornell box's official view hits a point
//! that the renderer's projection, written out here from its definition (view coordinates, then
//! px = sx x / w + w_img / 2 with sx = w_img / (2 tan(fov_x / 2)), py = sy y / w + h_img / 2 with
//! sy = -h_img / (2 tan(fov_y / 2))), puts back on that pixel centre; and with the renderer's
//! one-sample pattern and black, distinctly emitting polygons, each pixel of the truth image is
//! exactly the exitance of the polygon its centre sees.

use std::path::Path;

use glam::DVec3;

use base::progress::SILENT;
use scene::bvh::Bvh;
use scene::{Camera, Projection};
use truth::{render, CameraRays, PixelFilter, TruthOptions};

fn cornell() -> scene::Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box.toml");
    scene::load_scene(&path).expect("the shipped Cornell box loads")
}

/// The renderer's projection of `p` for `camera` and a `w` x `h` image.
fn renderer_projection(camera: &Camera, w: f64, h: f64, p: DVec3) -> [f64; 2] {
    let forward = (camera.look_at - camera.eye).normalize();
    let right = forward.cross(camera.up).normalize();
    let up = right.cross(forward);
    let d = p - camera.eye;
    let v = DVec3::new(d.dot(right), d.dot(up), d.dot(forward));
    match camera.projection {
        Projection::Perspective { fov_y_deg } => {
            let ty = (0.5 * fov_y_deg.to_radians()).tan();
            let tx = ty * w / h;
            let (sx, sy) = (w / (2.0 * tx), -h / (2.0 * ty));
            [sx * v.x / v.z + 0.5 * w, sy * v.y / v.z + 0.5 * h]
        }
        Projection::Orthographic { width, height } => {
            [w / width * v.x + 0.5 * w, -h / height * v.y + 0.5 * h]
        }
    }
}

#[test]
fn pixel_centre_rays_project_back_onto_their_pixels() {
    let scene = cornell();
    let bvh = Bvh::build(&scene.polygons);
    for (camera, w, h) in [
        (scene.camera, 48u32, 32u32),
        (
            Camera {
                projection: Projection::Orthographic {
                    width: 2.4,
                    height: 1.9,
                },
                ..scene.camera
            },
            40,
            40,
        ),
    ] {
        let rays = CameraRays::new(&camera, w, h).unwrap();
        let mut hits = 0;
        for j in 0..h {
            for i in 0..w {
                let (px, py) = (i as f64 + 0.5, j as f64 + 0.5);
                let (o, d) = rays.ray(px, py);
                let Some((_, t)) = bvh.first_hit(o, d * 20.0, u32::MAX) else {
                    continue;
                };
                hits += 1;
                let q = renderer_projection(&camera, w as f64, h as f64, o + d * 20.0 * t);
                assert!(
                    (q[0] - px).abs() < 1e-9 && (q[1] - py).abs() < 1e-9,
                    "pixel ({i}, {j}) projects to {q:?}"
                );
            }
        }
        assert!(hits > (w * h) as usize / 2, "{hits}");
    }
}

#[test]
fn the_centre_pattern_sees_each_pixel_centres_polygon() {
    let mut scene = cornell();
    // Every polygon black and emitting its own colour: B at a point is the exitance of the
    // polygon there, with no noise.
    let n = scene.polygons.len();
    scene.materials = (0..n)
        .map(|i| scene::Material {
            name: format!("m{i}"),
            reflectance: DVec3::ZERO,
            emission: DVec3::new(i as f64 + 1.0, 0.5, 1.0),
        })
        .collect();
    for (i, p) in scene.polygons.iter_mut().enumerate() {
        p.material = i as u32;
    }
    let (w, h) = (40u32, 40u32);
    let opts = TruthOptions {
        width: w,
        height: h,
        samples_per_pixel: 2,
        filter: PixelFilter::Pattern(base::method::Aa::ONE),
        ..TruthOptions::new(&scene)
    };
    let img = render(&scene, &opts, &SILENT).unwrap();
    let rays = CameraRays::new(&scene.camera, w, h).unwrap();
    let bvh = Bvh::build(&scene.polygons);
    for j in 0..h {
        for i in 0..w {
            let (o, d) = rays.ray(i as f64 + 0.5, j as f64 + 0.5);
            let want = match bvh.first_hit(o, d * 20.0, u32::MAX) {
                Some((k, _)) if scene.polygons[k as usize].normal.dot(d) < 0.0 => {
                    scene.materials[k as usize].emission.as_vec3()
                }
                Some(_) => glam::Vec3::ZERO,
                None => scene.display.background.as_vec3(),
            };
            assert_eq!(img.mean.get(i, j), want, "pixel ({i}, {j})");
            assert_eq!(img.stderr.get(i, j), glam::Vec3::ZERO);
        }
    }
}
