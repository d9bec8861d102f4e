//! The library integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

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
