//! `pixelflow-sim sweep` on a small case: two-spots at 64 x 64, two densities, two texture sizes,
//! one frame per point. Checks the record keys, that errors fall as the sampling density rises,
//! and that the Pareto flags agree with the numbers. No timing is asserted.

use std::path::{Path, PathBuf};

use serde_json::Value;

/// A file in this test's own directory (the tests run in parallel threads of one process, so
/// they must not share output paths).
fn tmp(test: &str, name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("sweep")
        .join(test);
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn sweep(test: &str, extra: &[&str]) -> (Value, String) {
    let json = tmp(test, "two-spots.json");
    let csv = tmp(test, "two-spots.csv");
    let scene = Path::new(crate::REPO).join("scenes/two-spots.toml");
    let o = crate::bin()
        .args([
            "sweep",
            scene.to_str().unwrap(),
            "--size",
            "64x64",
            "--densities",
            "4,1",
            "--texture-levels",
            "2",
            "--frames",
            "1",
            "--repeats",
            "2",
            "--json",
            json.to_str().unwrap(),
            "--csv",
            csv.to_str().unwrap(),
            "--plots",
            tmp(test, "plots").to_str().unwrap(),
            "--quiet",
        ])
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (v, std::fs::read_to_string(&csv).unwrap())
}

#[test]
fn a_small_sweep_has_every_key_falling_errors_and_consistent_fronts() {
    let (report, csv) = sweep("keys", &[]);
    let points = report["points"].as_array().unwrap();
    // 2 densities x (direct + mesh + 3 texture methods x 2 sizes x 2 placements) = 28 points.
    assert_eq!(points.len(), 28);
    assert_eq!(csv.lines().count(), 29);
    for p in points {
        for key in [
            "method",
            "density",
            "texture",
            "frame_ms",
            "frame_ms_spread",
            "bytes",
            "error_reconstruction",
            "error_total",
            "reconstruction",
            "total",
            "pareto_time",
            "pareto_memory",
            "error_physics",
            "physics",
        ] {
            assert!(p.get(key).is_some(), "point lacks `{key}`: {p}");
        }
        for k in ["perceptual", "rmse", "max_abs", "mach_band"] {
            assert!(p["total"][k].as_f64().unwrap().is_finite(), "{p}");
        }
        assert!(p["frame_ms"].as_f64().unwrap() > 0.0);
        assert!(p["bytes"].as_u64().unwrap() > 0);
        // What a method holds while drawing is at least what it stores: the direct method adds
        // its patch caches, textures are held as f32 (12-bit stored), the mesh's triangles as
        // drawn are larger than its vertices and indices.
        assert!(
            p["working_bytes"].as_u64().unwrap() > p["bytes"].as_u64().unwrap(),
            "{p}"
        );
        let texture = p["method"].as_str().unwrap().starts_with("texture-");
        assert_eq!(p["texture"].is_null(), !texture, "{p}");
        if texture {
            let placement = p["texture"]["placement"].as_str().unwrap();
            assert!(placement == "centre" || placement == "corner", "{p}");
        }
    }
    // Errors fall as the density rises, for the methods whose accuracy follows the samples.
    let err = |m: &str, d: u64| {
        points
            .iter()
            .find(|p| p["method"] == m && p["density"] == d)
            .map(|p| p["error_total"].as_f64().unwrap())
            .unwrap()
    };
    for m in ["direct", "mesh"] {
        assert!(err(m, 1) < err(m, 0), "{m}: {} -> {}", err(m, 0), err(m, 1));
    }
    // The Pareto flags agree with the numbers: a flagged point is dominated by no other point,
    // an unflagged one by at least one.
    for (cost, flag) in [("frame_ms", "pareto_time"), ("bytes", "pareto_memory")] {
        let pts: Vec<(f64, f64)> = points
            .iter()
            .map(|p| {
                (
                    p[cost].as_f64().unwrap(),
                    p["error_total"].as_f64().unwrap(),
                )
            })
            .collect();
        for (i, p) in points.iter().enumerate() {
            let (c, e) = pts[i];
            let dominated = pts
                .iter()
                .any(|&(c2, e2)| c2 <= c && e2 <= e && (c2 < c || e2 < e));
            assert_eq!(p[flag].as_bool().unwrap(), !dominated, "{flag}: {p}");
        }
        assert!(points.iter().any(|p| p[flag].as_bool().unwrap()));
    }
    equal_error_is_consistent(&report);
    budget_is_consistent(&report);
}

/// The error budget against the path tracer obeys the metric's own geometry. The perceptual
/// distance is an L2 norm of the difference of two mean-normalised, filtered images, so the
/// triangle inequality holds exactly between the measured distances: a method's image is no
/// further from the truth than its distance to its solution's exact image plus that exact image's
/// distance to the truth. Taking the truth's noise out in quadrature never raises a distance.
fn budget_is_consistent(report: &Value) {
    let truth = &report["truth"];
    assert_eq!(truth["samples_per_pixel"], 1024, "{truth}");
    // Two-spots is lit by point spots alone and nothing it reflects reaches the camera's
    // surfaces back, so at the pixel centres the tracer is exact: its noise is 0 here.
    let noise = truth["perceptual"].as_f64().unwrap();
    assert!((0.0..1e-6).contains(&noise), "{truth}");
    let f = |v: &Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("no `{k}` in {v}"));
    for p in report["points"].as_array().unwrap() {
        let level = &report["densities"][p["density"].as_u64().unwrap() as usize];
        let solution = &level["solution"];
        let physics = &p["physics"];
        assert_eq!(f(p, "error_physics"), f(physics, "perceptual"));
        let bound = f(p, "error_reconstruction") + f(solution, "perceptual_measured");
        assert!(
            f(physics, "perceptual_measured") <= bound * (1.0 + 1e-9),
            "triangle inequality: {p} {solution}"
        );
        for e in [physics, solution] {
            assert!(f(e, "perceptual") <= f(e, "perceptual_measured"), "{e}");
            assert!(f(e, "rmse") <= f(e, "rmse_measured"), "{e}");
            let expected = (f(e, "perceptual_measured").powi(2) - noise * noise)
                .max(0.0)
                .sqrt();
            assert!(
                (f(e, "perceptual") - expected).abs() <= 1e-9 * (1.0 + expected),
                "{e}"
            );
        }
    }
}

