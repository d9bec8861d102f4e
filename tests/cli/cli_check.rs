//! `pixelflow-sim check`, run as a process: exit codes 0 (valid scene) and 2 (bad input or
//! usage), the summary on stdout, warnings and errors on stderr.

use std::path::{Path, PathBuf};
use std::process::Output;

fn run(args: &[&str]) -> Output {
    crate::bin()
        .args(args)
        .current_dir(crate::REPO)
        .output()
        .expect("the binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pfs-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn check_valid_scene_prints_summary_and_exits_0() {
    let out = run(&["check", "scenes/two-spots.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(
        stdout.contains("polygons        1 (1 quads, 0 triangles)"),
        "{stdout}"
    );
    assert!(stdout.contains("spot lights     2"), "{stdout}");
    assert!(stdout.contains("image           256 x 256"), "{stdout}");
    assert!(text(&out.stderr).is_empty());
}

/// The furnished rooms docs/accuracy.md measures load: 320 x 240, one emitter, the floor and
/// walls cut along the furniture's feet.
#[test]
fn check_accepts_the_furnished_rooms_of_the_accuracy_page() {
    for room in ["furnished-room", "furnished-room-small-light"] {
        let path = format!("scenes/accuracy/{room}.toml");
        let out = run(&["check", &path]);
        assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
        let stdout = text(&out.stdout);
        assert!(stdout.contains("image           320 x 240"), "{stdout}");
        assert!(stdout.contains("emitters        1 polygons"), "{stdout}");
        assert!(stdout.contains("contact lines   46"), "{stdout}");
    }
}

#[test]
fn check_cornell_lists_its_repairs_as_notes_and_exits_0() {
    let out = run(&["check", "scenes/cornell-box.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    assert!(
        stderr.starts_with("note: scenes/cornell-box/CornellBox-Original.obj:62:"),
        "{stderr}"
    );
    assert!(!stderr.contains("warning:"), "{stderr}");
    assert!(stderr.contains("split into two triangles"), "{stderr}");
    assert!(
        stderr.contains("12 contact lines")
            && stderr.contains("4 of them sides of polygons lying close over another")
            && stderr.contains("cut 2 polygons into 39 pieces"),
        "{stderr}"
    );
    let stdout = text(&out.stdout);
    // 17 faces, the floor among them cut into 30 pieces (10 of them triangles), the ceiling
    // into 9 along the lamp's outline.
    assert!(
        stdout.contains("polygons        54 (44 quads, 10 triangles)"),
        "{stdout}"
    );
    assert!(stdout.contains("emitters        1 polygons"), "{stdout}");
}

#[test]
fn check_bad_scene_names_file_line_and_key_and_exits_2() {
    let dir = scratch("bad");
    let scene = dir.join("bad.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\nfov_y = 40\n\n[[materials]]\nname = \"m\"\nreflectance = [0.5, 1.2, 0.5]\n",
    )
    .unwrap();
    let out = run(&["check", scene.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = text(&out.stderr);
    let expect = format!(
        "error: {}:8: materials[0].reflectance: component 1 is 1.2",
        scene.display()
    );
    assert!(stderr.starts_with(&expect), "{stderr}");
    assert!(text(&out.stdout).is_empty());
}

#[test]
fn check_missing_file_exits_2() {
    let out = run(&["check", "no/such/scene.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("no/such/scene.toml: cannot read scene file"));
}

#[test]
fn usage_errors_exit_2_and_help_exits_0() {
    assert_eq!(run(&[]).status.code(), Some(2));
    assert_eq!(run(&["check"]).status.code(), Some(2));
    assert_eq!(run(&["frobnicate"]).status.code(), Some(2));
    let help = run(&["check", "--help"]);
    assert_eq!(help.status.code(), Some(0));
    assert!(text(&help.stdout).contains("Load and validate a scene file"));
    assert!(Path::new(env!("CARGO_BIN_EXE_pixelflow-sim")).exists());
}

#[test]
fn gallery_fine_is_the_gallery_with_a_finer_solve() {
    // Same geometry, lights, camera and path as gallery.toml; only [radiosity] differs.
    use scene::load_scene;
    let root = std::path::Path::new(crate::REPO);
    let a = load_scene(&root.join("scenes/gallery.toml")).unwrap();
    let b = load_scene(&root.join("scenes/gallery-fine.toml")).unwrap();
    assert_eq!(a.polygons.len(), b.polygons.len());
    assert_eq!(a.spots, b.spots);
    assert_eq!(a.camera, b.camera);
    assert_eq!(a.camera_path, b.camera_path);
    assert!(b.radiosity.tolerance < a.radiosity.tolerance);
    assert!(b.radiosity.max_depth > a.radiosity.max_depth);
}

/// Inputs are read with a size limit and requests with absurd counts are refused before any
/// work. Regressions: an include pointing at an endless file grew memory until the allocator
/// aborted; `--threads 100000` and `--frames 4294967295` ran until they aborted or for hours.
#[cfg(unix)]
#[test]
fn endless_inputs_and_absurd_counts_are_refused_with_exit_2() {
    let d = scratch("endless");
    let scene = d.join("z.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov_y = 40\n\n[[materials]]\nname = \"grey\"\n\
         reflectance = [0.5, 0.5, 0.5]\n\n[[obj]]\nfile = \"/dev/zero\"\n",
    )
    .unwrap();
    let out = run(&["check", scene.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    let err = text(&out.stderr);
    assert!(
        err.contains("obj[0].file") && err.contains("larger than"),
        "{err}"
    );
    // What broke: under a 64M limit an endless include was read to 1 GiB. Reads now stop at
    // half of what the memory limit leaves past the program's own 8 MiB: 28 MiB.
    let out = run(&["check", scene.to_str().unwrap(), "--memory-limit", "64M"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("larger than 29360128 bytes"),
        "{}",
        text(&out.stderr)
    );
    // A scene file that never ends, and a compare input that never ends.
    let out = run(&["check", "/dev/zero"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("larger than"));
    let cases: [&[&str]; 4] = [
        &["render", "scenes/two-spots.toml", "--threads", "100000"],
        &["bench", "scenes/two-spots.toml", "--frames", "4294967295"],
        &["stats", "scenes/two-spots.toml", "--frames", "4294967295"],
        &["sweep", "scenes/two-spots.toml", "--frames", "4294967295"],
    ];
    for args in cases {
        let out = run(args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
}

/// Memory over the limit is refused before the allocation, with exit 2 and the estimate in the
/// message: `check` reports the estimate against the limit and fails over it; a solve whose
/// starting trees cannot fit, a solve whose refinement would pass the limit, a frame too large,
/// and textures too large are each refused within seconds.
#[test]
fn memory_requests_over_the_limit_are_refused_with_the_estimate() {
    let out = run(&["check", "scenes/two-spots.toml"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(stdout.contains("verdict         fits\n"), "{stdout}");
    assert!(stdout.contains("solve at start  "), "{stdout}");

    let out = run(&["check", "scenes/two-spots.toml", "--memory-limit", "1K"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("memory limit    1.0 KiB\n"));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("the solve of scenes/two-spots.toml needs an estimated")
            && stderr.contains("over the memory limit of 1.0 KiB"),
        "{stderr}"
    );

    // One quad forced to depth 16 from the start: 4^17 / 3 nodes, hundreds of GiB.
    let dir = scratch("memory");
    let deep = dir.join("deep.toml");
    std::fs::write(
        &deep,
        "[camera]\neye = [0.5, 0.5, 2]\nlook_at = [0.5, 0.5, 0]\nfov_y = 40\n\
         [[materials]]\nname = \"w\"\nreflectance = [0.5, 0.5, 0.5]\n\
         [[polygons]]\nvertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]\nmaterial = \"w\"\n\
         [[spots]]\nposition = [0.5, 0.5, 1]\ndirection = [0, 0, -1]\nintensity = [1, 1, 1]\nhalf_angle = 60\n\
         [radiosity]\nmin_depth = 16\nmax_depth = 16\n",
    )
    .unwrap();
    let deep = deep.to_str().unwrap();
    let never = dir.join("never.pfsol");
    for cmd in [
        vec!["check", deep, "--memory-limit", "16G"],
        vec![
            "solve",
            deep,
            "-o",
            never.to_str().unwrap(),
            "--memory-limit",
            "16G",
        ],
    ] {
        let out = run(&cmd);
        assert_eq!(out.status.code(), Some(2), "{cmd:?}: {}", text(&out.stderr));
        let stderr = text(&out.stderr);
        assert!(
            stderr.contains("needs an estimated 5.8 TiB (program 8.0 MiB + quadtrees and samples"),
            "{cmd:?}: {stderr}"
        );
    }
    assert!(!never.exists(), "a refused solve wrote its output");

    // The solve's own guard: the Cornell box starts at 400 KiB but refines past the 2 MiB a
    // 10 MiB limit leaves past the program's own 8 MiB.
    let out = run(&[
        "solve",
        "scenes/cornell-box.toml",
        "-o",
        dir.join("c.pfsol").to_str().unwrap(),
        "--memory-limit",
        "10M",
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("in this refinement pass") && stderr.contains("over the memory limit"),
        "{stderr}"
    );
    assert!(!dir.join("c.pfsol").exists());

    // The largest documented frame, with every output: the image and the PNG and EXR buffers
    // are 10.5 GiB.
    let png = dir.join("big.png");
    let out = run(&[
        "render",
        "scenes/two-spots.toml",
        "--width",
        "16384",
        "--height",
        "16384",
        "--aa",
        "16",
        "--exr",
        dir.join("big.exr").to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--memory-limit",
        "8G",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("a 16384 x 16384 frame with 16 samples per pixel needs"),
        "{}",
        text(&out.stderr)
    );

    // 4096^2 textures: 4096^2 x 12 B x 4/3 = 256 MiB for the one polygon, plus the 2-texel
    // gutters of its 13 levels (4 x 2 x (m + 2) texels each, 0.9 MiB in all).
    let out = run(&[
        "render",
        "scenes/two-spots.toml",
        "--method",
        "texture-bilinear",
        "--texture-size",
        "4096",
        "-o",
        png.to_str().unwrap(),
        "--memory-limit",
        "100M",
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("textures and expanded RRPs 256.9 MiB"),
        "{}",
        text(&out.stderr)
    );
    assert!(!png.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// What broke: the default memory limit read only the machine's RAM, so under `ulimit -v 4G`
/// `check` called a solve that needed 9.9 GiB fitting (limit 17.7 GiB) and the solve aborted.
/// The default is now at most half the address-space limit.
#[test]
fn the_default_limit_follows_ulimit_v() {
    if !Path::new("/proc/self/limits").exists() || !Path::new("/bin/sh").exists() {
        return;
    }
    let scene = Path::new(crate::REPO).join("scenes/two-spots.toml");
    let o = std::process::Command::new("/bin/sh")
        .arg("-c")
        .arg("ulimit -v 4194304 && exec \"$0\" check \"$1\"")
        .arg(env!("CARGO_BIN_EXE_pixelflow-sim"))
        .arg(&scene)
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{out}");
    let line = out
        .lines()
        .find(|l| l.starts_with("memory limit"))
        .unwrap_or_else(|| panic!("no limit line: {out}"));
    // At most 2 GiB (less where the machine or its cgroup allows less).
    let words: Vec<&str> = line.split_whitespace().collect();
    let (value, unit) = (words[2].parse::<f64>().unwrap(), words[3]);
    let gib = match unit {
        "GiB" => value,
        "MiB" => value / 1024.0,
        "KiB" => value / (1024.0 * 1024.0),
        _ => panic!("{line}"),
    };
    assert!(gib <= 2.0, "{line}");
}

/// The frame's memory estimate brackets what a render holds: the estimate (read from the
/// refusal under a 1 KiB limit) is never below the measured peak less the program and the
/// solution (8 MiB here), and not more than 1.5 times it. What broke: a whole-frame bound
/// estimated 13.7 GiB for a render that peaked at 0.58 GiB, and refused it under 8G.
#[test]
fn the_frame_estimate_brackets_the_measured_peak() {
    if !crate::can_measure_peaks() {
        return;
    }
    let dir = scratch("frame-peak");
    let sol = dir.join("two-spots.pfsol");
    let out = run(&[
        "solve",
        "scenes/two-spots.toml",
        "-o",
        sol.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let (exr, png) = (dir.join("f.exr"), dir.join("f.png"));
    for (side, aa) in [("1024", "16"), ("2048", "4")] {
        let args = [
            "render",
            sol.to_str().unwrap(),
            "--width",
            side,
            "--height",
            side,
            "--aa",
            aa,
            "--exr",
            exr.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--quiet",
        ];
        let mut refused = args.to_vec();
        refused.extend(["--memory-limit", "1K"]);
        let out = run(&refused);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
        // The quoted estimate counts the program's own memory: the whole peak is compared.
        let mib = quoted_estimate_mib(&text(&out.stderr));
        let peak = crate::peak_bytes(&args);
        let held = peak as f64 / (1 << 20) as f64;
        assert!(
            held <= mib,
            "{side}^2 aa {aa}: held {held:.1} MiB, estimated {mib}"
        );
        assert!(
            held * 1.5 >= mib,
            "{side}^2 aa {aa}: held {held:.1} MiB, estimated {mib}: over 1.5x"
        );
    }
}

/// The estimate a refusal quotes, in MiB.
fn quoted_estimate_mib(stderr: &str) -> f64 {
    stderr
        .split("needs an estimated ")
        .nth(1)
        .and_then(|r| r.split(" MiB").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no estimate in MiB: {stderr}"))
}

/// The radiosity textures' estimate brackets what a texture render holds (as the frame's
/// does): never below the measured peak less the program, at most 1.5 times it.
#[test]
fn the_texture_estimate_brackets_the_measured_peak() {
    if !crate::can_measure_peaks() {
        return;
    }
    let dir = scratch("texture-peak");
    let sol = dir.join("cornell.pfsol");
    let out = run(&[
        "solve",
        "scenes/cornell-box.toml",
        "-o",
        sol.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let png = dir.join("t.png");
    let args = [
        "render",
        sol.to_str().unwrap(),
        "--method",
        "texture-bicubic",
        "--texture-budget",
        "64M",
        "-o",
        png.to_str().unwrap(),
        "--quiet",
    ];
    let mut refused = args.to_vec();
    // Past the program's own 8 MiB: over the solution file's size (the input cap is half of
    // what is left) and the frame's (6.1 MiB with the luminance summary's buffer), under the
    // textures.
    refused.extend(["--memory-limit", "16M"]);
    let out = run(&refused);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    assert!(e.contains("radiosity textures"), "{e}");
    let mib = quoted_estimate_mib(&e);
    // The quoted estimate counts the program's own memory: the whole peak is compared.
    let held = crate::peak_bytes(&args) as f64 / (1 << 20) as f64;
    assert!(held <= mib, "held {held:.1} MiB, estimated {mib}");
    assert!(
        held * 1.5 >= mib,
        "held {held:.1} MiB, estimated {mib}: over 1.5x"
    );
}

/// The solve's memory guard is honest in both directions: a solve is admitted under 1.5 times
/// what it holds unlimited, and under the smallest limit it is admitted at (found by
/// bisection) it holds no more than 10 % over that limit. What broke: gallery-fine under a
/// 100 MiB limit peaked at 124-151 MiB (worker buffers, shapes and the file not counted).
#[test]
fn the_solve_guard_brackets_the_measured_peak() {
    if !crate::can_measure_peaks() {
        return;
    }
    let dir = scratch("solve-peak");
    let sol = dir.join("cornell.pfsol");
    let s = sol.to_str().unwrap();
    // Two levels shallower than the shipped box: the same kinds of memory, in about two fifths
    // of its CPU time.
    let base = [
        "solve",
        "scenes/cornell-box.toml",
        "-D",
        "radiosity.max_depth=5",
        "-o",
        s,
        "--quiet",
    ];
    let mib = |bytes: u64| bytes as f64 / (1 << 20) as f64;
    // Resident peaks throughout: the limit now covers the program's own memory too.
    let held = mib(crate::peak_bytes(&base));
    let solve_under = |limit_mib: f64| {
        let limit = format!("{}K", (limit_mib * 1024.0) as u64);
        let mut args = base.to_vec();
        args.extend(["--memory-limit", &limit]);
        let (code, peak, err) = crate::run_measured(&args);
        match code {
            Some(0) => {
                let h = mib(peak);
                assert!(
                    h <= 1.1 * limit_mib,
                    "held {h:.1} MiB under a {limit_mib:.1} MiB limit"
                );
                true
            }
            Some(2) => {
                assert!(err.contains("the solve of"), "{err}");
                false
            }
            other => panic!("exit {other:?} under {limit_mib:.1} MiB: {err}"),
        }
    };
    let (mut lo, mut hi) = (held / 4.0, 1.5 * held);
    assert!(
        solve_under(hi),
        "refused under 1.5x the {held:.1} MiB it holds"
    );
    assert!(
        !solve_under(lo),
        "admitted under a quarter of what it holds"
    );
    // Two bisection steps: each admitted or refused solve checks the bracket again (a solve
    // costs seconds; four steps made this the slowest test of the binary).
    for _ in 0..2 {
        let mid = 0.5 * (lo + hi);
        if solve_under(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
}

/// A scene whose light is too small and close for its `max_depth` (an emitter 1 mm wide 2 cm
/// over a 1 m floor; the light-driven depth gives way at `max_depth = 2`, so the guard stops
/// refinement where the light still varies): `solve`, `check` on the solution, `stats` and
/// `render --stats` all say so, naming the floor's file and line.
#[test]
fn a_guard_stop_is_reported_by_solve_check_stats_and_render() {
    let dir = scratch("guard");
    let scene = dir.join("guard.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0.5, -1.0, 1.0]\nlook_at = [0.5, 0.5, 0.0]\nfov_y = 50.0\n\n\
         [image]\nwidth = 32\nheight = 32\n\n\
         [[materials]]\nname = \"grey\"\nreflectance = [0.5, 0.5, 0.5]\n\n\
         [[materials]]\nname = \"lamp\"\nreflectance = [0.0, 0.0, 0.0]\nemission = [1000.0, 1000.0, 1000.0]\n\n\
         [[polygons]]\nname = \"floor\"\nvertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]\nmaterial = \"grey\"\n\n\
         [[polygons]]\nname = \"lamp\"\nvertices = [[0.4132, 0.5816, 0.02], [0.4132, 0.5826, 0.02], [0.4142, 0.5826, 0.02], [0.4142, 0.5816, 0.02]]\nmaterial = \"lamp\"\n\n\
         [radiosity]\nmin_depth = 0\nmax_depth = 2\n",
    )
    .unwrap();
    let sol = dir.join("guard.pfsol");
    let (scene_s, sol_s) = (scene.to_str().unwrap(), sol.to_str().unwrap());
    let solved = run(&["solve", scene_s, "-o", sol_s, "--quiet"]);
    assert_eq!(solved.status.code(), Some(0), "{}", text(&solved.stderr));
    // The floor's `vertices` line.
    let floor_at = format!("{scene_s}:21: polygons[0].vertices");
    let warned = |stderr: &str| {
        stderr.contains("warning: refinement stopped at radiosity.max_depth = 2")
            && stderr.contains(&floor_at)
    };
    assert!(warned(&text(&solved.stderr)), "{}", text(&solved.stderr));
    let checked = run(&["check", sol_s]);
    assert_eq!(checked.status.code(), Some(0), "{}", text(&checked.stderr));
    assert!(warned(&text(&checked.stderr)), "{}", text(&checked.stderr));
    let stats = run(&["stats", sol_s, "--frames", "0", "--json"]);
    assert_eq!(stats.status.code(), Some(0), "{}", text(&stats.stderr));
    let json: serde_json::Value = serde_json::from_slice(&stats.stdout).unwrap();
    let g = &json["guard_stops"];
    assert!(g["leaves"].as_u64().unwrap() > 0, "{g}");
    assert_eq!(g["worst"].as_str(), Some(floor_at.as_str()), "{g}");
    assert!(g["worst_excess"].as_f64().unwrap() > 0.01, "{g}");
    assert!(g["error_share"].as_f64().unwrap() > 0.01, "{g}");
    let report = dir.join("frame.json");
    let png = dir.join("frame.png");
    let rendered = run(&[
        "render",
        sol_s,
        "-o",
        png.to_str().unwrap(),
        "--stats",
        report.to_str().unwrap(),
    ]);
    assert_eq!(
        rendered.status.code(),
        Some(0),
        "{}",
        text(&rendered.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["guard_stops"]["leaves"], g["leaves"], "{json}");
    // Deep enough, the light is resolved: nothing to report.
    let deep = dir.join("deep.toml");
    let text_in = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&deep, text_in.replace("max_depth = 2", "max_depth = 10")).unwrap();
    let sol2 = dir.join("deep.pfsol");
    let solved = run(&[
        "solve",
        deep.to_str().unwrap(),
        "-o",
        sol2.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(solved.status.code(), Some(0), "{}", text(&solved.stderr));
    assert!(
        !text(&solved.stderr).contains("refinement stopped"),
        "{}",
        text(&solved.stderr)
    );
    let checked = run(&["check", sol2.to_str().unwrap()]);
    assert!(
        text(&checked.stdout).contains("guard stops: none"),
        "{}",
        text(&checked.stdout)
    );
}

/// A scene read from a pipe is read once: the probe for a solution file's magic bytes used to
/// take the first bytes of the scene (`check <(cat scene.toml)` was refused as "not a scene").
#[test]
fn a_scene_from_a_pipe_is_read_once() {
    use std::io::Write;
    let scene = std::fs::read(Path::new(crate::REPO).join("scenes/two-spots.toml")).unwrap();
    let mut child = crate::bin()
        .current_dir(crate::REPO)
        .args(["check", "/dev/stdin"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&scene).unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("spot lights     2"),
        "{}",
        text(&out.stdout)
    );
}

/// Paths written inside a file are relative to the file a symbolic link leads to, not to the
/// link: a scene linked from another folder finds its OBJ beside itself, and a solution linked
/// from a folder at another depth finds its scene. What broke: a linked solution looked for its
/// scene beside the link.
#[test]
fn links_are_followed_before_relative_paths() {
    let dir = scratch("links");
    let real = dir.join("real");
    let other = dir.join("other").join("deeper");
    std::fs::create_dir_all(&real).unwrap();
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(
        real.join("room.obj"),
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.4 0.4 0.5\nv 0.6 0.4 0.5\nv 0.6 0.6 0.5\n\
         v 0.4 0.6 0.5\nusemtl grey\nf 1 2 3 4\nusemtl lamp\nf 8 7 6 5\n",
    )
    .unwrap();
    std::fs::write(
        real.join("room.toml"),
        "[camera]\neye = [0.5, -1.0, 1.0]\nlook_at = [0.5, 0.5, 0.0]\nfov_y = 50.0\n\n\
         [image]\nwidth = 16\nheight = 16\n\n\
         [[materials]]\nname = \"grey\"\nreflectance = [0.5, 0.5, 0.5]\n\n\
         [[materials]]\nname = \"lamp\"\nreflectance = [0.0, 0.0, 0.0]\nemission = [1.0, 1.0, 1.0]\n\n\
         [[obj]]\nfile = \"room.obj\"\nmaterials = { grey = \"grey\", lamp = \"lamp\" }\n\n[radiosity]\nmax_depth = 3\n",
    )
    .unwrap();
    let scene_link = other.join("room-link.toml");
    std::os::unix::fs::symlink(real.join("room.toml"), &scene_link).unwrap();
    let out = run(&["check", scene_link.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));

    let sol = real.join("room.pfsol");
    let s = sol.to_str().unwrap();
    let out = run(&[
        "solve",
        real.join("room.toml").to_str().unwrap(),
        "-o",
        s,
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let sol_link = other.join("room-link.pfsol");
    std::os::unix::fs::symlink(&sol, &sol_link).unwrap();
    let out = run(&["check", sol_link.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
}

/// Parsing is held to the memory limit as well as reading: an OBJ and an MTL far smaller than
/// the input cap (half the limit) but whose parsed form is far larger are refused before they
/// are parsed, naming the file and what it holds, and the refusal's peak stays under the
/// limit; with room they load. What broke: MTL
/// parsing reached 646 MB under a 64 MiB limit.
#[test]
fn parsing_an_obj_or_mtl_is_held_to_the_memory_limit() {
    let dir = scratch("parse-memory");
    let mut mtl = String::new();
    for i in 0..60_000 {
        mtl += &format!("newmtl m{i}\nKd 0.5 0.5 0.5\n");
    }
    std::fs::write(dir.join("many.mtl"), &mtl).unwrap();
    std::fs::write(
        dir.join("m.obj"),
        "mtllib many.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl m0\nf 1 2 3 4\n",
    )
    .unwrap();
    let mut obj = String::new();
    let n = 200;
    for j in 0..=n {
        for i in 0..=n {
            obj += &format!("v {i} {j} 0\n");
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i + 1;
            obj += &format!("f {a} {} {} {}\n", a + 1, a + n + 2, a + n + 1);
        }
    }
    std::fs::write(dir.join("grid.obj"), &obj).unwrap();
    for (model, file, what) in [
        ("m.obj", "many.mtl", "60000 materials"),
        ("grid.obj", "grid.obj", "40000 faces"),
    ] {
        let path = dir.join(model);
        let p = path.to_str().unwrap();
        // 2.0 MB of MTL (about 70 MB parsed) and 2.4 MB of OBJ (about 30 MB) under 24 MiB:
        // 16 MiB for the data past the program's own, files read up to 8 MiB.
        let small = ["check", p, "--memory-limit", "24M"];
        let out = run(&small);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
        let e = text(&out.stderr);
        assert!(
            e.contains(file) && e.contains(what) && e.contains("memory limit"),
            "{e}"
        );
        if crate::can_measure_peaks() {
            let (code, peak, _) = crate::run_measured(&small);
            assert_eq!(code, Some(2));
            let held = peak as f64 / (1 << 20) as f64;
            assert!(held <= 24.0, "held {held:.1} MiB refusing under 24 MiB");
        }
        let out = run(&["check", p, "--memory-limit", "4G"]);
        assert!(out.status.success(), "{}", text(&out.stderr));
    }
}

/// Under an address-space cap (`ulimit -v`, whose half is the default memory limit) an MTL
/// whose parsed form would not fit is refused with exit 2 and the estimate, not aborted by
/// the allocator. What broke: a 45 MB MTL aborted `check` under a 4 GiB cap.
#[test]
fn an_mtl_too_large_to_parse_under_ulimit_v_is_refused_not_aborted() {
    let dir = scratch("ulimit-mtl");
    let mut mtl = String::with_capacity(16 << 20);
    for i in 0..500_000 {
        mtl += &format!("newmtl m{i}\nKd 0.5 0.5 0.5\n");
    }
    std::fs::write(dir.join("many.mtl"), &mtl).unwrap();
    let obj = dir.join("m.obj");
    std::fs::write(
        &obj,
        "mtllib many.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl m0\nf 1 2 3 4\n",
    )
    .unwrap();
    // 768 MiB of address space: a default limit of 384 MiB against an estimate near 600 MiB
    // (the parse itself holds about 480 MB).
    let out = std::process::Command::new("sh")
        .args(["-c", "ulimit -v 786432 && exec \"$0\" check \"$1\""])
        .arg(env!("CARGO_BIN_EXE_pixelflow-sim"))
        .arg(&obj)
        .output()
        .expect("sh runs");
    let e = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(
        e.contains("many.mtl") && e.contains("500000 materials"),
        "{e}"
    );
}
