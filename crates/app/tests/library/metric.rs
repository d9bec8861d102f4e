//! The metric module against its definition: the perceptual distance's invariances, its growth
//! with blur and noise, a small case computed by a plain O(N^4) DFT written here (so the FFT path
//! is checked independently), the Mach-band measure on piecewise-linear vs C1 reconstructions,
//! and the image readers (PFM, PNG, EXR, HDR) with their errors.

use std::f64::consts::PI;
use std::io::Cursor;
use std::path::{Path, PathBuf};

use app::commands::compare::compare_files;
use glam::Vec3;
use image::{ImageBuffer, ImageFormat, Rgb};
use imageio::{decode_image, read_image, srgb_decode, srgb_encode, to_srgb8};
use metric::{compare, perceptual_distance, LinearImage};
use proptest::prelude::*;

fn grey(w: u32, h: u32, f: impl Fn(u32, u32) -> f64) -> LinearImage {
    LinearImage::from_fn(w, h, |x, y| Vec3::splat(f(x, y) as f32))
}

fn scaled(img: &LinearImage, k: f32) -> LinearImage {
    LinearImage {
        pixels: img.pixels.iter().map(|p| *p * k).collect(),
        ..img.clone()
    }
}

fn dist(a: &LinearImage, b: &LinearImage) -> f64 {
    perceptual_distance(a, b, 32.0).unwrap()
}

/// A positive, coloured, textured test image: a checkerboard of 8-pixel cells under two
/// sinusoids, luminance in about [0.15, 1.3].
fn textured(w: u32, h: u32) -> LinearImage {
    LinearImage::from_fn(w, h, |x, y| {
        let checker = if (x / 8 + y / 8) % 2 == 0 { 0.3 } else { 0.0 };
        let s = 0.25 * (2.0 * PI * x as f64 / 23.0).sin() * (2.0 * PI * y as f64 / 17.0).cos();
        let v = (0.6 + checker + s) as f32;
        Vec3::new(v * 1.1, v, v * 0.8)
    })
}

/// Box blur of radius r (a (2r+1)^2 window), edges clamped.
fn box_blur(img: &LinearImage, r: i64) -> LinearImage {
    let (w, h) = (img.width as i64, img.height as i64);
    LinearImage::from_fn(img.width, img.height, |x, y| {
        let mut s = Vec3::ZERO;
        for dy in -r..=r {
            for dx in -r..=r {
                let xx = (x as i64 + dx).clamp(0, w - 1) as u32;
                let yy = (y as i64 + dy).clamp(0, h - 1) as u32;
                s += img.get(xx, yy);
            }
        }
        s / ((2 * r + 1) * (2 * r + 1)) as f32
    })
}

/// Uniform in [-1, 1), from the project's seeded generator.
fn noise(seed: u64, n: usize) -> Vec<f64> {
    let mut r = base::rng::Rng::new(seed);
    (0..n).map(|_| r.next_f64() * 2.0 - 1.0).collect()
}

// ---------------------------------------------------------------------------------------------
// Perceptual distance

#[test]
fn identical_images_are_at_distance_zero() {
    for (w, h) in [(1, 1), (4, 4), (5, 3), (64, 48)] {
        let a = textured(w, h);
        assert_eq!(dist(&a, &a), 0.0, "{w} x {h}");
    }
}

#[test]
fn scaling_by_a_constant_changes_nothing() {
    let a = textured(32, 24);
    let b = box_blur(&a, 2);
    let d = dist(&a, &b);
    assert!(d > 0.0);
    // A power of two scales every luminance and the mean exactly, so Y / mean(Y) is bit-identical:
    // distance(a, 8 a) is exactly 0 and distance(8 a, 8 b) exactly distance(a, b).
    assert_eq!(dist(&a, &scaled(&a, 8.0)), 0.0);
    assert_eq!(dist(&scaled(&a, 8.0), &scaled(&b, 8.0)), d);
    // Any other factor: the f32 pixels are rounded once (relative 2^-24 = 6e-8), which moves
    // L = cbrt(Y') by a third of that and the CSF-weighted norm (A <= 0.981, L of order 1) by
    // well under 1e-6.
    let k = 3.7;
    assert!(dist(&a, &scaled(&a, k)) < 1e-6);
    assert!((dist(&scaled(&a, k), &scaled(&b, k)) - d).abs() < 1e-6);
    // Scaling only one image of a different pair changes nothing either.
    assert!((dist(&scaled(&a, 0.01), &b) - d).abs() < 1e-6);
}

