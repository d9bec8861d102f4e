//! `pixelflow-sim results` on a small case: two-spots (with a three-frame camera path added) at
//! 32 x 32, one timed frame per point. Checks that the page has every section, that every image
//! and plot it links exists and decodes, and that its numbers are the data's. No timing is
//! asserted.

use std::path::{Path, PathBuf};

use serde_json::Value;

fn dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("results");
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_results_page_links_every_image_and_quotes_its_data() {
    let d = dir();
    let scene = d.join("walk-spots.toml");
    let text = std::fs::read_to_string(Path::new(crate::REPO).join("scenes/two-spots.toml"))
        .unwrap()
        + "\n[camera_path]\nframes = 3\nkeyframes = [\n\
           { eye = [0.3, 0.5, 2.0], look_at = [0.3, 0.5, 0.0], up = [0.0, 1.0, 0.0] },\n\
           { eye = [0.7, 0.5, 2.0], look_at = [0.7, 0.5, 0.0], up = [0.0, 1.0, 0.0] },\n]\n";
    std::fs::write(&scene, text).unwrap();
    let doc = d.join("page.md");
    let o = crate::bin()
        .args([
            "results",
            "--doc",
            doc.to_str().unwrap(),
            "--scenes",
            scene.to_str().unwrap(),
            "--size",
            "32",
            "--gallery-width",
            "32",
            "--frames",
            "1",
            "--repeats",
            "1",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = std::fs::read_to_string(&doc).unwrap();
    for section in [
        "## walk-spots",
        "## Equal-error memory",
        "## Walkthrough frame rates",
        "## Image gallery",
        "## Commands",
    ] {
        assert!(page.contains(section), "missing {section}");
    }
    // Every linked image exists (relative to the page) and decodes.
    let mut links = 0;
    for part in page.split("](").skip(1) {
        let target = &part[..part.find(')').unwrap()];
        if target.ends_with(".png") {
            let path = d.join(target);
            image::open(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            links += 1;
        }
    }
    // 4 plots + 6 gallery images.
    assert_eq!(links, 10);
    // The data beside the page, and the page quoting it.
    let data: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("results/results.json")).unwrap())
            .unwrap();
    let sc = &data["scenes"][0];
    assert_eq!(sc["name"], "walk-spots");
    let walk = sc["walkthrough"].as_array().unwrap();
    let methods: Vec<&str> = walk.iter().map(|w| w["method"].as_str().unwrap()).collect();
    assert_eq!(
        methods,
        [
            "direct",
            "texture-nearest",
            "texture-bilinear",
            "texture-bicubic",
            "mesh"
        ]
    );
    for w in walk {
        let s = &w["summary"];
        assert_eq!(s["frames"], 3);
        let (lo, med, hi) = (
            s["fps_min"].as_f64().unwrap(),
            s["fps_median"].as_f64().unwrap(),
            s["fps_max"].as_f64().unwrap(),
        );
        assert!(0.0 < lo && lo <= med && med <= hi, "{s}");
        // Also flown in the default 6 separate processes: the median inside its interval.
        let p = &w["processes"];
        assert_eq!(p["processes"], 6, "{w}");
        let (a, m, b) = (
            p["interval"][0].as_f64().unwrap(),
            p["fps"].as_f64().unwrap(),
            p["interval"][1].as_f64().unwrap(),
        );
        assert!(0.0 < a && a <= m && m <= b, "{p}");
    }
    assert_eq!(sc["walkthrough_load"].as_array().unwrap().len(), 6);
    // The error along the path: all three frames, four methods, the textures within the
    // RRPs' bytes, every error finite and the page quoting the direct method's first.
    let we = &sc["walk_errors"];
    assert_eq!(we["frames"], serde_json::json!([0, 1, 2]));
    let wm = we["methods"].as_array().unwrap();
    assert_eq!(wm.len(), 4);
    assert!(wm[1]["bytes"].as_u64().unwrap() <= wm[0]["bytes"].as_u64().unwrap());
    for m in wm {
        let e = m["errors"].as_array().unwrap();
        assert_eq!(e.len(), 3);
        assert!(e.iter().all(|x| x.as_f64().unwrap().is_finite()), "{m}");
    }
    assert!(page.contains(&format!(
        "| 0 | {:.3} |",
        wm[0]["errors"][0].as_f64().unwrap()
    )));
    assert!(page.contains("## Table 1 at matched error"));
    let gallery = sc["gallery"].as_array().unwrap();
    assert_eq!(gallery.len(), 6);
    assert_eq!(gallery[0]["method"], "reference");
    assert_eq!(gallery[0]["error"], 0.0);
    for g in &gallery[1..] {
        let e = g["error"].as_f64().unwrap();
        assert!(e > 0.0 && e.is_finite(), "{g}");
        // The page prints each distance to 3 decimals under its image.
        assert!(page.contains(&format!(" {e:.3} |")), "{g}");
    }
    // The error budget quotes each density's solution error against the path tracer, with its
    // interval (two-spots' truth is exact, so every figure is resolved), which term is larger
    // where the intervals say so, which method is nearer the light, and the solver's seed.
    assert!(page.contains("**Error budget against physics**"));
    assert!(page.contains(", it is the larger term at "));
    assert!(page.contains("**Which method is nearer the light**"));
    assert!(page.contains("pairs are called"));
    assert!(page.contains("**Solver seed.** Solved again with seed 2"));
    for d in sc["sweep"]["densities"].as_array().unwrap() {
        let e = d["solution"]["perceptual"].as_f64().unwrap();
        assert!(e.is_finite() && e >= 0.0, "{d}");
        assert!(d["solution"]["resolved"].as_bool().unwrap(), "{d}");
        assert!(page.contains(&format!(" | {e:.3} (")), "{d}");
    }
    let direct = &sc["sweep"]["equal_error"]["direct_error"];
    assert!(page.contains(&format!(
        "reconstruction error {:.3}",
        direct.as_f64().unwrap()
    )));
}

/// A failure late in the run (here a directory where a gallery image goes, which only the
/// image's own write finds) leaves none of the run's files: the data, plots and page appear
/// together or not at all.
#[test]
fn a_results_run_that_fails_late_writes_nothing() {
    let d = dir().join("held");
    let _ = std::fs::remove_dir_all(&d);
    let obstacle = d.join("results/two-spots/gallery-mesh.png");
    std::fs::create_dir_all(&obstacle).unwrap();
    let doc = d.join("page.md");
    let o = crate::bin()
        .current_dir(crate::REPO)
        .args(["results", "--doc", doc.to_str().unwrap()])
        .args(["--scenes", "scenes/two-spots.toml", "--size", "32"])
        .args(["--gallery-width", "32", "--frames", "1", "--repeats", "1"])
        .args(["--truth-samples", "0", "--quiet"])
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("gallery-mesh.png"));
    let mut left = Vec::new();
    let mut stack = vec![d.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            if e.file_type().unwrap().is_dir() {
                stack.push(e.path());
            } else {
                left.push(e.path());
            }
        }
    }
    assert!(left.is_empty(), "files left by a failed run: {left:?}");
}

#[test]
fn bad_options_are_refused_before_any_work() {
    let d = dir();
    let doc = d.join("refused.md");
    for args in [
        vec!["--gallery-width", "0"],
        vec!["--size", "0"],
        vec!["--scenes", "scenes/none.toml"],
        vec!["--scenes", "scenes/two-spots.toml,scenes/two-spots.toml"],
    ] {
        let mut a = vec!["--doc", doc.to_str().unwrap()];
        a.extend(&args);
        let o = crate::bin()
            .current_dir(crate::REPO)
            .arg("results")
            .args(&a)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        assert!(!doc.exists(), "{args:?}");
    }
}

/// The page is written only where it is named: without `--doc` nothing runs (a checkout's
/// committed docs/results.md is never replaced by default).
#[test]
fn results_needs_the_page_named() {
    let o = crate::bin()
        .current_dir(crate::REPO)
        .args(["results", "--scenes", "scenes/two-spots.toml"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--doc"));
}
