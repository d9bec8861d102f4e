//! The furnace: a closed box whose every face emits E and reflects rho is uniformly bright,
//! B = E / (1 - rho) everywhere, with direct part rho E (the irradiance of a uniform enclosure
//! of exitance E is E) and indirect part E rho^2 / (1 - rho). Every estimate must fall within
//! four of its standard errors of these, and the errors must be honest: over independent seeds
//! and faces, the z-scores' mean square must be near 1.

use glam::DVec3;

use crate::common::{furnace, mean_square};
use base::progress::SILENT;
use truth::{polygons, render, PixelFilter, TruthOptions};

const RHO: DVec3 = DVec3::new(0.5, 0.3, 0.7);
const E: DVec3 = DVec3::new(1.0, 2.0, 0.5);

fn expected() -> (DVec3, DVec3, DVec3) {
    let b = E / (DVec3::ONE - RHO);
    (b, RHO * E, E * RHO * RHO / (DVec3::ONE - RHO))
}

/// The z-scores of one estimate's three channels against `want`.
fn z(got: DVec3, se: DVec3, want: DVec3) -> [f64; 3] {
    ((got - want) / se).to_array()
}

#[test]
fn every_face_is_e_over_one_minus_rho_with_honest_errors() {
    let scene = furnace(RHO, E);
    let (b, direct, indirect) = expected();
    let mut zs: Vec<f64> = Vec::new();
    let seeds = 16;
    for seed in 0..seeds {
        let opts = TruthOptions {
            seed,
            samples_per_polygon: 2048,
            ..TruthOptions::new(&scene)
        };
        for e in polygons(&scene, &opts, &SILENT).unwrap() {
            assert_eq!(e.samples, 2048);
            for (got, se, want) in [
                (e.radiosity, e.radiosity_se, b),
                (e.direct, e.direct_se, direct),
                (e.indirect, e.indirect_se, indirect),
            ] {
                let zz = z(got, se, want);
                assert!(
                    zz.iter().all(|z| z.abs() < 4.0),
                    "seed {seed} face {}: {got} +- {se}, want {want}",
                    e.polygon
                );
            }
            // The errors are small enough for the check to mean something: 2 % of B.
            assert!(
                (e.radiosity_se / b).max_element() < 0.02,
                "{}",
                e.radiosity_se
            );
            zs.extend(z(e.radiosity, e.radiosity_se, b));
        }
    }
    // 16 seeds x 6 faces x 3 channels; the channels of one face share their paths, so about 96
    // independent values: chi-square with ~96 degrees of freedom divided by 96 has sd ~0.14.
    // Errors under- or overstated by a third would put the mean square near 2.25 or 0.44.
    let ms = mean_square(&zs);
    assert!(
        ms > 0.6 && ms < 1.6,
        "mean square z {ms} over {} values",
        zs.len()
    );
}

#[test]
fn every_pixel_inside_the_furnace_is_e_over_one_minus_rho() {
    let scene = furnace(RHO, E);
    let (b, _, _) = expected();
    let opts = TruthOptions {
        seed: 5,
        samples_per_pixel: 256,
        ..TruthOptions::new(&scene)
    };
    let img = render(&scene, &opts, &SILENT).unwrap();
    assert_eq!(img.samples_per_pixel, 256);
    assert_eq!(img.back_face_samples, 0);
    let mut zs = Vec::new();
    for (m, se) in img.mean.pixels.iter().zip(&img.stderr.pixels) {
        let zz = z(m.as_dvec3(), se.as_dvec3(), b);
        assert!(zz.iter().all(|z| z.abs() < 5.0), "{m} +- {se}, want {b}");
        zs.extend(zz);
    }
    // 256 pixels x 3 channels of 256 samples each. A pixel's samples are skewed (a few long
    // paths carry much of the light, most of it in the channel that reflects most), so with few
    // samples a low mean comes with a low sample variance and the z-scores have heavy tails; at
    // 256 samples they are close to normal (at 32, one pixel in 256 was 7 sd off).
    let ms = mean_square(&zs);
    assert!(ms > 0.8 && ms < 1.25, "mean square z {ms}");
    // The renderer's pattern: the same expected value.
    let centre = TruthOptions {
        filter: PixelFilter::Pattern(base::method::Aa::new("aa", 4).unwrap()),
        ..opts
    };
    let img = render(&scene, &centre, &SILENT).unwrap();
    let mean: DVec3 = img.mean.pixels.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / 256.0;
    assert!(((mean - b) / b).abs().max_element() < 0.02, "{mean}");
}

/// A bounce limit truncates the series: with at most one reflection before the point,
/// B = E + rho E + rho^2 E.
#[test]
fn a_bounce_limit_truncates_the_series() {
    let scene = furnace(RHO, E);
    let opts = TruthOptions {
        seed: 3,
        samples_per_polygon: 4096,
        max_bounces: Some(1),
        ..TruthOptions::new(&scene)
    };
    let want = E + RHO * E + RHO * RHO * E;
    for e in polygons(&scene, &opts, &SILENT).unwrap() {
        let zz = z(e.radiosity, e.radiosity_se, want);
        assert!(
            zz.iter().all(|z| z.abs() < 4.0),
            "{} +- {}, want {want}",
            e.radiosity,
            e.radiosity_se
        );
    }
}
