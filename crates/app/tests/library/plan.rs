//! Every option is checked before any work: a bad method, antialiasing count, texture size,
//! budget, image size, renderer count or region is refused before the solve starts. The proof is
//! the observer: the solver reports its stage's progress from the moment it starts, so a job that
//! fails with an observer that saw nothing never solved. The scene is gallery-fine, whose solve
//! takes tens of seconds: a check that came after the solve would make these tests slow too, but
//! the observer is what they assert.

use app::context::Context;
use std::path::PathBuf;
use std::sync::Mutex;

use app::commands::bench::{run_bench, BenchRequest};
use app::commands::render::{run_render, RenderRequest};
use app::commands::stats::{run_stats, StatsRequest};
use app::context::TextureOptions;
use base::progress::Observer;
use base::Error;
use engine::frame::FrameOptions;

/// Records every stage that reported progress.
#[derive(Default)]
struct Recorder(Mutex<Vec<String>>);

impl Observer for Recorder {
    fn progress(&self, stage: &str, _fraction: f64) {
        self.0.lock().unwrap().push(stage.to_string());
    }
}

impl Recorder {
    fn stages(&self) -> Vec<String> {
        self.0.lock().unwrap().clone()
    }
}

fn gallery_fine() -> PathBuf {
    PathBuf::from(crate::REPO).join("scenes/gallery-fine.toml")
}

fn request() -> RenderRequest {
    RenderRequest {
        input: gallery_fine(),
        output: Some(std::env::temp_dir().join("pfs-plan-never-written.png")),
        renderers: 1,
        region: 128,
        ..RenderRequest::default()
    }
}

/// The option an error names, for bad options; the request for limits.
fn option_of(e: &Error) -> String {
    match e {
        Error::InvalidOption { option, .. } => option.clone(),
        Error::ResourceLimit { what, .. } => what.clone(),
        other => panic!("expected an option or limit error, got {other:?}"),
    }
}

#[test]
fn bad_render_options_are_refused_before_the_solve() {
    type Edit = fn(&mut RenderRequest);
    let cases: [(&str, Edit); 14] = [
        ("method", |r| r.method = Some("texturebilinear".into())),
        ("aa", |r| r.aa = Some(3)),
        ("texture-size", |r| r.texture.size = Some(3)),
        ("texture-size", |r| r.texture.size = Some(8192)),
        ("texture-budget", |r| r.texture.budget = Some(1)),
        ("texture-size", |r| {
            r.texture.size = Some(8);
            r.texture.budget = Some(1 << 20);
        }),
        ("bicubic", |r| {
            r.method = Some("texture-bicubic".into());
            r.texture.bicubic = Some((2.0, 0.0));
        }),
        ("width", |r| r.width = Some(0)),
        ("height", |r| r.height = Some(1 << 20)),
        ("renderers", |r| r.renderers = 0),
        ("renderers", |r| r.renderers = 1000),
        ("region", |r| r.region = 12),
        ("exr", |r| {
            r.walkthrough = true;
            r.exr = Some(PathBuf::from("x.exr"));
        }),
        // gallery-fine has a camera path; a walkthrough of a scene without one is refused too
        // (tested on the CLI with two-spots).
        ("method", |r| r.method = Some(String::new())),
    ];
    for (option, edit) in cases {
        let mut req = request();
        edit(&mut req);
        let rec = Recorder::default();
        let e = run_render(&Context::new(&rec), &req, &mut |_| {}).unwrap_err();
        assert_eq!(option_of(&e), option, "{e}");
        assert_eq!(e.exit_code(), 2, "{e}");
        assert!(rec.stages().is_empty(), "{option}: the solve started");
    }
}

#[test]
fn bad_bench_and_stats_options_are_refused_before_the_solve() {
    let bench = |edit: fn(&mut BenchRequest)| {
        let mut req = BenchRequest {
            input: gallery_fine(),
            scene: None,
            methods: vec!["direct".into()],
            texture: TextureOptions::default(),
            sizes: vec![64],
            frames: 1,
            aa: 1,
            renderers: 1,
            region: 128,
            load: Default::default(),
        };
        edit(&mut req);
        let rec = Recorder::default();
        let e = run_bench(&Context::new(&rec), &req).unwrap_err();
        assert!(rec.stages().is_empty(), "{e}: the solve started");
        option_of(&e)
    };
    assert_eq!(bench(|r| r.methods.push("phong".into())), "method");
    assert_eq!(bench(|r| r.sizes = vec![64, 0]), "sizes");
    assert_eq!(bench(|r| r.sizes = vec![1 << 20]), "sizes");
    assert_eq!(bench(|r| r.aa = 2), "aa");
    assert_eq!(bench(|r| r.renderers = 0), "renderers");
    assert_eq!(bench(|r| r.region = 12), "region");
    assert_eq!(bench(|r| r.texture.size = Some(5)), "texture-size");

    let stats = |edit: fn(&mut StatsRequest)| {
        let mut req = StatsRequest {
            input: gallery_fine(),
            scene: None,
            frames: 0,
            frame: FrameOptions::new(64, 64),
            texture: TextureOptions::default(),
            load: Default::default(),
        };
        edit(&mut req);
        let rec = Recorder::default();
        let e = run_stats(&Context::new(&rec), &req).unwrap_err();
        assert!(rec.stages().is_empty(), "{e}: the solve started");
        option_of(&e)
    };
    assert_eq!(stats(|r| r.frame.width = 0), "width");
    assert_eq!(stats(|r| r.texture.budget = Some(3)), "texture-budget");
    assert_eq!(stats(|r| r.texture.bicubic = Some((0.0, -1.0))), "bicubic");
}

/// The recorder does see a solve that starts: without this the tests above could pass with an
/// observer that is never called.
#[test]
fn the_recorder_sees_a_solve() {
    let req = RenderRequest {
        input: PathBuf::from(crate::REPO).join("scenes/two-spots.toml"),
        output: Some(std::env::temp_dir().join(format!("pfs-plan-{}.png", std::process::id()))),
        width: Some(16),
        height: Some(16),
        renderers: 1,
        region: 128,
        ..RenderRequest::default()
    };
    let rec = Recorder::default();
    run_render(&Context::new(&rec), &req, &mut |_| {}).unwrap();
    assert!(rec.stages().iter().any(|s| s == "solve"));
    let _ = std::fs::remove_file(req.output.unwrap());
}