/// The equal-error search's record agrees with its own definition: measured at the scene's own
/// density (factor 1, level 1 here) against the same direct error and RRP bytes as the sweep's
/// direct point there; every texture method at both placements; scales and bytes rising; each
/// reported texture is the first tested one within its ratio of the direct error.
fn equal_error_is_consistent(report: &Value) {
    let e = &report["equal_error"];
    assert_eq!(e["density"], 1, "{e}");
    let direct = report["points"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["method"] == "direct" && p["density"] == 1)
        .unwrap();
    let direct_error = e["direct_error"].as_f64().unwrap();
    // The same frame compared with the same reference: the same number.
    assert_eq!(
        direct_error,
        direct["error_reconstruction"].as_f64().unwrap()
    );
    assert_eq!(e["rrp_bytes"], direct["bytes"]);
    let ratios: Vec<f64> = e["ratios"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_f64().unwrap())
        .collect();
    assert_eq!(ratios, [1.0, 1.1]);
    let rows = e["rows"].as_array().unwrap();
    assert_eq!(
        rows.len(),
        12,
        "3 texture methods x 2 placements x mip-mapped or not"
    );
    // The same sets with and without their mip chains: the chainless set holds level 0 alone,
    // 3/4 of the chained bytes for large square textures (1 + 1/4 + 1/16 + ... = 4/3), less
    // for small ones whose 2-texel gutters weigh more (a 2 x 2 texture: 36 of 36 + 25 texels,
    // 0.59); 1 x 1 textures have no chain.
    let bytes_at = |mip: bool, scale: i64| {
        rows.iter()
            .filter(|r| r["mip_mapped"] == mip && r["method"] == "texture-bilinear")
            .flat_map(|r| r["tested"].as_array().unwrap())
            .find(|p| p["scale"] == scale)
            .map(|p| p["bytes"].as_f64().unwrap())
            .unwrap()
    };
    let ratio = bytes_at(false, 0) / bytes_at(true, 0);
    assert!(ratio < 1.0 && ratio > 0.59, "{ratio}");
    for row in rows {
        let tested = row["tested"].as_array().unwrap();
        assert!(tested.len() >= 2, "{row}");
        for w in tested.windows(2) {
            assert!(w[0]["scale"].as_i64() < w[1]["scale"].as_i64(), "{row}");
            assert!(w[0]["bytes"].as_u64() < w[1]["bytes"].as_u64(), "{row}");
        }
        for (reached, r) in row["reached"].as_array().unwrap().iter().zip(&ratios) {
            let within = |p: &Value| p["error"].as_f64().unwrap() <= r * direct_error;
            let first = tested.iter().find(|p| within(p));
            match first {
                Some(p) => assert_eq!(reached, p, "{row}"),
                None => assert!(reached.is_null(), "{row}"),
            }
        }
    }
}

#[test]
fn the_plots_are_png_and_svg_of_the_documented_size() {
    let (report, _) = sweep("plots", &["--no-equal-error", "--truth-samples", "0"]);
    // No truth image: no budget, and no field pretends to one.
    assert!(report["truth"].is_null(), "{}", report["truth"]);
    for p in report["points"].as_array().unwrap() {
        assert!(
            p["error_physics"].is_null() && p["physics"].is_null(),
            "{p}"
        );
    }
    assert!(report["equal_error"].is_null());
    for name in ["error-vs-time", "error-vs-memory"] {
        let png = tmp("plots", "plots").join(format!("{name}.png"));
        let img = image::open(&png)
            .expect("the plot decodes as PNG")
            .to_rgb8();
        assert_eq!(img.dimensions(), (1000, 700), "{name}");
        // Not blank: the white background plus drawn axes, points and text.
        let dark = img
            .pixels()
            .filter(|p| p.0.iter().all(|&c| c < 100))
            .count();
        assert!(dark > 1000, "{name}: {dark} dark pixels");
        let svg =
            std::fs::read_to_string(tmp("plots", "plots").join(format!("{name}.svg"))).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.contains("Pareto front"),
            "{name}"
        );
    }
}
