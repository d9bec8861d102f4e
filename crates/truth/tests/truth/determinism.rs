//! Determinism: the same seed gives the same bits with one worker thread or two, for the image
//! and for the polygons; another seed gives other bits.

use glam::DVec3;

use crate::common::{furnace, spot_down};
use base::progress::SILENT;
use truth::{polygons, render, PolygonEstimate, TruthImage, TruthOptions};

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn image_bits(img: &TruthImage) -> Vec<u32> {
    img.mean
        .pixels
        .iter()
        .chain(&img.stderr.pixels)
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .collect()
}

fn polygon_bits(est: &[PolygonEstimate]) -> Vec<u64> {
    est.iter()
        .flat_map(|e| {
            [
                e.radiosity,
                e.radiosity_se,
                e.direct,
                e.direct_se,
                e.indirect,
                e.indirect_se,
            ]
        })
        .flat_map(|v| v.to_array().map(f64::to_bits))
        .collect()
}

#[test]
fn same_seed_same_bits_for_any_thread_count() {
    let mut scene = furnace(DVec3::new(0.6, 0.5, 0.4), DVec3::new(0.2, 0.1, 0.3));
    scene.spots = vec![spot_down(DVec3::new(0.5, 0.95, 0.5), 1.0, 60.0, 2.0)];
    let opts = TruthOptions {
        seed: 42,
        width: 13,
        height: 7,
        samples_per_pixel: 9,
        samples_per_polygon: 600,
        strata: 3,
        ..TruthOptions::new(&scene)
    };
    let run = |threads: usize, opts: &TruthOptions| {
        in_pool(threads, || {
            (
                render(&scene, opts, &SILENT).unwrap(),
                polygons(&scene, opts, &SILENT).unwrap(),
            )
        })
    };
    let (img1, poly1) = run(1, &opts);
    let (img2, poly2) = run(2, &opts);
    assert_eq!(image_bits(&img1), image_bits(&img2));
    assert_eq!(polygon_bits(&poly1), polygon_bits(&poly2));
    // 600 samples in 9 cells of pairs: rounded up to 34 pairs per cell.
    assert!(poly1.iter().all(|e| e.samples == 612));
    assert_eq!(img1.samples_per_pixel, 9);
    let other = TruthOptions { seed: 43, ..opts };
    let (img3, poly3) = run(2, &other);
    assert_ne!(image_bits(&img1), image_bits(&img3));
    assert_ne!(polygon_bits(&poly1), polygon_bits(&poly3));
}

/// An error target stops the run early, at the same pass for any thread count.
#[test]
fn an_error_target_stops_early_and_deterministically() {
    let scene = furnace(DVec3::splat(0.5), DVec3::ONE);
    let opts = TruthOptions {
        seed: 7,
        samples_per_pixel: 4096,
        samples_per_polygon: 1 << 20,
        max_error: Some(0.02),
        ..TruthOptions::new(&scene)
    };
    let (a, b) = (
        in_pool(1, || polygons(&scene, &opts, &SILENT).unwrap()),
        in_pool(2, || polygons(&scene, &opts, &SILENT).unwrap()),
    );
    assert_eq!(polygon_bits(&a), polygon_bits(&b));
    for e in &a {
        assert!(e.samples < 1 << 20, "{}", e.samples);
        let rel = e.radiosity_se / e.radiosity;
        assert!(rel.max_element() < 0.03, "{rel}");
    }
    let img = render(&scene, &opts, &SILENT).unwrap();
    assert!(img.samples_per_pixel < 4096 && img.samples_per_pixel >= 16);
    assert!(img.relative_error <= 0.02, "{}", img.relative_error);
}
