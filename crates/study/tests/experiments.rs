//! The paper's experiments at reduced cost (128 x 128 images instead of 256 x 256, a depth-8
//! instead of depth-9 full sampling): the orderings the paper reported, and the direct method's
//! place among them; the shipped two-spots scene's coarse samples; the narrow-spot hard case.

use std::path::{Path, PathBuf};

/// The repository root (scenes), from this crate's directory.
const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

use radiosity::{self, sizes::EDGE_INSET, Oracle, SolveOptions};
use scene::load_scene;
use study::experiment::{
    fig5, fig6, paper_misfit, spot_fraction_at, spot_radius_10, sweep_falloffs, sweep_half_angle,
    Figure, FigureOptions, CONE_EDGE_FRACTION, MAX_SWEEP_HALF_ANGLE_DEG, PAPER_FIG5, PAPER_FIG6,
};

fn scene_path(name: &str) -> PathBuf {
    Path::new(REPO).join(format!("scenes/{name}.toml"))
}

fn opts_of(name: &str, falloff: Option<f64>) -> FigureOptions {
    FigureOptions {
        size: 128,
        reference_depth: 8,
        first_spot_falloff: falloff,
        ..FigureOptions::paper(&scene_path(name))
    }
}

fn opts(falloff: Option<f64>) -> FigureOptions {
    opts_of("two-spots", falloff)
}

fn d(f: &Figure, key: &str) -> f64 {
    f.distance(key)
        .unwrap_or_else(|| panic!("{} has no panel {key}", f.name))
}

/// The reconstructions of the coarse data (not the references).
const RECONSTRUCTIONS: [&str; 3] = ["bilinear", "bicubic", "direct"];

#[test]
fn fig6_bicubic_filtering_beats_bilinear_and_direct_beats_bilinear() {
    // The shipped scene, as the paper's Fig. 6: an 8 x 8 texture resampled from the RRPs, drawn
    // with bilinear and Mitchell-Netravali filtering; the direct method needs no texture. Both
    // texel placements keep the paper's ordering on a spot the coarse grid resolves.
    let f = fig6(&opts(None)).unwrap();
    let (bl, bc, di) = (d(&f, "bilinear"), d(&f, "bicubic"), d(&f, "direct"));
    assert!(bc < bl, "bicubic {bc} should beat bilinear {bl}");
    let (cbl, cbc) = (d(&f, "corner-bilinear"), d(&f, "corner-bicubic"));
    assert!(
        cbc < cbl,
        "corner: bicubic {cbc} should beat bilinear {cbl}"
    );
    // With the gutters both placements reach the polygon's edges (no clamped half-texel
    // ring), so neither is better everywhere; each stays within a third of the other.
    for (c, e) in [(cbl, bl), (cbc, bc)] {
        assert!(
            c < 1.33 * e && e < 1.33 * c,
            "corner {cbl}, {cbc} vs centre {bl}, {bc}"
        );
    }
    // The direct method beats bilinear textures. Against the Mitchell-Netravali texture it is
    // level within 5 %: the texture's smoothing of the coarse RRP brings it as near the fine
    // reference as the RRP itself once the gutters carry it to the polygon's edges (the paper's
    // Fig. 6 scene, not the shipped one, is where its ordering is measured).
    for k in ["bilinear", "corner-bilinear"] {
        assert!(di < d(&f, k), "direct {di} vs {k} {}", d(&f, k));
    }
    for k in ["bicubic", "corner-bicubic"] {
        assert!(di < 1.05 * d(&f, k), "direct {di} vs {k} {}", d(&f, k));
    }
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
    assert!(mach("corner-bicubic") < mach("corner-bilinear"));
}