#[test]
fn distance_grows_with_blur_radius() {
    let a = textured(64, 64);
    let d: Vec<f64> = (1..=5).map(|r| dist(&box_blur(&a, r), &a)).collect();
    for i in 1..d.len() {
        assert!(d[i] > d[i - 1], "blur distances not increasing: {d:?}");
    }
    assert!(d[0] > 0.0);
}

#[test]
fn distance_grows_with_noise_amplitude() {
    let a = textured(64, 64);
    let n = noise(7, a.pixels.len());
    let amps = [0.01, 0.02, 0.05, 0.1, 0.2];
    let d: Vec<f64> = amps
        .iter()
        .map(|&amp| {
            // Luminance stays positive: the image's minimum is about 0.15 > amp.
            let b = LinearImage {
                pixels: a
                    .pixels
                    .iter()
                    .zip(&n)
                    .map(|(p, &z)| *p + Vec3::splat((amp * z) as f32))
                    .collect(),
                ..a.clone()
            };
            dist(&b, &a)
        })
        .collect();
    for i in 1..d.len() {
        assert!(d[i] > d[i - 1], "noise distances not increasing: {d:?}");
    }
}

/// The metric of docs/metrics.md written out as plainly as possible, with an O(W^2 H^2) DFT, independent of the
/// module's code.
fn direct_distance(a: &[f64], b: &[f64], w: usize, h: usize, ppd: f64) -> f64 {
    let l = |y: &[f64]| -> Vec<f64> {
        let m = y.iter().sum::<f64>() / y.len() as f64;
        y.iter().map(|v| (v / m).cbrt()).collect()
    };
    let (la, lb) = (l(a), l(b));
    let freq = |k: usize, n: usize| {
        if (k as f64) < n as f64 / 2.0 {
            k as f64 / n as f64
        } else {
            (k as f64 - n as f64) / n as f64
        }
    };
    let mut sum = 0.0;
    for ky in 0..h {
        for kx in 0..w {
            let (mut re1, mut im1, mut re2, mut im2) = (0.0, 0.0, 0.0, 0.0);
            for y in 0..h {
                for x in 0..w {
                    let ph = -2.0
                        * PI
                        * (kx as f64 * x as f64 / w as f64 + ky as f64 * y as f64 / h as f64);
                    re1 += la[y * w + x] * ph.cos();
                    im1 += la[y * w + x] * ph.sin();
                    re2 += lb[y * w + x] * ph.cos();
                    im2 += lb[y * w + x] * ph.sin();
                }
            }
            let f = (freq(kx, w).powi(2) + freq(ky, h).powi(2)).sqrt() * ppd;
            let a = 2.6 * (0.0192 + 0.114 * f) * (-(0.114 * f).powf(1.1)).exp();
            sum += a * a * ((re1 - re2).powi(2) + (im1 - im2).powi(2));
        }
    }
    (sum / (w * h) as f64).sqrt()
}

