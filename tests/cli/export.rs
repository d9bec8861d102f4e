//! `pixelflow-sim export` from the command line, and solution files that travel with their
//! scene: a `.pfsol` names its scene relative to itself, and `--scene` points a solution at a
//! scene that moved on its own.

use std::path::{Path, PathBuf};
use std::process::Output;

use crate::bin;

fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("cli_export")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A solution and its scene copied together to another folder still render; once the scene is
/// moved on its own, the solution names a missing file until `--scene` says where it went.
#[test]
fn a_solution_copied_with_its_scene_finds_it() {
    let root = scratch("portable");
    let a = root.join("a");
    std::fs::create_dir_all(a.join("scenes")).unwrap();
    std::fs::create_dir_all(a.join("out")).unwrap();
    let scene = a.join("scenes/two-spots.toml");
    std::fs::copy(Path::new(crate::REPO).join("scenes/two-spots.toml"), &scene).unwrap();
    let sol = a.join("out/s.pfsol");
    let o = run(&[
        "solve",
        scene.to_str().unwrap(),
        "-o",
        sol.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));

    let b = root.join("b");
    std::fs::rename(&a, &b).unwrap();
    let sol = b.join("out/s.pfsol");
    let png = root.join("moved.png");
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render",
            sol.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "32",
        ];
        args.extend(["-o", png.to_str().unwrap(), "--quiet"]);
        args.extend(extra);
        run(&args)
    };
    let o = render(&[]);
    assert!(o.status.success(), "copied together: {}", text(&o.stderr));

    let elsewhere = root.join("elsewhere.toml");
    std::fs::rename(b.join("scenes/two-spots.toml"), &elsewhere).unwrap();
    let o = render(&[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("two-spots.toml"),
        "{}",
        text(&o.stderr)
    );
    let o = render(&["--scene", elsewhere.to_str().unwrap()]);
    assert!(o.status.success(), "--scene: {}", text(&o.stderr));

    // --scene names a solution's scene: with a scene file as input it is a mistake.
    let o = run(&[
        "render",
        elsewhere.to_str().unwrap(),
        "--scene",
        "x.toml",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(text(&o.stderr).contains("--scene"), "{}", text(&o.stderr));
}

#[test]
fn export_writes_what_its_name_says_and_refuses_bad_options() {
    let dir = scratch("options");
    let glb = dir.join("two-spots.glb");
    let o = run(&[
        "export",
        "scenes/two-spots.toml",
        "-o",
        glb.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let bytes = std::fs::read(&glb).unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    assert!(
        text(&o.stdout).contains("atlas: 1 page(s)"),
        "{}",
        text(&o.stdout)
    );
    assert!(dir.join("two-spots.lightmap-0.exr").is_file());
    // The same bytes for any thread count.
    let again = scratch("options-one-thread").join("two-spots.glb");
    let o = run(&[
        "export",
        "scenes/two-spots.toml",
        "-o",
        again.to_str().unwrap(),
        "--threads",
        "1",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        std::fs::read(&again).unwrap() == bytes,
        "another thread count, other bytes"
    );

    let gltf = dir.join("two-spots.gltf");
    let o = run(&[
        "export",
        "scenes/two-spots.toml",
        "-o",
        gltf.to_str().unwrap(),
        "--mesh",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&gltf).unwrap()).unwrap();
    assert_eq!(json["asset"]["version"], "2.0");
    assert_eq!(json["extensionsUsed"][0], "KHR_materials_unlit");
    assert!(dir.join("two-spots.bin").is_file());

    for (args, key) in [
        (vec!["-o", "x.png"], "-o"),
        (vec!["-o", "x.glb", "--page-size", "100"], "--page-size"),
        (
            vec!["-o", "x.glb", "--texel-placement", "corner"],
            "--texel-placement",
        ),
    ] {
        let mut all = vec!["export", "scenes/two-spots.toml"];
        all.extend(args);
        let o = run(&all);
        assert_eq!(o.status.code(), Some(2), "{all:?}: {}", text(&o.stderr));
        assert!(
            text(&o.stderr).contains(key),
            "{all:?}: {}",
            text(&o.stderr)
        );
    }
}

/// The files an export writes beside its glTF (the `.bin` buffer, the atlas pages) are checked
/// against its inputs before any work: a solution named like the buffer, or a scene file named
/// like a page, is refused with exit 2 and left as it was (the export used to replace it).
#[test]
fn files_beside_the_export_never_replace_an_input() {
    let dir = scratch("beside");
    let scene = dir.join("two-spots.toml");
    std::fs::copy(Path::new(crate::REPO).join("scenes/two-spots.toml"), &scene).unwrap();
    let sol = dir.join("s.pfsol");
    let o = run(&[
        "solve",
        scene.to_str().unwrap(),
        "-o",
        sol.to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o.stderr));
    // The solution copied to the name of the buffer beside `s.gltf`.
    let bin = dir.join("s.bin");
    std::fs::copy(&sol, &bin).unwrap();
    let before = std::fs::read(&bin).unwrap();
    let gltf = dir.join("s.gltf");
    let o = run(&[
        "export",
        bin.to_str().unwrap(),
        "-o",
        gltf.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("refusing to overwrite an input"),
        "{}",
        text(&o.stderr)
    );
    assert_eq!(std::fs::read(&bin).unwrap(), before);
    assert!(!gltf.exists());
    // The scene file itself named like a page.
    let page = dir.join("p.lightmap-0.exr");
    std::fs::copy(&scene, &page).unwrap();
    let o = run(&[
        "export",
        sol.to_str().unwrap(),
        "--scene",
        page.to_str().unwrap(),
        "-o",
        dir.join("p.glb").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    assert!(
        text(&o.stderr).contains("refusing to overwrite an input"),
        "{}",
        text(&o.stderr)
    );
    assert_eq!(
        std::fs::read(&page).unwrap(),
        std::fs::read(&scene).unwrap()
    );
}
