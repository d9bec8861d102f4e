//! The library integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

/// Scenes the tests solve coarser than shipped, with the depth they take: the gallery at its
/// own settings is half a minute of the test command's ten-minute budget on 2 cores (22 s at
/// depth 5 against 50 s at its own 6), and what its tests check (golden images, finite renders,
/// mesh coverage, compact RRPs, a warning-free solve, the lightmap round trip) does not depend on
/// the last level. `pixelflow-sim results` solves it at its own settings.
pub const COARSER: [(&str, u32); 1] = [("gallery", 5)];

/// The prepared solve of shipped scene `name` (a stem under `scenes/`) with the default options
/// (at the depth [`COARSER`] gives, if it names the scene), one per scene for the whole test
/// binary: golden images, renders, meshes and reconstructions of the shipped scenes share it
/// instead of each solving again. A second test asking for a scene being solved waits for it.
pub fn shipped(name: &str) -> &'static app::prepare::Prepared {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};
    type Cell = Arc<OnceLock<&'static app::prepare::Prepared>>;
    static CELLS: OnceLock<Mutex<HashMap<String, Cell>>> = OnceLock::new();
    let cell = {
        let mut map = CELLS
            .get_or_init(Default::default)
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        map.entry(name.to_string()).or_default().clone()
    };
    cell.get_or_init(|| {
        let path = std::path::Path::new(REPO)
            .join("scenes")
            .join(format!("{name}.toml"));
        let mut input = app::context::Input::load(&path).expect("shipped scene loads");
        if let Some(&(_, depth)) = COARSER.iter().find(|(n, _)| *n == name) {
            input.scene.radiosity.max_depth = depth;
        }
        let texture = app::context::TextureOptions::default();
        let policy = texture.policy(&input.scene).expect("texture policy");
        let placement = texture.placement(&input.scene).expect("texel placement");
        let p = app::prepare::prepare(&app::context::Context::default(), input, policy, placement)
            .expect("shipped scene prepares");
        Box::leak(Box::new(p))
    })
}

/// `scene` solved and prepared with the default options, as `render` prepares a scene it
/// loaded from `path`.
pub fn prepare_scene(path: &std::path::Path, scene: scene::Scene) -> app::prepare::Prepared {
    let input = app::context::Input {
        path: path.to_path_buf(),
        scene,
        solution_file: None,
        estimator: Default::default(),
        sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
        input_limit: base::output::MAX_INPUT_BYTES,
    };
    let texture = app::context::TextureOptions::default();
    let policy = texture.policy(&input.scene).expect("texture policy");
    let placement = texture.placement(&input.scene).expect("texel placement");
    app::prepare::prepare(&app::context::Context::default(), input, policy, placement)
        .expect("scene prepares")
}

mod camera_scale;
mod closed_form;
mod contact_lines;
mod export;
mod frame_context;
mod golden;
mod mesh;
mod metric;
mod mutations;
mod plan;
mod reconstruction_scenes;
mod render;
mod truth_camera;
mod solution_rrps;
mod smooth_surfaces;
mod t_junctions;
mod texture_seams;
mod triangles;
mod two_sided;