#[test]
fn a_small_case_matches_a_direct_dft() {
    // 4 x 4, grey 0.5 with one pixel changed to 1.0, and a non-square odd case, at two ppd.
    // Both paths sum a few dozen terms of order 1 in f64: they agree to ~1e-15; 1e-9 is the
    // issue's bound.
    let a4 = grey(4, 4, |_, _| 0.5);
    let b4 = grey(4, 4, |x, y| if (x, y) == (1, 2) { 1.0 } else { 0.5 });
    let c5 = grey(5, 3, |x, y| 0.2 + 0.1 * x as f64 + 0.05 * (y * y) as f64);
    let d5 = grey(5, 3, |x, y| {
        if (x, y) == (4, 0) {
            2.0
        } else {
            0.2 + 0.1 * x as f64 + 0.05 * (y * y) as f64
        }
    });
    for (a, b) in [(&a4, &b4), (&c5, &d5)] {
        for ppd in [32.0, 5.0] {
            let (w, h) = (a.width as usize, a.height as usize);
            let expect = direct_distance(&a.luminance(), &b.luminance(), w, h, ppd);
            let got = perceptual_distance(a, b, ppd).unwrap();
            assert!(
                (got - expect).abs() < 1e-9,
                "{w} x {h} at ppd {ppd}: {got} vs {expect}"
            );
            assert!(expect > 1e-3, "the case must not be trivial: {expect}");
        }
    }
}

#[test]
fn the_4x4_case_has_a_closed_form_dc_term() {
    // A constant image against the same image with one pixel changed, at ppd -> 0: every bin is
    // at f = 0 where A = 0.04992, and by Parseval sum |F1 - F2|^2 = W H sum (L_a - L_b)^2, so
    // D = 0.04992 sqrt(sum (L_a - L_b)^2) (an L2 norm over pixels, not an RMS). With a = 0.5
    // everywhere, L_a = 1; b has mean (15 * 0.5 + 1) / 16 = 0.53125, so L_b is
    // cbrt(0.5 / 0.53125) at 15 pixels and cbrt(1 / 0.53125) at one.
    let a = grey(4, 4, |_, _| 0.5);
    let b = grey(4, 4, |x, y| if (x, y) == (1, 2) { 1.0 } else { 0.5 });
    let lo = (0.5f64 / 0.53125).cbrt() - 1.0;
    let hi = (1.0f64 / 0.53125).cbrt() - 1.0;
    let want = 0.04992 * (15.0 * lo * lo + hi * hi).sqrt();
    let d = perceptual_distance(&a, &b, 1e-12).unwrap();
    // A(f) at f below 1e-12 cpd differs from A(0) by under 2.6 * 0.114 * 1e-12: negligible.
    assert!((d - want).abs() < 1e-12, "{d} vs {want}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn symmetric_and_zero_on_the_diagonal(
        w in 1u32..9, h in 1u32..9, seed in any::<u64>(), seed2 in any::<u64>()
    ) {
        let n = (w * h) as usize;
        let za = noise(seed, n);
        let zb = noise(seed2, n);
        let a = grey(w, h, |x, y| 1.0 + 0.9 * za[(y * w + x) as usize]);
        let b = grey(w, h, |x, y| 1.0 + 0.9 * zb[(y * w + x) as usize]);
        // |F1 - F2|^2 = |F2 - F1|^2 exactly in floating point (negation is exact).
        prop_assert_eq!(dist(&a, &b), dist(&b, &a));
        prop_assert_eq!(dist(&a, &a), 0.0);
        let c = compare(&a, &b, 32.0).unwrap();
        prop_assert!(c.perceptual_distance.is_finite() && c.mach_band.is_finite());
        prop_assert_eq!(c.mach_band, compare(&b, &a, 32.0).unwrap().mach_band);
    }
}

// ---------------------------------------------------------------------------------------------
// Mach-band measure

/// The smooth test function, its derivatives d/dx, d/dy, d2/dxdy, on a 128-pixel square.
fn smooth(x: f64, y: f64) -> [f64; 4] {
    let (kx, ky) = (2.0 * PI * 1.3 / 128.0, 2.0 * PI * 0.9 / 128.0);
    let (sx, cx) = (kx * x + 0.4).sin_cos();
    let (sy, cy) = (ky * y + 0.2).sin_cos();
    [
        1.0 + 0.5 * sx * cy,
        0.5 * kx * cx * cy,
        -0.5 * ky * sx * sy,
        -0.5 * kx * ky * cx * sy,
    ]
}

