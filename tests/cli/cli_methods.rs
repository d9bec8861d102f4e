//! The comparison backends and the commands built on them, as a user runs them: every
//! `--method` renders the shipped two-spots scene, `stats` prints Table 1 (and JSON), and bad
//! texture options or experiment names exit 2 with a message.

use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    crate::bin().args(args).output().expect("binary runs")
}

fn scene(name: &str) -> String {
    Path::new(crate::REPO)
        .join("scenes")
        .join(format!("{name}.toml"))
        .to_string_lossy()
        .into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_methods");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn every_method_renders_two_spots_close_to_the_reference() {
    // Each method's EXR against the reference's: the bright spot's peak is 3.2 (rho I / h^2) and
    // every reconstruction of the adaptive solution stays within a few percent of the oracle
    // there; the mean absolute difference over the image is small against the mean radiosity.
    let exr = |m: &str| {
        let path = tmp(&format!("{m}.exr"));
        let o = run(&[
            "render",
            &scene("two-spots"),
            "--method",
            m,
            "-o",
            tmp(&format!("{m}.png")).to_str().unwrap(),
            "--exr",
            path.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(o.status.success(), "{m}: {}", text(&o.stderr));
        image::open(&path).unwrap().to_rgb32f()
    };
    let reference = exr("reference");
    let mean_ref: f32 =
        reference.pixels().map(|p| p[1]).sum::<f32>() / (reference.len() / 3) as f32;
    for m in [
        "direct",
        "texture-nearest",
        "texture-bilinear",
        "texture-bicubic",
        "mesh",
    ] {
        let img = exr(m);
        let mut abs = 0.0f32;
        for (a, b) in img.pixels().zip(reference.pixels()) {
            abs += (a[1] - b[1]).abs();
        }
        let rel = abs / (img.len() / 3) as f32 / mean_ref;
        // The solver refined until bilinear prediction was within its tolerance (0.01 of the
        // local value, plus visibility noise): 2 % mean error leaves room for the filters.
        assert!(rel < 0.02, "{m}: mean relative difference {rel}");
    }
}

#[test]
fn stats_prints_table1_and_json() {
    let o = run(&["stats", &scene("two-spots")]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    for needle in [
        "original",
        "mesh (poly)",
        "RAT",
        "texture memory",
        "RRP memory",
    ] {
        assert!(out.contains(needle), "missing {needle}:\n{out}");
    }
    let o = run(&[
        "stats",
        &scene("two-spots"),
        "--json",
        "--frames",
        "1",
        "--width",
        "64",
        "--height",
        "64",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // One plane: 2 original triangles, 4 RAT vertices, one texture.
    assert_eq!(v["original"]["triangles"], 2);
    assert_eq!(v["rat_vertices"], 4);
    assert_eq!(v["texture_memory"]["textures"], 1);
    assert!(v["mesh"]["triangles"].as_u64().unwrap() > 1000);
    let methods: Vec<&str> = v["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["method"].as_str().unwrap())
        .collect();
    assert_eq!(
        methods,
        ["mesh", "texture-bilinear", "texture-bicubic", "direct"]
    );
}

#[test]
fn bad_texture_options_and_names_exit_2() {
    let ts = scene("two-spots");
    for (args, needle) in [
        (
            vec![
                "render",
                &ts,
                "--method",
                "texture-bilinear",
                "--texture-size",
                "3",
            ],
            "power of two",
        ),
        (
            vec![
                "render",
                &ts,
                "--method",
                "texture-bicubic",
                "--bicubic",
                "2,0",
            ],
            "[0, 1]",
        ),
        (vec!["render", &ts, "--bicubic", "0.3"], "B,C"),
        (
            vec!["render", &ts, "--texture-budget", "12Q"],
            "unknown unit",
        ),
        (
            vec![
                "render",
                &ts,
                "--texture-size",
                "8",
                "--texture-budget",
                "1M",
            ],
            "exclude",
        ),
        (
            vec![
                "render",
                &ts,
                "--method",
                "texture-bilinear",
                "--texture-budget",
                "1",
            ],
            "budget",
        ),
        (
            vec!["render", &ts, "--method", "phong"],
            "--method phong: is not a method",
        ),
        (vec!["experiment", "fig7"], "fig5, fig6, table1 or all"),
        (
            vec![
                "render",
                &ts,
                "--method",
                "texture-bilinear",
                "--texel-placement",
                "edge",
            ],
            "--texel-placement edge: is not a texel placement",
        ),
        (
            vec!["stats", &ts, "--texel-placement", "Corner"],
            "--texel-placement Corner",
        ),
        (
            vec!["bench", &ts, "--texel-placement", "middle"],
            "--texel-placement middle",
        ),
        (
            vec!["render", &ts, "--anisotropy", "0"],
            "--anisotropy 0: must be 1 (isotropic) to 16",
        ),
        (
            vec!["bench", &ts, "--anisotropy", "17"],
            "--anisotropy 17: must be 1 (isotropic) to 16",
        ),
        (
            vec!["export", &ts, "-o", "x.glb", "--anisotropy", "4"],
            "the engine that draws them filters them",
        ),
    ] {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o.stderr));
        assert!(
            text(&o.stderr).contains(needle),
            "{args:?}: {}",
            text(&o.stderr)
        );
    }
}

#[test]
fn texture_budget_shrinks_textures_until_they_fit() {
    let stats = tmp("budget.json");
    let o = run(&[
        "render",
        &scene("two-spots"),
        "--method",
        "texture-bilinear",
        "--texture-budget",
        "10K",
        "-o",
        tmp("budget.png").to_str().unwrap(),
        "--stats",
        stats.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    // 12-bit texels with a mip chain and 2-texel gutters: a 32 x 32 texture stores 36^2 + 20^2
    // + 12^2 + 8^2 + 6^2 + 5^2 = 1965 texels x 4.5 B = 8843 B, a 64 x 64 one 68^2 = 4624 texels
    // at level 0 alone (20,808 B), so a 10 KiB budget gives 32 x 32, stored as 36 x 36.
    assert_eq!(v["texture_memory"]["texels"], 36 * 36);
    assert!(v["texture_memory"]["bytes_with_chain"][1].as_u64().unwrap() <= 10 * 1024);
}

#[test]
fn texel_placement_round_trips_through_the_cli() {
    // Corner placement renders, differs from the default centre placement, and the default is
    // the same as asking for centre explicitly (bit for bit).
    let ts = scene("two-spots");
    let exr = |name: &str, extra: &[&str]| {
        let path = tmp(&format!("placement-{name}.exr"));
        let png = tmp(&format!("placement-{name}.png"));
        let mut args = vec![
            "render",
            &ts,
            "--method",
            "texture-bilinear",
            "-o",
            png.to_str().unwrap(),
            "--exr",
            path.to_str().unwrap(),
            "--quiet",
        ];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{name}: {}", text(&o.stderr));
        std::fs::read(&path).unwrap()
    };
    let default = exr("default", &[]);
    let centre = exr("centre", &["--texel-placement", "centre"]);
    let corner = exr("corner", &["--texel-placement", "corner"]);
    assert_eq!(default, centre);
    assert_ne!(default, corner);
}
