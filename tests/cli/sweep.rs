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
            "frame_ms_interval",
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
    // The solutions' distance to the converged one: finite, not growing with density, and
    // zero here (two spots on a plane with nothing reflected back: every solution's exact
    // image is the direct light itself); the converged one has none.
    let conv: Vec<f64> = report["densities"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["converged"].as_f64().unwrap())
        .collect();
    assert!(conv.iter().all(|c| c.is_finite() && *c >= 0.0), "{conv:?}");
    assert!(conv[1] <= conv[0], "{conv:?}");
    assert!(report["reference"]["converged"].is_null());
    // The memory flags agree with the numbers: a flagged point is dominated by no other point,
    // an unflagged one by at least one.
    let e = |p: &Value| p["error_total"].as_f64().unwrap();
    for p in points {
        let (c, ei) = (p["bytes"].as_f64().unwrap(), e(p));
        let dominated = points.iter().any(|q| {
            let c2 = q["bytes"].as_f64().unwrap();
            c2 <= c && e(q) <= ei && (c2 < c || e(q) < ei)
        });
        assert_eq!(p["pareto_memory"].as_bool().unwrap(), !dominated, "{p}");
        // The time front: off it only when another point as accurate is faster beyond both
        // confidence intervals.
        let lo = p["frame_ms_interval"][0].as_f64().unwrap();
        let beaten = points
            .iter()
            .any(|q| e(q) <= ei && q["frame_ms_interval"][1].as_f64().unwrap() < lo);
        assert_eq!(p["pareto_time"].as_bool().unwrap(), !beaten, "{p}");
        assert!(lo <= p["frame_ms"].as_f64().unwrap(), "{p}");
        assert!(p["frame_ms"].as_f64().unwrap() <= p["frame_ms_interval"][1].as_f64().unwrap());
    }
    for flag in ["pareto_time", "pareto_memory"] {
        assert!(points.iter().any(|p| p[flag].as_bool().unwrap()));
    }
    // Timed in the default 6 separate processes, each density once per process.
    let timing = &report["timing"];
    assert_eq!(timing["processes"], 6);
    assert!((timing["coverage"].as_f64().unwrap() - 0.96875).abs() < 1e-12);
    assert_eq!(timing["load"].as_array().unwrap().len(), 12);
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
    assert_eq!(truth["parts"], 8, "{truth}");
    // Its spots' shadows are single rays to a point, and nothing else is random: a second
    // solver seed draws the same image.
    let seed = &report["solver_seed"];
    assert_eq!(seed["seeds"], serde_json::json!([1, 2]), "{seed}");
    assert_eq!(seed["same_image"], true, "{seed}");
    assert_eq!(seed["distance"], 0.0, "{seed}");
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
            assert_eq!(e["replicates"].as_array().unwrap().len(), 8, "{e}");
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
    // Across views: two-spots has no camera path, so its camera alone, at 64 x 64 and twice
    // that, for each of the 3 texture methods. At the sweep's own size the centre-placed,
    // mip-mapped curve is the one-view search's row, error for error.
    let views = report["equal_views"].as_array().unwrap();
    assert_eq!(views.len(), 6, "{views:?}");
    let sizes: Vec<(u64, u64)> = views
        .iter()
        .map(|c| (c["width"].as_u64().unwrap(), c["height"].as_u64().unwrap()))
        .collect();
    assert_eq!(&sizes[..3], [(64, 64); 3]);
    assert_eq!(&sizes[3..], [(128, 128); 3]);
    for c in &views[..3] {
        assert_eq!(c["direct_error"].as_f64().unwrap(), direct_error);
        let row = e["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| {
                r["method"] == c["method"] && r["placement"] == "centre" && r["mip_mapped"] == true
            })
            .unwrap();
        let curve: Vec<f64> = c["curve"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["error"].as_f64().unwrap())
            .collect();
        let tested: Vec<f64> = row["tested"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["error"].as_f64().unwrap())
            .collect();
        assert_eq!(
            curve[..tested.len().min(curve.len())],
            tested[..tested.len().min(curve.len())],
            "{}",
            c["method"]
        );
    }
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
    for name in [
        "error-vs-time",
        "error-vs-memory",
        "error-vs-samples",
        "error-vs-texture-size",
    ] {
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
        assert!(svg.starts_with("<svg"), "{name}");
        if name == "error-vs-time" || name == "error-vs-memory" {
            assert!(svg.contains("Pareto front"), "{name}");
        }
    }
}

/// `--sharp-levels 0` gives every method the same data (the spots' light from the solver's
/// samples, as the mesh draws it), and the report says which data the methods drew; a level
/// past the lattice's depth is refused before any solve.
#[test]
fn the_sweep_says_which_sharp_levels_its_methods_drew() {
    let (report, _) = sweep(
        "sharp0",
        &[
            "--sharp-levels",
            "0",
            "--methods",
            "direct,mesh",
            "--truth-samples",
            "0",
            "--no-equal-error",
            "--processes",
            "0",
        ],
    );
    assert_eq!(report["sharp_levels"], 0);
    let scene = Path::new(crate::REPO).join("scenes/two-spots.toml");
    let o = crate::bin()
        .args([
            "sweep",
            scene.to_str().unwrap(),
            "--sharp-levels",
            "17",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--sharp-levels"));
}
