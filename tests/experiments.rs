//! The paper's experiments at reduced cost (128 x 128 images instead of 256 x 256, a depth-8
//! instead of depth-9 full sampling): the orderings the paper reported, and the direct method's
//! place among them.

use std::path::Path;

use pixelflow_sim::experiment::{fig5, fig6, spot_radius_10, Figure, FigureOptions};

fn opts(falloff: Option<f64>) -> FigureOptions {
    FigureOptions {
        size: 128,
        reference_depth: 8,
        first_spot_falloff: falloff,
        ..FigureOptions::paper(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/two-spots.toml"))
    }
}

fn d(f: &Figure, key: &str) -> f64 {
    f.distance(key)
        .unwrap_or_else(|| panic!("{} has no panel {key}", f.name))
}

/// The reconstructions of the coarse data (not the references).
const RECONSTRUCTIONS: [&str; 3] = ["bilinear", "bicubic", "direct"];

#[test]
fn fig6_bicubic_filtering_beats_bilinear_and_direct_beats_both() {
    // The shipped scene, as the paper's Fig. 6: an 8 x 8 texture resampled from the RRPs, drawn
    // with bilinear and Mitchell-Netravali filtering; the direct method needs no texture.
    let f = fig6(&opts(None)).unwrap();
    let (bl, bc, di) = (d(&f, "bilinear"), d(&f, "bicubic"), d(&f, "direct"));
    assert!(bc < bl, "bicubic {bc} should beat bilinear {bl}");
    assert!(di < bc && di < bl, "direct {di} vs {bc}, {bl}");
    // Nearest filtering of the 8 x 8 texture is the worst of all.
    assert!(d(&f, "texture") > bl);
    // C1 on-screen filtering leaves less Mach-band energy than C0 bilinear.
    let mach = |k: &str| {
        f.panel(k)
            .unwrap()
            .versus_reference
            .as_ref()
            .unwrap()
            .mach_band
    };
    assert!(mach("bicubic") < mach("bilinear"));
}

#[test]
fn fig5_ordering_holds_when_the_coarse_grid_resolves_the_spot() {
    // Falloff 15: the bright spot's 10 % radius is about one sample spacing of the 5 x 5 grid
    // (checked below), the regime of the paper's figure, where bicubic (RRP) resampling is closer
    // to the reference than bilinear, and the direct method (the same RRPs per pixel) with it.
    let o = opts(Some(15.0));
    assert!((spot_radius_10(15.0, 0.5) / 0.25 - 1.08).abs() < 0.01);
    let f = fig5(&o).unwrap();
    let (bl, bc, di) = (d(&f, "bilinear"), d(&f, "bicubic"), d(&f, "direct"));
    assert!(bc < bl, "bicubic {bc} should beat bilinear {bl}");
    for k in RECONSTRUCTIONS {
        assert!(di <= d(&f, k) + 1e-9, "direct {di} vs {k} {}", d(&f, k));
    }
    // (d) and (e) evaluate the same RRPs at the same points: equal up to f32 rounding of (u, v)
    // in the rasterizer (relative 1e-4 of a distance of order 1 is far above that rounding).
    assert!((di - bc).abs() < 1e-4 * bc, "{di} vs {bc}");
    // The raw 5 x 5 samples shown blockwise are far worse than any reconstruction.
    assert!(d(&f, "coarse") > 2.0 * bl);
}

#[test]
fn fig5_full_sampling_reference_hits_every_pixel_centre() {
    // Pixel centres of a 128 x 128 texture-space image are (2x + 1) / 256: lattice points of a
    // depth-8 quadtree, so the paper's full-sampling reference samples the oracle exactly where
    // the oracle reference does and their distance is 0.
    let f = fig5(&opts(None)).unwrap();
    assert_eq!(d(&f, "full"), 0.0);
    assert_eq!(d(&f, "reference"), 0.0);
    assert!(d(&f, "bilinear") > 0.1);
}

#[test]
fn spot_radius_formula() {
    // cos^(n+3)(theta) = 0.1 at the 10 % radius; n = 60, h = 0.5: theta = acos(0.1^(1/63)).
    let theta = 0.1f64.powf(1.0 / 63.0).acos();
    assert!((spot_radius_10(60.0, 0.5) - 0.5 * theta.tan()).abs() < 1e-15);
    assert!((spot_radius_10(60.0, 0.5) - 0.1378).abs() < 1e-3);
}