#[test]
fn mach_band_separates_piecewise_linear_from_c1() {
    // Knots every S = 16 pixels (a 9 x 9 lattice over 128 x 128, like an element or texel grid).
    // The piecewise-linear (bilinear) reconstruction has kinks at every knot line; the bicubic
    // Hermite one, with the function's own derivatives at the knots, is C1. The reference is the
    // function itself.
    const N: u32 = 128;
    const S: f64 = 16.0;
    let reference = grey(N, N, |x, y| smooth(x as f64, y as f64)[0]);
    let cell = |p: f64| {
        let i = (p / S).floor().min(N as f64 / S - 1.0);
        (i * S, p / S - i)
    };
    let bilinear = grey(N, N, |x, y| {
        let ((x0, s), (y0, t)) = (cell(x as f64), cell(y as f64));
        let g = |dx: f64, dy: f64| smooth(x0 + dx * S, y0 + dy * S)[0];
        (1.0 - s) * (1.0 - t) * g(0.0, 0.0)
            + s * (1.0 - t) * g(1.0, 0.0)
            + (1.0 - s) * t * g(0.0, 1.0)
            + s * t * g(1.0, 1.0)
    });
    // Cubic Hermite basis: value weights h0 (at 0), h1 (at 1); derivative weights d0, d1.
    let basis = |s: f64| {
        let (s2, s3) = (s * s, s * s * s);
        [
            2.0 * s3 - 3.0 * s2 + 1.0,
            -2.0 * s3 + 3.0 * s2,
            s3 - 2.0 * s2 + s,
            s3 - s2,
        ]
    };
    let bicubic = grey(N, N, |x, y| {
        let ((x0, s), (y0, t)) = (cell(x as f64), cell(y as f64));
        let (bs, bt) = (basis(s), basis(t));
        let mut v = 0.0;
        for i in 0..2 {
            for j in 0..2 {
                let g = smooth(x0 + i as f64 * S, y0 + j as f64 * S);
                // Derivatives per unit of the local parameter: times S (S^2 for the twist).
                v += bs[i] * bt[j] * g[0]
                    + bs[2 + i] * bt[j] * g[1] * S
                    + bs[i] * bt[2 + j] * g[2] * S
                    + bs[2 + i] * bt[2 + j] * g[3] * S * S;
            }
        }
        v
    });
    let pl = compare(&bilinear, &reference, 32.0).unwrap();
    let c1 = compare(&bicubic, &reference, 32.0).unwrap();
    assert_eq!(
        compare(&reference, &reference, 32.0).unwrap().mach_band,
        0.0
    );
    // Estimate (see the mach module doc): kinks of about g'' S = 0.5 (2 pi 1.3 / 128)^2 16 = 0.03
    // every 16 pixels against a C1 error of order g''' S = 0.002, squared: a ratio of hundreds at
    // least (measured: 6.6e-6 vs 7.3e-10, about 9000); assert 100.
    assert!(
        pl.mach_band > 100.0 * c1.mach_band,
        "piecewise-linear {:e} vs C1 {:e}",
        pl.mach_band,
        c1.mach_band
    );
    assert!(c1.mach_band > 0.0);
    // The perceptual distance orders them the same way (what the paper's Fig. 5 shows).
    assert!(pl.perceptual_distance > c1.perceptual_distance);
}

// ---------------------------------------------------------------------------------------------
// Image input

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("metric");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// A PFM file: `rows_top_down[y][x]` written bottom row first, little- or big-endian.
fn pfm(rows_top_down: &[Vec<[f32; 3]>], little: bool) -> Vec<u8> {
    let (w, h) = (rows_top_down[0].len(), rows_top_down.len());
    let mut out = format!("PF\n{w} {h}\n{}\n", if little { "-1.0" } else { "1.0" }).into_bytes();
    for row in rows_top_down.iter().rev() {
        for p in row {
            for c in p {
                out.extend_from_slice(&if little {
                    c.to_le_bytes()
                } else {
                    c.to_be_bytes()
                });
            }
        }
    }
    out
}

