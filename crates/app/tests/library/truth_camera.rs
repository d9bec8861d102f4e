//! The path tracer's camera against the renderer's rasterizer: with the renderer's own sample
//! patterns, a truth image of black polygons that each emit their own colour (B is the exitance
//! of the polygon a sample sees, no noise) equals the renderer's reference image of the same
//! scene pixel for pixel, except where a pixel centre lies within the rasterizer's snapping
//! (1/256 pixel) of an edge, and there the renderer's colour is one a ray a little beside the
//! centre sees.

use std::path::Path;

use glam::{DVec3, Vec3};

use app::context::Context;
use app::context::Input;
use app::frames::render_frame;
use app::prepare::prepare;
use base::method::Method;
use base::progress::SILENT;
use engine::frame::FrameOptions;
use scene::bvh::Bvh;
use truth::{CameraRays, PixelFilter, TruthOptions};

/// The Cornell box with every polygon black and emitting its own colour; duplicated faces (the
/// same corners) get the same colour, so which of them wins a depth tie does not matter.
fn coloured_cornell() -> scene::Scene {
    let path = Path::new(crate::REPO).join("scenes/cornell-box.toml");
    let mut scene = scene::load_scene(&path).expect("the Cornell box loads");
    let n = scene.polygons.len();
    scene.materials = (0..n)
        .map(|i| scene::Material {
            name: format!("m{i}"),
            reflectance: DVec3::ZERO,
            emission: DVec3::new(1.0 + i as f64, 0.25 * (i % 5) as f64, 0.5),
        })
        .collect();
    for i in 0..n {
        let key = |p: &scene::Polygon| (p.centroid() * 1e6).round();
        let first = (0..i)
            .find(|&j| key(&scene.polygons[j]) == key(&scene.polygons[i]))
            .unwrap_or(i);
        scene.polygons[i].material = first as u32;
    }
    scene
}

#[test]
fn truth_sample_patterns_are_the_renderers() {
    for n in [1, 4, 16] {
        let aa = base::method::Aa::new("aa", n).unwrap();
        let ours = PixelFilter::Pattern(aa).positions().unwrap();
        let theirs = engine::raster::sample_offsets(aa);
        assert_eq!(ours.len(), theirs.len());
        for (a, b) in ours.iter().zip(theirs) {
            assert_eq!((a.0 as f32, a.1 as f32), *b, "aa {n}");
        }
    }
}

#[test]
fn truth_pixels_see_the_polygons_the_rasterizer_sees() {
    let scene = coloured_cornell();
    let (w, h) = (64u32, 64u32);
    let input = Input {
        path: scene.source.clone(),
        scene: scene.clone(),
        solution_file: None,
        estimator: Default::default(),
        sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
        input_limit: base::output::MAX_INPUT_BYTES,
    };
    let ctx = Context::default();
    let policy = reconstruction::texture::SizePolicy::Fixed(1);
    let p = prepare(&ctx, input, policy, scene.render.texel_placement).expect("solves");
    let frame = render_frame(
        &p,
        Method::Reference,
        &scene.camera,
        &FrameOptions::new(w, h),
    )
    .expect("renders");
    let opts = TruthOptions {
        width: w,
        height: h,
        samples_per_pixel: 1,
        filter: PixelFilter::Pattern(base::method::Aa::ONE),
        ..TruthOptions::new(&scene)
    };
    let img = truth::render(&scene, &opts, &SILENT).expect("traces");
    let rays = CameraRays::new(&scene.camera, w, h).unwrap();
    let bvh = Bvh::build(&scene.polygons);
    let colour_at = |px: f64, py: f64| {
        let (o, d) = rays.ray(px, py);
        match bvh.first_hit(o, d * 20.0, u32::MAX) {
            Some((k, _)) => scene.material_of(k as usize).emission.as_vec3(),
            None => scene.display.background.as_vec3(),
        }
    };
    let mut differ = 0;
    for j in 0..h {
        for i in 0..w {
            let (ours, theirs) = (img.mean.get(i, j), frame.pixels[(j * w + i) as usize]);
            if (ours - theirs).abs().max_element() <= 1e-6 * ours.abs().max_element() {
                continue;
            }
            differ += 1;
            let (cx, cy) = (i as f64 + 0.5, j as f64 + 0.5);
            let d = 1.0 / 256.0;
            let near: Vec<Vec3> = [(-d, 0.0), (d, 0.0), (0.0, -d), (0.0, d)]
                .iter()
                .map(|&(dx, dy)| colour_at(cx + dx, cy + dy))
                .collect();
            assert!(
                near.iter()
                    .any(|c| (*c - theirs).abs().max_element() < 1e-5),
                "pixel ({i}, {j}): truth {ours}, renderer {theirs}, near the centre {near:?}"
            );
        }
    }
    // Edges cross about 2,000 pixel widths of this image; a centre within 1/256 of one is rare.
    assert!(differ <= 16, "{differ} pixels differ");
}
