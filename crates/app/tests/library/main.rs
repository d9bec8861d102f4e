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

/// A generated building of `rooms_x` x `rooms_z` rooms (shell cut `cut` x `cut`), loaded
/// through the scene loader from memory: closed rooms joined by doorways, the case sampled
/// visibility is for.
pub fn building(rooms_x: u32, rooms_z: u32, cut: u32) -> scene::Scene {
    use fixtures::generate::{generate_building, BuildingOptions, BuildingPaths};
    use std::path::Path;
    let o = BuildingOptions {
        cut,
        ..BuildingOptions::new(rooms_x, rooms_z)
    };
    let paths = BuildingPaths::for_output(Path::new("/virtual/b.toml")).expect("paths");
    let b = generate_building(&o, &paths).expect("building");
    let read = |p: &Path| -> std::io::Result<String> {
        if p == paths.obj {
            Ok(b.obj.clone())
        } else if p == paths.mtl {
            Ok(b.mtl.clone())
        } else {
            Err(std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no such file",
            ))
        }
    };
    scene::parse_scene_with(&b.toml, &paths.scene, &read).expect("scene")
}

mod camera_scale;
mod closed_form;
mod contact_lines;
mod export;
mod frame_context;
mod golden;
mod mesh;
mod metric;
mod models;
mod mutations;
mod physics;
mod plan;
mod reconstruction_scenes;
mod render;
mod sampled_visibility;
mod truth_camera;
mod solution_rrps;
mod smooth_surfaces;
mod gallery_scene;
mod t_junctions;
mod texture_seams;
mod triangles;