#[test]
fn fig5_ordering_holds_on_the_shipped_scene() {
    // The shipped bright spot is resolved by the 5 x 5 grid (its grid neighbours hold 41 % of
    // the peak, checked below and in shipped_two_spots_samples_match_the_formula), the regime
    // of the paper's figure: bicubic (RRP) resampling is closer to the reference than bilinear,
    // and the direct method (the same RRPs per pixel) with it.
    let f = fig5(&opts(None)).unwrap();
    let (bl, bc, di) = (d(&f, "bilinear"), d(&f, "bicubic"), d(&f, "direct"));
    assert!(bc < bl, "bicubic {bc} should beat bilinear {bl}");
    // (d) and (e) evaluate the same RRPs at the same points: equal up to f32 rounding of (u, v)
    // in the rasterizer (relative 1e-4 of a distance of order 1 is far above that rounding), so
    // direct is the closest reconstruction up to that rounding.
    assert!((di - bc).abs() < 1e-4 * bc, "{di} vs {bc}");
    for k in RECONSTRUCTIONS {
        assert!(
            di <= d(&f, k) * (1.0 + 1e-4),
            "direct {di} vs {k} {}",
            d(&f, k)
        );
    }
    // The raw 5 x 5 samples shown blockwise are far worse than any reconstruction.
    assert!(d(&f, "coarse") > 2.0 * bl);
    // C1 reconstruction: less Mach-band energy than bilinear's creases.
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
fn narrow_spot_is_the_hard_case() {
    // scenes/two-spots-narrow.toml: the bright spot's 10 % radius is about half the grid's
    // spacing and its grid neighbours hold under 0.1 % of the peak, so the 5 x 5 samples hold one
    // spike and nothing of the spot's width. Every reconstruction guesses a shape: bilinear a
    // pyramid, the monotone bicubic a plateau of the spacing's width, which is no better. So the
    // paper's Fig. 5 ordering does not hold there, and all reconstructions are several times
    // farther from the reference than on the shipped (resolved) scene.
    let s = load_scene(&scene_path("two-spots-narrow")).unwrap();
    let (n, h) = (s.spots[0].falloff, s.spots[0].position.z);
    assert!(spot_radius_10(n, h) / 0.25 < 0.6);
    assert!(spot_fraction_at(n, h, 0.25) < 1e-3);
    let narrow = fig5(&opts_of("two-spots-narrow", None)).unwrap();
    let (bl, bc) = (d(&narrow, "bilinear"), d(&narrow, "bicubic"));
    assert!(
        bc >= bl,
        "narrow spot: bicubic {bc} unexpectedly beats bilinear {bl}"
    );
    let wide = fig5(&opts(None)).unwrap();
    for k in RECONSTRUCTIONS {
        assert!(
            d(&narrow, k) > 2.0 * d(&wide, k),
            "{k}: narrow {} vs shipped {}",
            d(&narrow, k),
            d(&wide, k)
        );
    }
}

#[test]
fn shipped_two_spots_samples_match_the_formula() {
    // The criterion of scenes/two-spots.toml: the bright spot's four grid neighbours (0.25 from
    // the peak) hold 25-60 % of the peak. Each spot, pointing straight down from height h, leaves
    // B = rho I cos^(n+3)(theta) / h^2 on the plane; the solver's oracle must give the sum of the
    // two spots' B at the coarse grid's samples (one plane, nothing else to reflect light), up
    // to f32 rounding of its result (relative 1e-6; 1e-5 leaves a margin). The oracle evaluates
    // edge samples EDGE_INSET (1e-6) inside the square, so the formula is taken there too.
    let path = scene_path("two-spots");
    let scene = load_scene(&path).unwrap();
    let solution = radiosity::solve(&scene, &SolveOptions::default()).unwrap();
    let oracle = Oracle::new(&solution, &scene).unwrap();
    let rho = scene.materials[0].reflectance.x;
    let formula = |u: f64, v: f64| -> f64 {
        scene
            .spots
            .iter()
            .map(|s| {
                let (dx, dy, h) = (u - s.position.x, v - s.position.y, s.position.z);
                let c = h / (dx * dx + dy * dy + h * h).sqrt();
                assert!(c > s.half_angle.cos(), "the cone must cover the sample");
                rho * s.intensity.x * c.powf(s.falloff + 3.0) / (h * h)
            })
            .sum()
    };
    let grid = [0.0, 0.25, 0.5, 0.75, 1.0];
    let inset = |x: f64| x.clamp(EDGE_INSET, 1.0 - EDGE_INSET);
    for &u in &grid {
        for &v in &grid {
            let got = oracle.radiosity(0, u, v).x as f64;
            let want = formula(inset(u), inset(v));
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "({u}, {v}): {got} vs {want}"
            );
        }
    }
    // The values the scene's comments state (3 decimals).
    let peak = formula(0.25, 0.75);
    assert!((peak - 3.281).abs() < 5e-4, "peak {peak}");
    for ((u, v), want) in [
        ((0.0, 0.75), 1.338),
        ((0.25, 1.0), 1.338),
        ((0.5, 0.75), 1.472),
        ((0.25, 0.5), 1.472),
        ((0.5, 0.5), 1.000),
        ((0.0, 1.0), 0.643),
    ] {
        assert!(
            (formula(u, v) - want).abs() < 5e-4,
            "({u}, {v}): {}",
            formula(u, v)
        );
        // Every grid neighbour of the peak is clearly lower than it and far from zero.
        let frac = formula(u, v) / peak;
        assert!((0.15..0.6).contains(&frac), "({u}, {v}): {frac}");
    }
    // The bright spot alone: its four neighbours hold 0.8^4 = 41 % of its peak.
    let (n, h) = (scene.spots[0].falloff, scene.spots[0].position.z);
    let f = spot_fraction_at(n, h, 0.25);
    assert!((f - 0.8f64.powi(4)).abs() < 1e-12 && (0.25..=0.6).contains(&f));
    // Its cone covers the whole plane: the farthest corner, (1, 0), is inside it.
    let s = &scene.spots[0];
    let far = (0.75f64.hypot(0.75) / h).atan();
    assert!(far < s.half_angle && s.half_angle.cos().powf(n) <= CONE_EDGE_FRACTION);
}

