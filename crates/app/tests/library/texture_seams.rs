//! Texture seams end to end: a floor split in two under an area light whose footprint crosses
//! the split, solved and prepared as `render` prepares it (joined seams, the size policy's
//! sides, the textures' gutters). Both textures are sampled along the shared edge from their
//! own side; the aim is a step of at most 1e-3 of the floor's peak, for bilinear and
//! Mitchell-Netravali filtering, at both texel placements, magnified and on coarser mip levels.

use glam::DVec3;

use app::context::Context;
use app::context::Input;
use app::prepare::prepare;
use app::prepare::Prepared;
use base::method::{Filter, Placement};
use fixtures::closed_form::{camera, material, rect};
use reconstruction::texture::{RadiosityTexture, Sampler, SizePolicy};
use reconstruction::Estimator;
use scene::Scene;

/// Polygons 0 and 1 are the floor halves x in [-2, 0] and [0, 2] (y in [-2, 2]); 2 the light,
/// off-centre across the split so the light varies along and across the seam.
fn split_floor() -> Scene {
    let left = rect(-2.0, 0.0, -2.0, 2.0, 0.0, DVec3::Z, 0);
    let right = rect(0.0, 2.0, -2.0, 2.0, 0.0, DVec3::Z, 0);
    let light = rect(-0.3, 0.5, -0.7, 0.1, 1.0, -DVec3::Z, 1);
    let materials = vec![
        material("floor", [0.6; 3], [0.0; 3]),
        material("light", [0.0; 3], [4.0; 3]),
    ];
    Scene::new(camera(), 64, 64, materials, vec![left, right, light])
}

fn prepared(scene: &Scene, placement: Placement) -> Prepared {
    let input = Input {
        path: "split-floor.toml".into(),
        scene: scene.clone(),
        solution_file: None,
        estimator: Estimator::default(),
        sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
        input_limit: base::output::MAX_INPUT_BYTES,
    };
    prepare(&Context::default(), input, SizePolicy::FromDepth, placement).expect("solves")
}

/// Largest step along the seam (left's u = 1 against right's u = 0, one v for both) between
/// two textures, filtered with `filter` at level of detail `lod`.
fn step(a: &RadiosityTexture, b: &RadiosityTexture, filter: Filter, lod: f32) -> f64 {
    let s = Sampler::new(filter);
    (0..=400)
        .map(|k| {
            let v = k as f32 / 400.0;
            let (x, y) = (s.sample(a, lod, 1.0, v), s.sample(b, lod, 0.0, v));
            (x - y).abs().max_element() as f64
        })
        .fold(0.0, f64::max)
}

#[test]
fn textures_of_a_split_floor_meet_along_the_seam() {
    let scene = split_floor();
    // The seam is left's u = 1 and right's u = 0 at one v.
    for k in 0..=8 {
        let v = k as f64 / 8.0;
        let d = scene.polygons[0].point(1.0, v) - scene.polygons[1].point(0.0, v);
        assert!(
            d.length() < 1e-12,
            "the halves' parameters differ along the seam"
        );
    }
    for placement in [Placement::Centre, Placement::Corner] {
        let p = prepared(&scene, placement);
        assert_eq!(p.seams.joined(), 1, "the split is joined");
        let (rec, _) = p.expanded().unwrap();
        let peak = (0..=64)
            .flat_map(|j| (0..=64).map(move |i| (i, j)))
            .flat_map(|(i, j)| [0, 1].map(|q| rec.eval(q, i as f32 / 64.0, j as f32 / 64.0).x))
            .fold(0.0f32, f32::max) as f64;
        let (set, _) = p.textures().unwrap();
        let (a, b) = (&set.textures[0], &set.textures[1]);
        let depths: Vec<u32> = p
            .texture_extents()
            .unwrap()
            .iter()
            .map(|e| e.depth)
            .collect();
        // Clamp-to-edge textures of the same sides, for comparison.
        let (ca, cb) = (
            RadiosityTexture::from_rrp(rec, 0, (a.width, a.height), placement, 0),
            RadiosityTexture::from_rrp(rec, 1, (b.width, b.height), placement, 0),
        );
        for filter in [Filter::Bilinear, Filter::MITCHELL] {
            for lod in [0.0, 1.0, 2.5] {
                let s = step(a, b, filter, lod) / peak;
                let c = step(&ca, &cb, filter, lod) / peak;
                eprintln!(
                    "split floor {placement:?} {filter:?} lod {lod}: sides {} and {} (depths \
                     {:?}), step {s:.2e} of the peak with gutters, {c:.2e} clamped to the edge",
                    a.width,
                    b.width,
                    &depths[..2]
                );
                assert!(
                    s <= 1e-3,
                    "{placement:?} {filter:?} lod {lod}: step {s:.2e}"
                );
                if placement == Placement::Centre {
                    // Without the gutter each side clamps half a texel inside: the defect the
                    // gutters remove is larger than the aim here.
                    assert!(c > 1e-3, "{filter:?} lod {lod}: clamped step only {c:.2e}");
                }
            }
        }
    }
}
