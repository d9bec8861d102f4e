//! A modelling tool's OBJ on the command line: `check`, `render` and `solve` of a bare model,
//! `--strict`, `-D` and `--camera`, and the warnings and luminance summary that keep a first
//! render from coming out black or washed out in silence.

use std::path::PathBuf;
use std::process::Output;

fn run(args: &[&str]) -> Output {
    crate::bin().args(args).output().expect("the binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("pfs-cli-models-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A small, quick render of the shipped studio model.
const SMALL: [&str; 6] = [
    "-D",
    "image.width=80",
    "-D",
    "image.height=60",
    "-D",
    "radiosity.max_depth=3",
];

/// A closed box room with outward normals (a modelling tool's cube) and an emitting panel
/// facing down inside it, as an OBJ with its MTL; `kd` is the walls' `Kd`.
fn outward_box(dir: &std::path::Path, kd: &str) -> PathBuf {
    let obj = "mtllib box.mtl\n\
        v 0 0 0\nv 2 0 0\nv 2 0 2\nv 0 0 2\nv 0 2 0\nv 2 2 0\nv 2 2 2\nv 0 2 2\n\
        v 0.8 1.9 0.8\nv 1.2 1.9 0.8\nv 1.2 1.9 1.2\nv 0.8 1.9 1.2\n\
        o Cube\nusemtl wall\n\
        f 1 2 3 4\nf 8 7 6 5\nf 5 6 2 1\nf 6 7 3 2\nf 3 7 8 4\nf 4 8 5 1\n\
        o Lamp\nusemtl lamp\nf 9 10 11 12\n";
    std::fs::write(dir.join("box.obj"), obj).unwrap();
    std::fs::write(
        dir.join("box.mtl"),
        format!("newmtl wall\nKd {kd}\n\nnewmtl lamp\nKd 0.5 0.5 0.5\nKe 4 4 4\n"),
    )
    .unwrap();
    dir.join("box.obj")
}

#[test]
fn check_a_bare_model_says_what_it_chose() {
    let out = run(&["check", "scenes/models/studio.obj"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    assert!(
        e.contains("warning: scenes/models/studio.obj: no camera in a model"),
        "{e}"
    );
    assert!(e.contains("note: ") && e.contains("ear clipping"), "{e}");
    assert!(!e.contains("back side") && !e.contains("enclosed"), "{e}");
    assert!(text(&out.stdout).contains("polygons"));
}

#[test]
fn render_a_bare_model_exposes_it_and_summarizes_its_luminance() {
    let dir = scratch("render");
    let png = dir.join("studio.png");
    let mut args = vec![
        "render",
        "scenes/models/studio.obj",
        "-o",
        png.to_str().unwrap(),
    ];
    args.extend(SMALL);
    let out = run(&args);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    let line = e
        .lines()
        .find(|l| l.contains("luminance min"))
        .unwrap_or_else(|| panic!("{e}"));
    // Auto exposure: the log-average luminance at middle grey leaves little black or clipped.
    assert!(line.contains("0.0 % of the model black"), "{line}");
    assert!(
        !e.contains("washed out") && !e.contains("is black at"),
        "{e}"
    );
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    // A fixed exposure far too high is called washed out.
    let mut args = vec![
        "render",
        "scenes/models/studio.obj",
        "-o",
        png.to_str().unwrap(),
        "--exposure",
        "8",
    ];
    args.extend(SMALL);
    let e = text(&run(&args).stderr);
    assert!(
        e.contains("washed out") && e.contains("auto-exposure"),
        "{e}"
    );
}

#[test]
fn an_outward_room_is_warned_about_before_it_renders_black() {
    let dir = scratch("outward");
    let obj = outward_box(&dir, "0.7 0.7 0.7");
    let png = dir.join("box.png");
    let out = run(&[
        "render",
        obj.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "-D",
        "image.width=64",
        "-D",
        "image.height=48",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    assert!(e.contains("enclosed by the back sides of faces"), "{e}");
    assert!(e.contains("lands on its back side"), "{e}");
}

#[test]
fn kd_of_one_is_clamped_or_refused_under_strict() {
    let dir = scratch("kd");
    let obj = outward_box(&dir, "1 1 1");
    let mtl = dir.join("box.mtl");
    let out = run(&["check", obj.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    assert!(
        e.contains(&format!("{}:2: material `wall` Kd", mtl.display()))
            && e.contains("clamped to [0.95, 0.95, 0.95]"),
        "{e}"
    );
    let out = run(&["check", obj.to_str().unwrap(), "--strict"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains(&format!("{}:2:", mtl.display())));
}

#[test]
fn overrides_set_the_camera_and_bad_ones_exit_2_naming_them() {
    let dir = scratch("overrides");
    let png = dir.join("o.png");
    // Outside the studio's west wall (x = 0), looking in: the back of that wall fills the view.
    let mut args = vec![
        "render",
        "scenes/models/studio.obj",
        "-o",
        png.to_str().unwrap(),
        "--camera",
        "-1,1.4,2.5,2,1.4,2.5",
    ];
    args.extend(SMALL);
    let out = run(&args);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    assert!(!e.contains("no camera in a model"), "{e}");
    assert!(
        e.contains("% of the image shows the back side of faces"),
        "{e}"
    );
    for bad in [
        ["-D", "image.width=0"],
        ["-D", "camera.zoom=2"],
        ["-D", "nokey"],
    ] {
        let out = run(&["check", "scenes/models/studio.obj", bad[0], bad[1]]);
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {}", text(&out.stderr));
        assert!(text(&out.stderr).contains("-D"), "{}", text(&out.stderr));
    }
}

#[test]
fn solve_of_a_model_prints_its_warnings_and_renders_from_the_file() {
    let dir = scratch("solve");
    let sol = dir.join("studio.pfsol");
    let out = run(&[
        "solve",
        "scenes/models/studio.obj",
        "-o",
        sol.to_str().unwrap(),
        "-D",
        "radiosity.max_depth=3",
        "--quiet",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("no camera in a model"));
    // The solution names the OBJ; rendered without the same override its scene differs (the
    // radiosity settings are hashed), which is refused rather than drawn from the wrong scene.
    let png = dir.join("s.png");
    let out = run(&[
        "render",
        sol.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "-D",
        "radiosity.max_depth=3",
        "-D",
        "image.width=64",
        "-D",
        "image.height=48",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let out = run(&["render", sol.to_str().unwrap(), "-o", png.to_str().unwrap()]);
    assert_ne!(out.status.code(), Some(0), "{}", text(&out.stderr));
}

#[test]
fn a_solution_file_named_for_another_format_is_refused() {
    let dir = scratch("solve-name");
    let png = dir.join("solution.png");
    let out = run(&[
        "solve",
        "scenes/two-spots.toml",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("must end in .pfsol"));
    assert!(!png.exists());
}

/// What broke: a missing model was reported at a line of the scene written for it
/// (`nothere.obj:15: obj[0].file`), and a model in another format by the TOML parser alone.
#[test]
fn a_missing_model_and_a_model_of_another_format_are_named_as_such() {
    let dir = scratch("formats");
    let missing = dir.join("nothere.obj");
    let out = run(&["render", missing.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(
        e.contains(&format!("{}: cannot read OBJ file", missing.display())),
        "{e}"
    );
    let fbx = dir.join("model.fbx");
    std::fs::write(&fbx, "Kaydara FBX Binary\0").unwrap();
    let out = run(&["check", fbx.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(
        e.contains("is not a scene file") && e.contains("export other formats as OBJ"),
        "{e}"
    );
}

/// One convention for JSON: `--json` prints one document on standard output, `--json FILE`
/// writes it there (never over an input).
#[test]
fn json_goes_to_standard_output_or_to_the_file_named() {
    let dir = scratch("json");
    let to_stdout = run(&["stats", "scenes/two-spots.toml", "--json"]);
    assert_eq!(
        to_stdout.status.code(),
        Some(0),
        "{}",
        text(&to_stdout.stderr)
    );
    let a: serde_json::Value = serde_json::from_slice(&to_stdout.stdout).unwrap();
    let file = dir.join("stats.json");
    let to_file = run(&[
        "stats",
        "scenes/two-spots.toml",
        "--json",
        file.to_str().unwrap(),
    ]);
    assert_eq!(to_file.status.code(), Some(0), "{}", text(&to_file.stderr));
    assert!(to_file.stdout.is_empty());
    let b: serde_json::Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    assert_eq!(a, b);
    // truth: the per-polygon report on standard output, in place of its table.
    let t = run(&[
        "truth",
        "scenes/two-spots.toml",
        "--json",
        "--polygon-samples",
        "64",
    ]);
    assert_eq!(t.status.code(), Some(0), "{}", text(&t.stderr));
    let t: serde_json::Value = serde_json::from_slice(&t.stdout).unwrap();
    assert!(
        t["polygons"].as_array().is_some_and(|p| !p.is_empty()),
        "{t}"
    );
    // Over the input: refused before any work.
    let scene = dir.join("s.toml");
    std::fs::copy(format!("{}/scenes/two-spots.toml", crate::REPO), &scene).unwrap();
    let over = run(&[
        "stats",
        scene.to_str().unwrap(),
        "--json",
        scene.to_str().unwrap(),
    ]);
    assert_eq!(over.status.code(), Some(2), "{}", text(&over.stderr));
    assert!(std::fs::read_to_string(&scene)
        .unwrap()
        .contains("[camera]"));
}

/// Every file a command writes is named for what it holds: statistics and JSON `.json`, CSV
/// `.csv`, a difference image `.png` or `.exr`; another name is refused before any work.
#[test]
fn data_files_named_for_another_format_are_refused() {
    let dir = scratch("data-names");
    let png = dir.join("x.png");
    let wrong = dir.join("stats.png");
    let cases: [Vec<&str>; 3] = [
        vec![
            "render",
            "scenes/two-spots.toml",
            "-o",
            png.to_str().unwrap(),
            "--stats",
            wrong.to_str().unwrap(),
        ],
        vec![
            "stats",
            "scenes/two-spots.toml",
            "--json",
            wrong.to_str().unwrap(),
        ],
        vec![
            "compare",
            "scenes/cornell-box/CornellBox-Original.mtl",
            "x.png",
            "--tolerance",
            "default",
            "--diff",
            "d.txt",
        ],
    ];
    for args in cases {
        let out = run(&args);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&out.stderr)
        );
        assert!(
            text(&out.stderr).contains("must end in"),
            "{args:?}: {}",
            text(&out.stderr)
        );
    }
    assert!(!wrong.exists() && !png.exists());
}

/// The shipped glTF room (`scenes/gltf/room.glb`, written by `tools/make-room-glb.py`): `check`
/// finds its panel's light and its camera, and chooses neither; `render` lights the room by the
/// panel (nothing of the model black).
#[test]
fn a_gltf_room_checks_and_renders_lit_by_its_own_panel() {
    let out = run(&["check", "scenes/gltf/room.glb"]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let (o, e) = (text(&out.stdout), text(&out.stderr));
    // The panel's two triangles merged into a quad, and its twin (doubleSided, emitting).
    assert!(o.contains("emitters        2 polygons"), "{o}");
    assert!(o.contains("spot lights     0"), "{o}");
    assert!(o.contains("image           800 x 600"), "{o}");
    assert!(
        !e.contains("no camera in a model") && !e.contains("default spot"),
        "{e}"
    );
    let dir = scratch("gltf-room");
    let png = dir.join("room.png");
    let mut args = vec![
        "render",
        "scenes/gltf/room.glb",
        "-o",
        png.to_str().unwrap(),
    ];
    args.extend(SMALL);
    let out = run(&args);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let e = text(&out.stderr);
    let line = e
        .lines()
        .find(|l| l.contains("luminance min"))
        .unwrap_or_else(|| panic!("{e}"));
    assert!(line.contains("0.0 % of the model black"), "{line}");
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
}

/// A damaged glTF exits 2 with the file and the glTF key: a GLB cut short, a `.gltf` whose
/// buffer file is missing.
#[test]
fn a_damaged_gltf_exits_2_naming_the_file_and_key() {
    let dir = scratch("gltf-damaged");
    let glb = std::fs::read(format!("{}/scenes/gltf/room.glb", crate::REPO)).unwrap();
    let cut = dir.join("cut.glb");
    std::fs::write(&cut, &glb[..glb.len() / 2]).unwrap();
    let out = run(&["check", cut.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(
        e.contains(&format!("{}: is a truncated GLB", cut.display())),
        "{e}"
    );
    let gltf = dir.join("lost.gltf");
    std::fs::write(
        &gltf,
        r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "buffers": [{"byteLength": 36, "uri": "lost.bin"}]}"#,
    )
    .unwrap();
    let out = run(&["render", gltf.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let e = text(&out.stderr);
    assert!(
        e.contains(&format!(
            "{}: buffers[0].uri: cannot read buffer file {}",
            gltf.display(),
            dir.join("lost.bin").display()
        )),
        "{e}"
    );
}

/// A light panel snapped onto a ceiling in Blender (`scenes/gltf/ceiling-lamp.glb`, written by
/// Blender 5.0.1 through `tools/make-ceiling-lamp-glb.py`): the panel lies in the ceiling's very
/// plane, facing down with it, its material double-sided. What broke: the ceiling and the panel
/// both took the light of the overlap, and every method drew the ceiling there (the depth tie
/// went to the ceiling, listed first): the brightest pixel of the view up at the panel read
/// 0.19. Now the panel lies on top (an emitter over a surface), the piece of ceiling under it
/// is buried, the account balances, and every method draws the panel at least at its exitance
/// (5: its emission strength; it also reflects).
#[test]
fn a_lamp_snapped_onto_a_ceiling_in_blender_shows_and_lights_the_room_once() {
    use app::context::{Context, TextureOptions};
    let path = PathBuf::from(crate::REPO).join("scenes/gltf/ceiling-lamp.glb");
    let p = app::prepare::prepare_path(&Context::default(), &path, &TextureOptions::default())
        .expect("prepares");
    let buried = p
        .scene
        .polygons
        .iter()
        .filter(|q| q.sealed == scene::seal::Sealed::Buried)
        .count();
    assert_eq!(buried, 1, "the piece of ceiling under the panel");
    let e = p.solution.stats.energy;
    assert!(e.error().abs() <= radiosity::ENERGY_ERROR_WARN, "{e:?}");
    let opts = engine::frame::FrameOptions::new(80, 45);
    for name in base::method::Method::NAMES {
        let m = base::method::Method::parse(name).unwrap();
        let f = app::frames::render_frame(&p, m, &p.scene.camera, &opts).expect("renders");
        let top = f.pixels.iter().map(|c| c.min_element()).fold(0.0, f32::max);
        assert!(top >= 5.0, "{name}: the brightest pixel reads {top}");
    }
}

/// The same Blender scene with the room as Blender's cube has it, facing outward
/// (`scenes/gltf/ceiling-lamp-outward.glb`, `tools/make-ceiling-lamp-glb.py --as-modelled`):
/// Blender shows its inside lit, its material is double-sided in the file. What broke: the
/// loader took the winding as written, warned that the camera was enclosed by back faces and
/// every method drew black. The room is now turned to face the lamp it encloses (a note says
/// so): no such warning, and every method's image within 1 % of the file whose normals Blender
/// recalculated inside (two solves of one room, which differ by their sampling only).
#[test]
fn a_blender_room_facing_outward_is_turned_to_face_its_lamp() {
    use app::context::{Context, TextureOptions};
    let load = |name: &str| {
        let path = PathBuf::from(crate::REPO).join("scenes/gltf").join(name);
        app::prepare::prepare_path(&Context::default(), &path, &TextureOptions::default())
            .expect("prepares")
    };
    let (inside, outward) = (load("ceiling-lamp.glb"), load("ceiling-lamp-outward.glb"));
    assert!(
        outward
            .scene
            .notes
            .iter()
            .any(|n| n.contains("turned to face the lights")),
        "{:?}",
        outward.scene.notes
    );
    assert!(
        outward
            .scene
            .warnings
            .iter()
            .all(|w| !w.contains("enclosed")),
        "{:?}",
        outward.scene.warnings
    );
    let opts = engine::frame::FrameOptions::new(80, 45);
    for name in base::method::Method::NAMES {
        let m = base::method::Method::parse(name).unwrap();
        let mean = |p: &app::prepare::Prepared| {
            let f = app::frames::render_frame(p, m, &inside.scene.camera, &opts).expect("renders");
            f.pixels.iter().map(|c| f64::from(c.x)).sum::<f64>() / f.pixels.len() as f64
        };
        let (a, b) = (mean(&inside), mean(&outward));
        assert!(
            a > 0.1 && (b / a - 1.0).abs() <= 0.01,
            "{name}: {b} against {a}"
        );
    }
}
