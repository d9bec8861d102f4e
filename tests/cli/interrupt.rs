//! Interrupted runs leave nothing behind: the registry of live temporaries that the binary's
//! SIGINT/SIGTERM handler removes, tested in-process, and a walkthrough killed with SIGTERM
//! while it writes frames.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use base::output::Outputs;

fn fresh_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pfs-interrupt-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Every file in `dir` (names only, sorted).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn the_handlers_cleanup_removes_every_staged_temporary_and_no_target() {
    let dir = fresh_dir("staged");
    std::fs::write(dir.join("old.png"), b"old").unwrap();
    let outputs = Outputs::new();
    let mut batch = outputs.batch();
    batch.stage(&dir.join("old.png"), b"new png").unwrap();
    batch.stage(&dir.join("new.exr"), b"new exr").unwrap();
    assert_eq!(names(&dir).len(), 3, "{:?}", names(&dir));
    // What the signal handler does: both temporaries go, the old target stays as it was.
    assert_eq!(outputs.remove_temporaries(), 2);
    assert_eq!(names(&dir), ["old.png"]);
    assert_eq!(std::fs::read(dir.join("old.png")).unwrap(), b"old");
    // A commit after the cleanup fails (its temporaries are gone) and replaces nothing.
    assert!(batch.commit().is_err());
    assert_eq!(names(&dir), ["old.png"]);
    assert_eq!(outputs.remove_temporaries(), 0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[cfg(unix)]
#[test]
fn a_walkthrough_killed_by_sigterm_exits_130_and_leaves_no_temporary() {
    let dir = fresh_dir("walk");
    let scene = Path::new(crate::REPO).join("scenes/two-spots.toml");
    let text = std::fs::read_to_string(scene).unwrap()
        + "\n[camera_path]\nframes = 100000\nkeyframes = [\n\
           { eye = [0.3, 0.5, 2.0], look_at = [0.3, 0.5, 0.0], up = [0.0, 1.0, 0.0] },\n\
           { eye = [0.7, 0.5, 2.0], look_at = [0.7, 0.5, 0.0], up = [0.0, 1.0, 0.0] },\n]\n";
    let walk = dir.join("walk.toml");
    std::fs::write(&walk, text).unwrap();
    let frames = dir.join("frames");
    let mut child = crate::bin()
        .args(["render", walk.to_str().unwrap(), "--walkthrough", "--quiet"])
        .args(["--width", "256", "--height", "256", "-o"])
        .arg(frames.join("f.png"))
        .spawn()
        .unwrap();
    // Wait for frames to be written, then interrupt in the middle of the stream of writes.
    let start = Instant::now();
    while names_or_empty(&frames).len() < 20 && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let killed = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    let left = names_or_empty(&frames);
    assert!(left.len() >= 20, "{} frames written", left.len());
    let hidden: Vec<_> = left.iter().filter(|n| n.starts_with('.')).collect();
    assert!(hidden.is_empty(), "temporaries left: {hidden:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn names_or_empty(dir: &Path) -> Vec<String> {
    if dir.is_dir() {
        names(dir)
    } else {
        Vec::new()
    }
}
