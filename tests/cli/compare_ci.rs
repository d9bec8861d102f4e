//! `pixelflow-sim compare` as a CI job runs it: one JSON document whatever checks run, the
//! share of differing pixels a run may tolerate (`--fail-percent`), thresholds that hold at any
//! image size (`--view-degrees` with `--max-distance-per-pixel`), and a PNG refused beside a
//! float image unless `--convert` says to decode it.

use std::f32::consts::TAU;
use std::path::{Path, PathBuf};
use std::process::Output;

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("compare_ci");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn run(args: &[&str]) -> Output {
    crate::bin().args(args).output().expect("binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The whole of stdout as ONE JSON value (`from_slice` refuses trailing data, so two
/// concatenated documents fail here).
fn one_document(o: &Output) -> serde_json::Value {
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not one JSON document ({e}):\n{}",
            String::from_utf8_lossy(&o.stdout)
        )
    })
}

/// Writes a little-endian colour PFM of `w x h` grey pixels `f(x, y)` (y = 0 the top row).
fn write_pfm(name: &str, w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> PathBuf {
    let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    for y in (0..h).rev() {
        for x in 0..w {
            let v = f(x, y).to_le_bytes();
            for _ in 0..3 {
                bytes.extend_from_slice(&v);
            }
        }
    }
    let p = tmp(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A smooth grey ramp, 0.2 to about 1.2, and the same with `moved` pixels (row-major indices)
/// raised by a tenth.
fn ramp_pair(prefix: &str, side: u32, moved: &[u32]) -> (PathBuf, PathBuf) {
    let ramp = |x: u32, y: u32| 0.2 + (x + y) as f32 / side as f32 * 0.5;
    let want = write_pfm(&format!("{prefix}-want.pfm"), side, side, ramp);
    let got = write_pfm(&format!("{prefix}-got.pfm"), side, side, |x, y| {
        let bump = if moved.contains(&(y * side + x)) {
            1.1
        } else {
            1.0
        };
        ramp(x, y) * bump
    });
    (got, want)
}

#[test]
fn two_checks_print_one_json_document() {
    let (got, want) = ramp_pair("two-checks", 16, &[37]);
    let o = run(&[
        "compare",
        s(&got),
        s(&want),
        "--tolerance",
        "default",
        "--max-distance",
        "1e9",
        "--json",
    ]);
    // One of 256 pixels differs and --fail-percent is 0: the pixel check fails, exit 1.
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let doc = one_document(&o);
    assert_eq!(doc["a"], s(&got));
    assert_eq!(doc["b"], s(&want));
    assert!(doc["converted"].is_null(), "{doc}");
    assert_eq!(doc["pixels"]["pixels"], 256);
    assert_eq!(doc["pixels"]["differing"], 1);
    // 1 / 256 = 0.390625 %, exact in binary.
    assert_eq!(doc["pixels"]["differing_percent"], 0.390625);
    // The first listed pixel is index 37: (5, 2).
    assert_eq!(doc["pixels"]["first"][0]["x"], 5);
    assert_eq!(doc["pixels"]["first"][0]["y"], 2);
    let checks = doc["checks"].as_array().unwrap();
    assert_eq!(checks.len(), 2, "{doc}");
    assert_eq!(checks[0]["name"], "fail-percent");
    assert_eq!(checks[0]["limit"], 0.0);
    assert_eq!(checks[0]["value"], 0.390625);
    assert_eq!(checks[0]["passed"], false);
    assert_eq!(checks[1]["name"], "max-distance");
    assert_eq!(checks[1]["value"], doc["perceptual_distance"]);
    assert_eq!(checks[1]["passed"], true);
    assert!(doc["perceptual_distance"].as_f64().unwrap() > 0.0, "{doc}");
    assert_eq!(doc["passed"], false);
    assert!(
        stderr(&o).contains("0.3906 % of the pixels differ"),
        "{}",
        stderr(&o)
    );

    // The perceptual measures alone: still one document, with no pixel check.
    let o = run(&["compare", s(&got), s(&want), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc = one_document(&o);
    assert!(doc["pixels"].is_null(), "{doc}");
    assert_eq!(doc["checks"], serde_json::json!([]));
    assert_eq!(doc["passed"], true);
    assert_eq!(doc["width"], 16);
}

#[test]
fn fail_percent_tolerates_that_share_of_pixels() {
    // 3 of 100 pixels moved by 10 %: 3 % differ at any tolerance below 0.1.
    let (got, want) = ramp_pair("percent", 10, &[0, 45, 99]);
    let check = |percent: &str| {
        run(&[
            "compare",
            s(&got),
            s(&want),
            "--tolerance",
            "default",
            "--fail-percent",
            percent,
        ])
    };
    let o = check("5");
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("3 of 100 pixels (3.0000 %) differ"), "{text}");
    assert!(
        text.contains("check passed: 3.0000 % of the pixels differ beyond the tolerance, within --fail-percent 5"),
        "{text}"
    );
    // Exactly at the limit passes: it fails only above.
    assert!(check("3").status.success());
    for percent in ["2.9", "0"] {
        let o = check(percent);
        assert_eq!(o.status.code(), Some(1), "{percent}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!(
                "3.0000 % of the pixels differ beyond the tolerance, over --fail-percent {percent}"
            )),
            "{}",
            stderr(&o)
        );
    }
    // Without the flag: today's rule, one pixel fails.
    let o = run(&["compare", s(&got), s(&want), "--tolerance", "default"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // A percentage outside [0, 100], or without --tolerance, is a usage error.
    for bad in [
        vec!["--tolerance", "default", "--fail-percent", "101"],
        vec!["--tolerance", "default", "--fail-percent", "NaN"],
        vec!["--fail-percent", "1"],
    ] {
        let mut args = vec!["compare", s(&got), s(&want)];
        args.extend(bad);
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("--fail-percent") || stderr(&o).contains("--tolerance"));
    }
}

/// The same periodic picture at `side x side` pixel centres: a lit pattern of whole cycles, the
/// image under test with a ripple of 3 cycles over it.
fn picture(name: &str, side: u32, ripple: f32) -> PathBuf {
    write_pfm(name, side, side, |x, y| {
        let (u, v) = (
            (x as f32 + 0.5) / side as f32,
            (y as f32 + 0.5) / side as f32,
        );
        (1.0 + 0.5 * (TAU * u).cos() * (TAU * v).sin()) * (1.0 + ripple * (3.0 * TAU * u).sin())
    })
}

#[test]
fn thresholds_hold_alike_at_256_and_1024_pixels() {
    let sizes = [256u32, 1024];
    let pairs: Vec<(PathBuf, PathBuf)> = sizes
        .iter()
        .map(|&n| {
            (
                picture(&format!("size-{n}-got.pfm"), n, 0.02),
                picture(&format!("size-{n}-want.pfm"), n, 0.0),
            )
        })
        .collect();
    let compare = |(got, want): &(PathBuf, PathBuf), extra: &[&str]| {
        let mut args = vec!["compare", s(got), s(want), "--view-degrees", "8", "--json"];
        args.extend(extra);
        let o = run(&args);
        assert!(
            o.status.code() == Some(0) || o.status.code() == Some(1),
            "{}",
            stderr(&o)
        );
        (o.status.code(), one_document(&o))
    };
    let docs: Vec<serde_json::Value> = pairs.iter().map(|p| compare(p, &[]).1).collect();
    let per_pixel = |d: &serde_json::Value| d["perceptual_distance_per_pixel"].as_f64().unwrap();
    let (small, large) = (per_pixel(&docs[0]), per_pixel(&docs[1]));
    // Both seen over 8 degrees (ppd 32 and 128): each harmonic of the picture lands on the same
    // cycles per degree, so by Parseval the per-pixel distance is the same sum at both sizes,
    // up to f32 rounding of the pixels (relative 1e-7 each): 1e-5 is a wide margin.
    assert_eq!(docs[0]["ppd"], 32.0);
    assert_eq!(docs[1]["ppd"], 128.0);
    assert!((small / large - 1.0).abs() < 1e-5, "{small} {large}");
    // The plain distance is a norm over the pixels: 16 times the pixels, 4 times the distance.
    let ratio = docs[1]["perceptual_distance"].as_f64().unwrap()
        / docs[0]["perceptual_distance"].as_f64().unwrap();
    assert!((ratio - 4.0).abs() < 4e-4, "{ratio}");

    // A per-pixel threshold 0.01 % above the value passes both sizes, 0.01 % below fails both.
    for (factor, code, passed) in [(1.0001, Some(0), true), (0.9999, Some(1), false)] {
        let limit = format!("{}", small * factor);
        for p in &pairs {
            let (c, doc) = compare(p, &["--max-distance-per-pixel", &limit]);
            assert_eq!(
                (c, &doc["passed"]),
                (code, &serde_json::json!(passed)),
                "{doc}"
            );
            assert_eq!(doc["checks"][0]["name"], "max-distance-per-pixel");
        }
    }
    // The share of moved pixels is size-independent too: the ripple moves a pixel by more than
    // 1e-3 of its value where |0.02 sin| > 1e-3 (to first order), on 1 - (2 / pi) asin(0.05)
    // of the width, 96.82 %; the sampled share is within a few pixel columns of it.
    let want = 100.0 * (1.0 - 2.0 / std::f64::consts::PI * 0.05f64.asin());
    for (p, n) in pairs.iter().zip(sizes) {
        let (_, doc) = compare(p, &["--tolerance", "1e-3", "--fail-percent", "100"]);
        let got = doc["pixels"]["differing_percent"].as_f64().unwrap();
        let column = 100.0 / n as f64;
        assert!(
            (got - want).abs() <= 6.0 * column + 0.1,
            "{n}: {got} against {want}"
        );
    }
}

#[test]
fn a_png_beside_an_exr_needs_convert() {
    // A PNG of sRGB codes 20..=235 and an EXR of the same codes decoded to linear: equal once
    // the PNG is decoded, different encodings until then.
    let (w, h) = (24u32, 9u32);
    let code = |x: u32, y: u32| (20 + (x * 9 + y) % 216) as u8;
    let decode = |c: u8| {
        let c = c as f64 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let png = tmp("encodings.png");
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([code(x, y)]))
        .save(&png)
        .unwrap();
    let exr = tmp("encodings.exr");
    image::Rgb32FImage::from_fn(w, h, |x, y| image::Rgb([decode(code(x, y)) as f32; 3]))
        .save(&exr)
        .unwrap();
    for (a, b) in [(&png, &exr), (&exr, &png)] {
        let o = run(&["compare", s(a), s(b), "--tolerance", "default"]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        let err = stderr(&o);
        for needle in [
            "encodings.png is a PNG",
            "different encodings",
            "exposure",
            "--convert",
        ] {
            assert!(err.contains(needle), "no `{needle}` in {err}");
        }
        assert!(o.stdout.is_empty());
    }
    let o = run(&[
        "compare",
        s(&png),
        s(&exr),
        "--tolerance",
        "default",
        "--convert",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc = one_document(&o);
    let note = doc["converted"].as_str().unwrap();
    assert!(note.contains("decoded from sRGB to linear"), "{note}");
    // The same f64 decoding rounded to f32 on both sides: no pixel beyond 16 f32 steps.
    assert_eq!(doc["pixels"]["differing"], 0, "{doc}");
    let o = run(&["compare", s(&png), s(&exr), "--convert"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).starts_with("note: "));
    // Two PNGs share their encoding: no flag needed.
    let o = run(&["compare", s(&png), s(&png), "--tolerance", "default"]);
    assert!(o.status.success(), "{}", stderr(&o));
}
