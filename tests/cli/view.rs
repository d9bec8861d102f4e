//! `pixelflow-sim view` without a window: a recorded session replayed, its last frame written.
//! At the scene's camera the frame is the PNG `render` writes, byte for byte; keys move the
//! camera and switch the method; a bad script is refused with its line.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::bin;

fn scratch() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_view");
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn a_replayed_session_draws_what_render_draws() {
    let dir = scratch();
    let sol = dir.join("cornell.pfsol");
    let o = run(&[
        "solve",
        "scenes/cornell-box.toml",
        "-o",
        sol.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let sol = sol.to_str().unwrap();
    let size = ["--width", "96", "--height", "64"];
    let view = |name: &str, script: &str| -> (Vec<u8>, String) {
        let s = dir.join(format!("{name}.txt"));
        std::fs::write(&s, script).unwrap();
        let png = dir.join(format!("{name}.png"));
        let mut args = vec!["view", sol, "--script", s.to_str().unwrap()];
        args.extend(["--screenshot", png.to_str().unwrap()]);
        args.extend(size);
        let o = run(&args);
        assert!(o.status.success(), "{name}: {}", text(&o.stderr));
        (std::fs::read(png).unwrap(), text(&o.stdout))
    };
    for method in ["direct", "texture-bilinear", "mesh"] {
        let (shot, status) = view(method, &format!("press {method}\n"));
        assert!(status.starts_with(method), "{status}");
        let png = dir.join(format!("render-{method}.png"));
        let mut args = vec![
            "render",
            sol,
            "--method",
            method,
            "-o",
            png.to_str().unwrap(),
            "--quiet",
        ];
        args.extend(size);
        let o = run(&args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        assert!(
            shot == std::fs::read(&png).unwrap(),
            "{method}: the viewer's frame is not render's"
        );
    }
    // Flying forward and turning changes the frame; reset brings back the scene's camera.
    let (still, _) = view("still", "wait 0.5\n");
    let (moved, _) = view("moved", "hold forward,turn-left 0.5\n");
    let (back, _) = view("back", "hold forward,turn-left 0.5\npress reset\n");
    assert!(moved != still && back == still);

    let bad = dir.join("bad.txt");
    std::fs::write(&bad, "wait 1\nhold sideways 2\n").unwrap();
    let png = dir.join("bad.png");
    let o = run(&[
        "view",
        sol,
        "--script",
        bad.to_str().unwrap(),
        "--screenshot",
        png.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("bad.txt:2"), "{}", text(&o.stderr));
    // A script that is not text, or missing, is bad input too (it exited 1).
    let binary = dir.join("binary.txt");
    std::fs::write(&binary, b"wait 1\n\xff\xfe\n").unwrap();
    for script in [&binary, &dir.join("missing.txt")] {
        let o = run(&[
            "view",
            sol,
            "--script",
            script.to_str().unwrap(),
            "--screenshot",
            png.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
        assert!(!png.exists());
    }
}

/// A scripted view's frame is held to the memory limit as `render`'s is, before any work (a
/// 16384 x 16384 frame was drawn under `--memory-limit 100M`: 3.96 GB).
#[test]
fn a_view_frame_over_the_memory_limit_is_refused() {
    let dir = scratch();
    let script = dir.join("limit.txt");
    std::fs::write(&script, "wait 0.1\n").unwrap();
    let png = dir.join("limit.png");
    let scene = Path::new(crate::REPO).join("scenes/two-spots.toml");
    let o = run(&[
        "--memory-limit",
        "100M",
        "view",
        scene.to_str().unwrap(),
        "--script",
        script.to_str().unwrap(),
        "--screenshot",
        png.to_str().unwrap(),
        "--width",
        "16384",
        "--height",
        "16384",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("over the memory limit"),
        "{}",
        text(&o.stderr)
    );
    assert!(!png.exists());
}

/// Without a display the window cannot open: `view` says so before any work (no solve first),
/// in words, not Rust's debug formatting, and exits 1.
#[test]
fn view_without_a_display_refuses_before_solving() {
    let scene = Path::new(crate::REPO).join("scenes/cornell-box.toml");
    for display in [None, Some("")] {
        let mut cmd = crate::bin();
        cmd.args(["view", scene.to_str().unwrap()])
            .env_remove("WAYLAND_DISPLAY");
        match display {
            None => cmd.env_remove("DISPLAY"),
            Some(d) => cmd.env("DISPLAY", d),
        };
        let o = cmd.output().unwrap();
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains("cannot open a window (DISPLAY is"), "{err}");
        assert!(err.contains("--script"), "{err}");
        assert!(!err.contains("Some(") && !err.contains("None"), "{err}");
        // Refused before the solve: none of the solve's notes (the Cornell box's refinement
        // note) was printed.
        assert!(!err.contains("refinement stopped"), "{err}");
    }
}
