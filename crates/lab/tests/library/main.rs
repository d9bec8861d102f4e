//! The library integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

/// A generated building of `rooms_x` x `rooms_z` rooms (shell cut `cut` x `cut`), loaded
/// through the scene loader from memory: closed rooms joined by doorways, the case sampled
/// visibility is for.
pub fn building(rooms_x: u32, rooms_z: u32, cut: u32) -> scene::Scene {
    use lab::generate::{generate_building, BuildingOptions, BuildingPaths};
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
mod experiments;
mod frame_context;
mod golden;
mod mesh;
mod metric;
mod mutations;
mod physics;
mod plan;
mod reconstruction_scenes;
mod render;
mod sampled_visibility;
mod truth_camera;
mod solution_rrps;
mod scene_loading;
mod gallery_scene;