#[test]
fn pfm_reads_both_endiannesses_top_row_first() {
    let rows = vec![
        vec![[1.0, 2.0, 3.0], [0.5, 0.25, -0.125]],
        vec![[4.0, 5.0, 6.0], [1e-3, 1e3, 7.5]],
        vec![[0.0, 0.0, 0.0], [9.0, 8.0, 7.0]],
    ];
    for little in [true, false] {
        let path = tmp(if little { "le.pfm" } else { "be.pfm" });
        std::fs::write(&path, pfm(&rows, little)).unwrap();
        let img = read_image(&path).unwrap();
        assert_eq!((img.width, img.height), (2, 3));
        for (y, row) in rows.iter().enumerate() {
            for (x, p) in row.iter().enumerate() {
                assert_eq!(
                    img.get(x as u32, y as u32),
                    Vec3::from_array(*p),
                    "({x}, {y})"
                );
            }
        }
    }
    // Greyscale "Pf": one float per pixel, R = G = B.
    let mut bytes = b"Pf 2 1 -1\n".to_vec();
    for v in [0.25f32, 2.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let img = decode_image(&bytes, Path::new("g.pfm")).unwrap();
    assert_eq!(img.pixels, vec![Vec3::splat(0.25), Vec3::splat(2.0)]);
}

#[test]
fn truncated_nonfinite_and_unknown_files_are_input_errors_naming_the_file() {
    let rows = vec![vec![[1.0f32, 1.0, 1.0]; 4]; 3];
    let full = pfm(&rows, true);
    let cut = tmp("cut.pfm");
    std::fs::write(&cut, &full[..full.len() - 5]).unwrap();
    let e = read_image(&cut).unwrap_err();
    assert_eq!(e.exit_code(), 2);
    let msg = e.to_string();
    assert!(
        msg.contains("cut.pfm") && msg.contains("truncated"),
        "{msg}"
    );

    let mut bad = rows.clone();
    bad[1][2] = [1.0, f32::INFINITY, 1.0];
    let inf = tmp("inf.pfm");
    std::fs::write(&inf, pfm(&bad, false)).unwrap();
    let msg = read_image(&inf).unwrap_err().to_string();
    assert!(msg.contains("inf.pfm") && msg.contains("(2, 1)"), "{msg}");

    let e = read_image(&tmp("does-not-exist.exr")).unwrap_err();
    assert_eq!(e.exit_code(), 2);
    assert!(e.to_string().contains("does-not-exist.exr"));

    // Truncated PNG and EXR: the decoders' errors, under our file name, no panic.
    let png = png8(&vec![vec![[10u8, 20, 30]; 5]; 4]);
    let exr = exr_bytes(4, 3, |x, y| [x as f32, y as f32, 1.0]);
    for (name, bytes) in [("cut.png", &png), ("cut.exr", &exr)] {
        let e = decode_image(&bytes[..bytes.len() / 2], Path::new(name)).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().starts_with(name), "{e}");
    }
}

#[test]
fn size_mismatch_and_all_black_files_are_errors() {
    let a = tmp("a43.pfm");
    let b = tmp("b42.pfm");
    let black = tmp("black.pfm");
    std::fs::write(&a, pfm(&vec![vec![[1.0, 0.5, 0.25]; 4]; 3], true)).unwrap();
    std::fs::write(&b, pfm(&vec![vec![[1.0, 0.5, 0.25]; 4]; 2], true)).unwrap();
    std::fs::write(&black, pfm(&vec![vec![[0.0; 3]; 4]; 3], true)).unwrap();
    let e = compare_files(&a, &b, 32.0).unwrap_err();
    assert_eq!(e.exit_code(), 2);
    let msg = e.to_string();
    assert!(
        msg.contains("4 x 3") && msg.contains("4 x 2") && msg.contains("b42.pfm"),
        "{msg}"
    );
    let e = compare_files(&a, &black, 32.0).unwrap_err();
    assert_eq!(e.exit_code(), 2);
    let msg = e.to_string();
    assert!(
        msg.contains("black.pfm") && msg.contains("mean luminance is 0"),
        "{msg}"
    );
    assert_eq!(
        compare_files(&a, &a, 32.0).unwrap().perceptual_distance,
        0.0
    );
}

