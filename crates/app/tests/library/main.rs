//! The library integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

/// The prepared solve of shipped scene `name` (a stem under `scenes/`) with the default options,
/// one per scene for the whole test binary: golden images, renders, meshes and reconstructions
/// of the shipped scenes share it instead of each solving again. A second test asking for a
/// scene being solved waits for it.
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
        let p = app::prepare::prepare_path(
            &app::context::Context::default(),
            &path,
            &app::context::TextureOptions::default(),
        )
        .expect("shipped scene prepares");
        Box::leak(Box::new(p))
    })
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
