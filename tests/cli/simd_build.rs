//! The SIMD build in outputs: `bench`, `stats` and `render --stats` name the build their frames
//! ran with, and a `PIXELFLOW_SIM_LANES` cap this CPU cannot run prints one warning saying what
//! runs instead.

use std::path::{Path, PathBuf};
use std::process::Output;

use lanes::{Isa, Level};

const LANES_ENV: &str = "PIXELFLOW_SIM_LANES";
const SCENE: &str = "scenes/two-spots.toml";

fn tmp(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("simd_build");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

/// Runs the binary with `args` and the lanes variable set to `lanes` (`None`: unset, whatever
/// the test's own environment holds).
fn run(lanes: Option<&str>, args: &[&str]) -> Output {
    let mut c = crate::bin();
    match lanes {
        Some(v) => c.env(LANES_ENV, v),
        None => c.env_remove(LANES_ENV),
    };
    c.args(args).output().expect("binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The bench's JSON rows, each naming its build.
fn bench_builds(lanes: Option<&str>) -> Vec<String> {
    let o = run(
        lanes,
        &["bench", SCENE, "--sizes", "32", "--frames", "1", "--json"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let rows: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = rows.as_array().unwrap();
    assert!(!rows.is_empty());
    rows.iter()
        .map(|r| r["simd"].as_str().expect("a simd field").to_string())
        .collect()
}

#[test]
fn bench_names_the_build_it_ran() {
    // Uncapped: the CPU's widest build; capped to portable: portable.
    let widest = Isa::detect().name();
    assert!(bench_builds(None).iter().all(|b| b == widest));
    assert!(bench_builds(Some("portable"))
        .iter()
        .all(|b| b == "portable"));
    // The text names it with its lanes, once, above the table.
    let o = run(None, &["bench", SCENE, "--sizes", "32", "--frames", "1"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let line = format!("simd build: {}\n", Isa::detect().level().describe());
    assert_eq!(
        text(&o.stdout).matches(&line).count(),
        1,
        "{}",
        text(&o.stdout)
    );
}

#[test]
fn stats_and_render_statistics_name_the_build() {
    let o = run(Some("avx2"), &["stats", SCENE, "--json"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let stats: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let avx2 = Isa::detect().capped(Level::Avx2).name();
    assert_eq!(stats["simd"], avx2);
    let o = run(Some("portable"), &["stats", SCENE]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stdout).contains("simd build: portable (8 f32 lanes)\n"),
        "{}",
        text(&o.stdout)
    );
    let (png, json) = (tmp("r.png"), tmp("r.json"));
    let o = run(
        Some("portable"),
        &[
            "render",
            SCENE,
            "--width",
            "16",
            "--height",
            "16",
            "-o",
            png.to_str().unwrap(),
            "--stats",
            json.to_str().unwrap(),
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(report["simd"], "portable");
}

#[test]
fn a_cap_this_cpu_cannot_run_warns_once() {
    let o = run(
        Some("avx512"),
        &["bench", SCENE, "--sizes", "16", "--frames", "1", "--json"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let err = text(&o.stderr);
    let running = Isa::detect().capped(Level::Avx512);
    let rows: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(rows[0]["simd"], running.name());
    let warnings: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with(&format!("warning: {LANES_ENV}")))
        .collect();
    if Isa::at(Level::Avx512).is_some() {
        assert!(warnings.is_empty(), "{err}");
        println!("this CPU runs avx512: checked that no warning is printed");
    } else {
        assert_eq!(warnings.len(), 1, "{err}");
        let w = warnings[0];
        assert!(
            w.starts_with("warning: PIXELFLOW_SIM_LANES=avx512: this CPU has no "),
            "{w}"
        );
        assert!(w.ends_with(&format!("; running {}", running.name())), "{w}");
    }
    // A cap below the CPU is a choice: no warning; an unknown value is a usage error.
    let o = run(Some("portable"), &["check", SCENE]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(!text(&o.stderr).contains("warning: PIXELFLOW_SIM_LANES"));
    let o = run(Some("avx1024"), &["check", SCENE]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("expected portable, avx2, avx512 or auto"));
}
