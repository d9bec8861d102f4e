//! `pixelflow-sim compare` as a user runs it: the table, the JSON, and exit code 2 with a message
//! naming the file for every kind of bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    crate::bin()
}

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_compare");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Writes a little-endian colour PFM of `w x h` grey pixels `f(x, y)` (y = 0 the top row).
fn write_pfm(name: &str, w: u32, h: u32, f: impl Fn(u32, u32) -> f32) -> PathBuf {
    let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    for y in (0..h).rev() {
        for x in 0..w {
            for _ in 0..3 {
                bytes.extend_from_slice(&f(x, y).to_le_bytes());
            }
        }
    }
    let p = tmp(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn compare_prints_a_table_and_json() {
    let a = write_pfm("a.pfm", 16, 8, |x, y| {
        0.5 + 0.02 * x as f32 + 0.01 * y as f32
    });
    let b = write_pfm("b.pfm", 16, 8, |x, y| {
        0.5 + 0.02 * x as f32 + 0.01 * y as f32 + if (x, y) == (3, 4) { 0.3 } else { 0.0 }
    });
    let o = run(&["compare", s(&a), s(&b)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    for row in [
        "perceptual distance",
        "(ppd 32)",
        "rmse",
        "psnr",
        "max abs error",
        "relative luminance error",
        "mach-band energy",
    ] {
        assert!(out.contains(row), "no `{row}` in\n{out}");
    }

    let o = run(&["compare", s(&a), s(&b), "--ppd", "16", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(json["width"], 16);
    assert_eq!(json["height"], 8);
    assert_eq!(json["ppd"], 16.0);
    // One pixel changed by 0.3 (f32: within 1e-7): max abs error 0.3, RMSE 0.3 / sqrt(128).
    let max = json["max_abs_error"].as_f64().unwrap();
    assert!((max - 0.3).abs() < 1e-6, "{json}");
    let rmse = json["rmse"].as_f64().unwrap();
    assert!((rmse - 0.3 / 128f64.sqrt()).abs() < 1e-6, "{json}");
    assert!(json["perceptual_distance"].as_f64().unwrap() > 0.0);

    // Identical images: distance 0, PSNR null.
    let o = run(&["compare", s(&a), s(&a), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json["perceptual_distance"], 0.0);
    assert!(json["psnr_db"].is_null());
}

#[test]
fn bad_inputs_exit_2_naming_the_file() {
    let a = write_pfm("ok.pfm", 8, 8, |x, _| 0.1 + x as f32);
    let small = write_pfm("small.pfm", 8, 7, |x, _| 0.1 + x as f32);
    let black = write_pfm("black.pfm", 8, 8, |_, _| 0.0);
    let junk = tmp("junk.png");
    std::fs::write(&junk, b"not an image at all").unwrap();
    let missing = tmp("missing.exr");
    for (args, needles) in [
        (vec![s(&a), s(&small)], vec!["8 x 8", "8 x 7", "small.pfm"]),
        (vec![s(&black), s(&a)], vec!["black.pfm", "mean luminance"]),
        (
            vec![s(&a), s(&junk)],
            vec!["junk.png", "unknown image format"],
        ),
        (vec![s(&missing), s(&a)], vec!["missing.exr"]),
        (vec![s(&a), s(&a), "--ppd", "0"], vec!["--ppd"]),
        // Regression: a huge ppd printed a NaN distance and exited 0.
        (
            vec![s(&a), s(&a), "--ppd", "1e300"],
            vec!["--ppd", "at most"],
        ),
    ] {
        let mut full = vec!["compare"];
        full.extend(args);
        let o = run(&full);
        assert_eq!(o.status.code(), Some(2), "{full:?}: {}", stderr(&o));
        let err = stderr(&o);
        for n in needles {
            assert!(err.contains(n), "{full:?}: no `{n}` in {err}");
        }
        assert!(o.stdout.is_empty());
    }
}
