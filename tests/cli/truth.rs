//! `pixelflow-sim truth` as a user runs it: the image, its standard errors and the per-polygon
//! JSON written, the same bytes for any thread count, and bad requests refused with exit 2
//! before any sampling.

use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    crate::bin().args(args).output().expect("the binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_truth");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// `truth` on the two-spots plane with `threads` workers into files named after `tag`.
fn truth_run(tag: &str, threads: &str) -> (PathBuf, PathBuf, PathBuf) {
    let (exr, json) = (tmp(&format!("{tag}.exr")), tmp(&format!("{tag}.json")));
    let o = run(&[
        "truth",
        "scenes/two-spots.toml",
        "-o",
        exr.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--spp",
        "4",
        "--width",
        "16",
        "--height",
        "12",
        "--polygon-samples",
        "256",
        "--threads",
        threads,
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    (exr.clone(), exr.with_extension("stderr.exr"), json)
}

#[test]
fn truth_writes_the_image_its_errors_and_the_polygons() {
    let (exr, se, json) = truth_run("a", "2");
    let img = image::open(&exr).expect("EXR decodes").to_rgb32f();
    assert_eq!(img.dimensions(), (16, 12));
    // The plane fills the view and every point of it is lit by a spot.
    assert!(img.pixels().all(|p| p[0] > 0.0 && p[0].is_finite()));
    let err = image::open(&se).expect("EXR decodes").to_rgb32f();
    assert_eq!(err.dimensions(), (16, 12));
    assert!(err.pixels().all(|p| p[0] >= 0.0 && p[0].is_finite()));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let polygons = v["polygons"].as_array().unwrap();
    assert_eq!(polygons.len(), 1);
    let p = &polygons[0];
    for key in [
        "polygon",
        "object",
        "material",
        "area",
        "samples",
        "emission",
        "radiosity",
        "radiosity_se",
        "direct",
        "direct_se",
        "indirect",
        "indirect_se",
    ] {
        assert!(p.get(key).is_some(), "{key} missing: {p}");
    }
    assert_eq!(p["object"], "plane");
    assert_eq!(p["material"], "white");
    assert_eq!(p["samples"], 256);
    // A lone plane sees nothing it could reflect: all its light is direct.
    assert_eq!(p["indirect"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(p["radiosity"], p["direct"]);
    assert!(p["radiosity"][0].as_f64().unwrap() > 0.1);
    assert_eq!(v["seed"], 1);
}

#[test]
fn truth_writes_the_same_bytes_for_any_thread_count() {
    let one = truth_run("one", "1");
    let two = truth_run("two", "2");
    for (a, b) in [(one.0, two.0), (one.1, two.1), (one.2, two.2)] {
        assert_eq!(
            std::fs::read(&a).unwrap(),
            std::fs::read(&b).unwrap(),
            "{a:?}"
        );
    }
}

/// `--compare-solver` splits each face's error: the solution's own mean (`solution`, its
/// samples integrated over its leaves) against the truth is the solution's error, the mean as
/// rendered (`solver`, the RRPs) against `solution` the reconstruction's. On the two-spots plane
/// (direct light only, which the solver computes exactly up to its sampling) both are small:
/// the solution within 1 % of the truth plus 3 of its standard errors, and the reconstruction
/// within 0.5 % of the solution (the RRPs interpolate the samples; their mean differs by the
/// quadratures' difference on the spots' peaks).
#[test]
fn compare_solver_splits_each_faces_error_into_solution_and_reconstruction() {
    let json = tmp("compare.json");
    let o = run(&[
        "truth",
        "scenes/two-spots.toml",
        "--json",
        json.to_str().unwrap(),
        "--polygon-samples",
        "65536",
        "--compare-solver",
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let p = &v["polygons"][0];
    let get = |k: &str, c: usize| p[k][c].as_f64().unwrap_or_else(|| panic!("{k}: {p}"));
    for c in 0..3 {
        let (truth, se) = (get("radiosity", c), get("radiosity_se", c));
        let (solution, solver) = (get("solution", c), get("solver", c));
        assert!((solution - truth).abs() <= 0.01 * truth + 3.0 * se, "{p}");
        assert!((solver - solution).abs() <= 0.005 * solution, "{p}");
        // A lone plane: all its light is direct.
        assert_eq!(get("solution_direct", c), solution, "{p}");
    }
}

#[test]
fn truth_refuses_bad_requests_with_exit_2() {
    let out = tmp("bad.exr");
    let out = out.to_str().unwrap();
    let json = tmp("bad.json");
    let json = json.to_str().unwrap();
    let scene = "scenes/two-spots.toml";
    for (args, says) in [
        (
            vec!["truth", "no/such/scene.toml", "-o", out],
            "no/such/scene.toml",
        ),
        (
            vec!["truth", scene],
            "give -o out.exr for the image, --json out.json",
        ),
        (vec!["truth", scene, "-o", out, "--aa", "3"], "--aa 3"),
        (vec!["truth", scene, "-o", out, "--spp", "1"], "--spp 1"),
        (vec!["truth", scene, "-o", "x.png"], "name it .exr"),
        (
            vec!["truth", scene, "--shadow-mask", "x.png"],
            "--shadow-mask x.png",
        ),
        (
            vec!["truth", scene, "--json", json, "--strata", "0"],
            "--strata 0",
        ),
        (
            vec!["truth", scene, "--json", json, "--max-error", "0"],
            "--max-error 0",
        ),
        (
            vec!["truth", scene, "-o", out, "--compare-solver"],
            "--compare-solver",
        ),
        (
            vec!["truth", scene, "--json", scene],
            "refusing to overwrite an input",
        ),
        (
            vec!["truth", scene, "-o", out, "--width", "0"],
            "image size",
        ),
    ] {
        let o = run(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    }
}

/// `truth --shadow-mask` marks the pixels near the Cornell box's shadow boundaries (its boxes
/// shadow the floor and each other under the ceiling light), and `compare --mask` splits an
/// image's error at them: the pixels it counts are the mask's, and a mask of another size is
/// refused naming it.
#[test]
fn the_shadow_mask_marks_shadows_and_compare_splits_at_it() {
    let mask = tmp("cornell-mask.exr");
    let (a, b, c) = (
        tmp("cornell-a.exr"),
        tmp("cornell-b.exr"),
        tmp("cornell-c.exr"),
    );
    for (seed, out) in [("1", &a), ("2", &b), ("3", &c)] {
        let mut args = vec![
            "truth",
            "scenes/cornell-box.toml",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend([
            "--spp", "4", "--width", "48", "--height", "48", "--seed", seed,
        ]);
        if seed == "1" {
            args.extend(["--shadow-mask", mask.to_str().unwrap()]);
        }
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let m = image::open(&mask).expect("EXR decodes").to_rgb32f();
    assert_eq!(m.dimensions(), (48, 48));
    assert!(m.pixels().all(|p| p[0] == 0.0 || p[0] == 1.0));
    let marked = m.pixels().filter(|p| p[0] == 1.0).count();
    // Boxes on a floor under a light: some pixels, far from all of them.
    assert!(
        marked > 20 && marked < 48 * 48 / 2,
        "{marked} pixels marked"
    );
    let json = tmp("cornell-masked.json");
    let o = run(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--mask",
        mask.to_str().unwrap(),
        "--second-reference",
        c.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["masked"]["near_pixels"], marked);
    let (inside, outside) = (
        v["masked"]["rmse_near"].as_f64().unwrap(),
        v["masked"]["rmse_far"].as_f64().unwrap(),
    );
    assert!(inside > 0.0 && outside > 0.0, "{v}");
    assert_eq!(v["masked"]["ratio"].as_f64().unwrap(), inside / outside);
    // Three truths of one scene at three seeds, each as noisy as the others: against two
    // references the squared difference of `a` is its own variance plus one reference's, the
    // product of its two differences its own variance alone, half as much.
    let cross = &v["masked"]["cross"];
    assert_eq!(cross["near_pixels"], marked);
    let (cf, se) = (
        cross["rmse_far"].as_f64().unwrap(),
        cross["squared_se_far"].as_f64().unwrap(),
    );
    let half = 0.5 * outside * outside;
    assert!(
        (cf * cf - half).abs() <= 5.0 * se + 0.1 * half,
        "{cross}: {} against {half}",
        cf * cf
    );
    let o = run(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--second-reference",
        c.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--mask"), "{}", stderr(&o));
    let small = tmp("small.exr");
    let o = run(&[
        "truth",
        "scenes/cornell-box.toml",
        "--shadow-mask",
        small.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "8",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--mask",
        small.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("small.exr") && stderr(&o).contains("8 x 8"));
}