fn png8(rows: &[Vec<[u8; 3]>]) -> Vec<u8> {
    let (w, h) = (rows[0].len() as u32, rows.len() as u32);
    let raw: Vec<u8> = rows.iter().flatten().flatten().copied().collect();
    let img: ImageBuffer<Rgb<u8>, Vec<u8>> = ImageBuffer::from_raw(w, h, raw).unwrap();
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), ImageFormat::Png)
        .unwrap();
    out
}

fn exr_bytes(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> Vec<u8> {
    let img: ImageBuffer<Rgb<f32>, Vec<f32>> = ImageBuffer::from_fn(w, h, |x, y| Rgb(f(x, y)));
    let mut out = Vec::new();
    img.write_to(&mut Cursor::new(&mut out), ImageFormat::OpenExr)
        .unwrap();
    out
}

/// The largest slope of the sRGB EOTF on [c - half, c + half] (it is increasing), times half a
/// code value: how far quantising to the nearest code can move the decoded linear value.
fn quantisation_bound(c: f64, half: f64) -> f64 {
    let hi = (c + half).min(1.0);
    let slope = if hi <= 0.04045 {
        1.0 / 12.92
    } else {
        2.4 / 1.055 * ((hi + 0.055) / 1.055).powf(1.4)
    };
    half * slope
}

#[test]
fn png_decodes_image_outs_srgb_back_to_linear() {
    // 8 bits: every linear value in [0, 1] on a fine grid, through image_out's encoder
    // (to_srgb8 rounds to the nearest code) and our decoder. The error is at most half a code
    // value times the EOTF's slope there, plus f32 rounding (1e-6).
    let n = 64u32;
    let lin = |x: u32, y: u32| (y * n + x) as f32 / (n * n - 1) as f32;
    let rows: Vec<Vec<[u8; 3]>> = (0..n)
        .map(|y| (0..n).map(|x| [to_srgb8(lin(x, y), 0.0); 3]).collect())
        .collect();
    let img = decode_image(&png8(&rows), Path::new("q.png")).unwrap();
    for y in 0..n {
        for x in 0..n {
            let v = lin(x, y) as f64;
            let bound = quantisation_bound(srgb_encode(v as f32) as f64, 0.5 / 255.0) + 1e-6;
            let got = img.get(x, y);
            assert!(
                (got.x as f64 - v).abs() <= bound,
                "{v}: {got} (bound {bound:e})"
            );
            assert_eq!(got.x, got.z);
        }
    }
    // The end points are exact.
    assert_eq!(img.get(0, 0), Vec3::ZERO);
    assert_eq!(img.get(n - 1, n - 1), Vec3::ONE);

    // 16 bits: the same with half of 1/65535.
    let codes: Vec<u16> = (0..n * n)
        .map(|i| (srgb_encode(i as f32 / (n * n - 1) as f32) as f64 * 65535.0).round() as u16)
        .collect();
    let raw: Vec<u16> = codes.iter().flat_map(|&c| [c, c, c]).collect();
    let buf: ImageBuffer<Rgb<u16>, Vec<u16>> = ImageBuffer::from_raw(n, n, raw).unwrap();
    let mut bytes = Vec::new();
    buf.write_to(&mut Cursor::new(&mut bytes), ImageFormat::Png)
        .unwrap();
    let img = decode_image(&bytes, Path::new("q16.png")).unwrap();
    for (i, p) in img.pixels.iter().enumerate() {
        let v = i as f64 / (n * n - 1) as f64;
        let c = codes[i] as f64 / 65535.0;
        // Encoding in f32 adds up to 1e-7 in code space, within the half-code window.
        let bound = quantisation_bound(c, 0.5 / 65535.0 + 1e-7) + 1e-6;
        assert!((p.y as f64 - v).abs() <= bound, "{v}: {p}");
        assert!((p.y as f64 - srgb_decode(c)).abs() < 1e-7);
    }
}

#[test]
fn exr_is_read_exactly_and_hdr_within_rgbe_precision() {
    let f = |x: u32, y: u32| [0.1 + x as f32, 2.0 * y as f32 + 0.5, 0.03125];
    let img = decode_image(&exr_bytes(5, 3, f), Path::new("t.exr")).unwrap();
    assert_eq!((img.width, img.height), (5, 3));
    for y in 0..3 {
        for x in 0..5 {
            assert_eq!(img.get(x, y), Vec3::from_array(f(x, y)));
        }
    }
    let buf: ImageBuffer<Rgb<f32>, Vec<f32>> = ImageBuffer::from_fn(5, 3, |x, y| Rgb(f(x, y)));
    let mut hdr = Vec::new();
    buf.write_to(&mut Cursor::new(&mut hdr), ImageFormat::Hdr)
        .unwrap();
    let img = decode_image(&hdr, Path::new("t.hdr")).unwrap();
    for y in 0..3 {
        for x in 0..5 {
            let want = Vec3::from_array(f(x, y));
            let got = img.get(x, y);
            // RGBE keeps an 8-bit mantissa per channel under the pixel's largest exponent: the
            // error is below 2^-7 of the largest channel.
            let tol = want.max_element() / 128.0;
            assert!(
                (got - want).abs().max_element() <= tol,
                "({x}, {y}): {got} vs {want}"
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Bad input never panics: any prefix of a valid PFM, PNG or EXR file, and arbitrary bytes
    /// after a PFM magic, give an image or an error naming the file.
    #[test]
    fn damaged_files_give_errors_not_panics(
        cut in 0.0f64..1.0, junk in proptest::collection::vec(any::<u8>(), 0..64)
    ) {
        let pfm_file = pfm(&[vec![[1.0f32, 2.0, 3.0]; 3], vec![[0.5f32; 3]; 3]], true);
        let png = png8(&[vec![[10u8, 20, 30]; 5], vec![[200u8, 100, 0]; 5]]);
        let exr = exr_bytes(6, 4, |x, y| [x as f32, y as f32, 0.5]);
        for (name, bytes) in [("p.pfm", &pfm_file), ("p.png", &png), ("p.exr", &exr)] {
            let n = (bytes.len() as f64 * cut) as usize;
            if let Err(e) = decode_image(&bytes[..n], Path::new(name)) {
                prop_assert!(e.to_string().starts_with(name));
                prop_assert_eq!(e.exit_code(), 2);
            }
        }
        let mut j = b"PF".to_vec();
        j.extend_from_slice(&junk);
        if let Err(e) = decode_image(&j, Path::new("j.pfm")) {
            prop_assert!(e.to_string().starts_with("j.pfm: PFM: "));
        }
    }
}

#[test]
fn png_grey_and_alpha_variants_decode_alike() {
    // A grey 8-bit PNG and an RGBA one (alpha ignored) decode to the same linear values as RGB.
    let (w, h) = (3u32, 2u32);
    let codes = [0u8, 40, 128, 200, 254, 255];
    let mut grey = Vec::new();
    image::ImageBuffer::<image::Luma<u8>, Vec<u8>>::from_raw(w, h, codes.to_vec())
        .unwrap()
        .write_to(&mut Cursor::new(&mut grey), ImageFormat::Png)
        .unwrap();
    let rgba_raw: Vec<u8> = codes.iter().flat_map(|&c| [c, c, c, 17]).collect();
    let mut rgba = Vec::new();
    image::ImageBuffer::<image::Rgba<u8>, Vec<u8>>::from_raw(w, h, rgba_raw)
        .unwrap()
        .write_to(&mut Cursor::new(&mut rgba), ImageFormat::Png)
        .unwrap();
    let g = decode_image(&grey, Path::new("g.png")).unwrap();
    let a = decode_image(&rgba, Path::new("a.png")).unwrap();
    assert_eq!(g, a);
    for (i, &c) in codes.iter().enumerate() {
        let want = srgb_decode(c as f64 / 255.0) as f32;
        assert_eq!(g.pixels[i], Vec3::splat(want));
    }
    // Code 128 is 0.2158605 linear (the sRGB table value).
    assert!((g.pixels[2].x - 0.215_860_5).abs() < 1e-6);
}