#[test]
fn sweep_widens_the_cone_with_the_spot() {
    let scene_half = 40f64.to_radians();
    // Falloff 60: cos^60 = 1e-6 at 31.7 deg, narrower than the scene's 40: the scene's stays.
    assert_eq!(sweep_half_angle(60.0, scene_half), scene_half);
    // Falloff 8: 1e-6 at acos(1e-6^(1/8)) = 86.0 deg, where cos^8 is 1e-6.
    let a = sweep_half_angle(8.0, scene_half);
    assert!((a.cos().powf(8.0) - CONE_EDGE_FRACTION).abs() < 1e-12 && a > scene_half);
    // Falloff 1 or 0 would need 90 deg or more: capped just below.
    let cap = MAX_SWEEP_HALF_ANGLE_DEG.to_radians();
    assert_eq!(sweep_half_angle(1.0, scene_half), cap);
    assert_eq!(sweep_half_angle(0.0, scene_half), cap);
}

#[test]
fn sweep_runs_from_the_narrow_spot_to_wide_ones_with_the_scenes_own() {
    // Narrowest first, the narrow scene's 60 and the shipped scene's 5 among them, each once.
    assert_eq!(
        sweep_falloffs(Some(5.0)),
        [60.0, 40.0, 30.0, 25.0, 22.0, 20.0, 18.0, 15.0, 12.0, 8.0, 5.0, 3.0, 1.0]
    );
    assert_eq!(sweep_falloffs(Some(60.0)).len(), 12);
}

