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
        "near sharp edges",
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
    // The reference's bump is itself a sharp edge (0.3 over about 0.6: a 33 % step), so all of
    // the error lies near it. The bump and its four neighbours are edge pixels; within 2 px of
    // them: rows 2..=6 over columns 0..=6 and rows 1 and 7 over columns 1..=5, 35 + 10 pixels.
    assert_eq!(json["edges"]["near_share"], 1.0, "{json}");
    assert_eq!(json["edges"]["near_pixels"], 45, "{json}");

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

/// CRC-32 (ISO-HDLC, as PNG chunks use it), bit by bit: a few bytes per test.
fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG of `side x side` 8-bit grey pixels whose data is a single empty chunk: a few dozen
/// bytes on disk claiming an image of `side^2` bytes decoded (a decompression bomb's header).
fn bomb_png(name: &str, side: u32) -> PathBuf {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        png.extend_from_slice(&body);
        png.extend_from_slice(&crc32(&body).to_be_bytes());
    };
    let mut ihdr = side.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&side.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &[]);
    chunk(b"IEND", &[]);
    let p = tmp(name);
    std::fs::write(&p, png).unwrap();
    p
}

/// What broke: two 16384^2 grey PNGs of a few hundred KiB each decoded to 7.3 GB and aborted
/// the process (exit 134) after two minutes, `--memory-limit` ignored. The size is now read
/// from the headers and the comparison's memory estimated before anything is decoded: refused
/// with exit 2 and the estimate, at once, in both the perceptual and the pixel-by-pixel mode.
#[test]
fn a_decompression_bomb_is_refused_by_its_header() {
    let (a, b) = (bomb_png("bomb-a.png", 16384), bomb_png("bomb-b.png", 16384));
    for extra in [&[][..], &["--tolerance", "default"][..]] {
        let mut args = vec!["compare", s(&a), s(&b), "--memory-limit", "4G"];
        args.extend_from_slice(extra);
        let start = std::time::Instant::now();
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("16384 x 16384 pixels") && e.contains("over the memory limit"),
            "{e}"
        );
        assert!(start.elapsed().as_secs() < 20, "took {:?}", start.elapsed());
    }
    // Within the limit the header is read, and the missing pixels are the decoder's error.
    let (c, d) = (bomb_png("small-a.png", 64), bomb_png("small-b.png", 64));
    let o = run(&["compare", s(&c), s(&d)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("small-a.png"), "{}", stderr(&o));
}

/// The memory estimate of a comparison is never below what it uses, and not far above: two
/// 1024 x 1024 images, the estimate's refusal threshold found by bisection against the
/// measured peak.
#[test]
fn the_compare_estimate_brackets_the_measured_peak() {
    if !crate::can_measure_peaks() {
        return;
    }
    let a = write_pfm("peak-a.pfm", 1024, 1024, |x, y| {
        0.1 + ((x ^ y) & 15) as f32 * 0.01
    });
    let b = write_pfm("peak-b.pfm", 1024, 1024, |x, _| 0.1 + (x & 7) as f32 * 0.01);
    // The estimate with the program's own memory: refused just under it, accepted at it.
    let est = 1024 * 1024 * app::commands::compare::PERCEPTUAL_PIXEL_BYTES;
    let program = app::budget::PROGRAM_BYTES;
    let refused = run(&[
        "compare",
        s(&a),
        s(&b),
        "--memory-limit",
        &(est + program - 1).to_string(),
    ]);
    assert_eq!(refused.status.code(), Some(2), "{}", stderr(&refused));
    let limit = (est + program).to_string();
    let peak = crate::peak_bytes(&["compare", s(&a), s(&b), "--memory-limit", &limit]);
    // The whole peak is under the limit; the pixels' share (the peak less the program) is
    // within their estimate and above 2/3 of it.
    assert!(peak <= est + program, "peak {peak} over the limit {limit}");
    let pixels = peak.saturating_sub(program);
    assert!(
        pixels <= est,
        "measured {pixels} bytes for the pixels, estimated {est}"
    );
    assert!(
        pixels * 3 >= est * 2,
        "measured {pixels}, estimated {est}: over 1.5x"
    );
}