#[test]
fn paper_misfit_measures_the_shape_of_the_four_distances() {
    // (bilinear, bicubic) pairs, as the sweep holds them.
    let (p5, p6) = (PAPER_FIG5, PAPER_FIG6);
    // The paper's numbers times any one factor fit exactly.
    let m = paper_misfit((3.0 * p5.1, 3.0 * p5.0), (3.0 * p6.1, 3.0 * p6.0));
    assert!(m < 1e-12, "{m}");
    // One distance e^0.4 too large: r = (0.4, 0, 0, 0), mean 0.1, deviations (0.3, -0.1 x 3),
    // rms sqrt((0.09 + 3 x 0.01) / 4) = sqrt(0.03).
    let m = paper_misfit((p5.1, p5.0 * 0.4f64.exp()), (p6.1, p6.0));
    assert!((m - 0.03f64.sqrt()).abs() < 1e-12, "{m}");
    // Equal distances everywhere miss the two ratios and Fig. 6 against Fig. 5.
    assert!(paper_misfit((1.0, 1.0), (1.0, 1.0)) > 0.3);
    assert!(paper_misfit((0.0, 1.0), (1.0, 1.0)).is_nan());
}

#[test]
fn sweep_falloff_changes_only_the_width() {
    // With the first spot's falloff set to the narrow scene's (60) and its cone widened, the
    // shipped scene is the narrow scene up to the cone: the cone edge of the narrow scene
    // (40 deg) cuts at cos^60 = 1e-7 of the peak, invisible, so the figures agree closely.
    let swept = fig5(&opts(Some(60.0))).unwrap();
    let narrow = fig5(&opts_of("two-spots-narrow", None)).unwrap();
    for k in RECONSTRUCTIONS {
        let (a, b) = (d(&swept, k), d(&narrow, k));
        assert!((a - b).abs() <= 1e-3 * b, "{k}: swept {a} vs narrow {b}");
    }
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

#[test]
fn the_fitted_scene_keeps_the_papers_ratios() {
    // The figures' default scene, its bright spot's width fitted to the paper's four distances
    // (docs/experiments.md, at 256 x 256 and a depth-9 reference). At this test's reduced cost
    // the ratios stay in the bands the paper's numbers allow for a different metric: Fig. 5
    // bicubic / bilinear 0.90-0.96 (the paper 0.933), Fig. 6 0.72-0.94 (the paper 0.766), and
    // the direct method closest to the reference in both.
    let o = opts_of("two-spots-paper", None);
    let (f5, f6) = (fig5(&o).unwrap(), fig6(&o).unwrap());
    let r5 = d(&f5, "bicubic") / d(&f5, "bilinear");
    let r6 = d(&f6, "bicubic") / d(&f6, "bilinear");
    eprintln!("fitted scene at reduced cost: fig5 ratio {r5:.3}, fig6 ratio {r6:.3}");
    assert!((0.90..=0.96).contains(&r5), "fig5 ratio {r5}");
    assert!((0.72..=0.94).contains(&r6), "fig6 ratio {r6}");
    let di = d(&f6, "direct");
    for k in [
        "bilinear",
        "bicubic",
        "corner-bilinear",
        "corner-bicubic",
        "clamp-bilinear",
        "clamp-bicubic",
    ] {
        assert!(di < d(&f6, k), "direct {di} vs {k} {}", d(&f6, k));
    }
    // Clamped to the edge (the paper's hardware) the filters hold the edge texel's value over
    // the outer half texel instead of continuing the RRP there, so both filters are farther
    // from the reference than with the gutters, and the paper's ordering still holds.
    let (kl, kc) = (d(&f6, "clamp-bilinear"), d(&f6, "clamp-bicubic"));
    eprintln!(
        "clamped: bilinear {kl:.4}, bicubic {kc:.4}, ratio {:.3}",
        kc / kl
    );
    assert!(kc < kl, "clamped: bicubic {kc} vs bilinear {kl}");
    assert!(kl > d(&f6, "bilinear") && kc > d(&f6, "bicubic"));
    assert!(d(&f5, "direct") <= d(&f5, "bicubic").min(d(&f5, "bilinear")) * (1.0 + 1e-4));
}
