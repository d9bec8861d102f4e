//! The engine integration tests, one test binary (one link) for all of them.

/// The repository root (scenes, docs), from this crate's directory.
pub const REPO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");

#[path = "../common/mod.rs"]
mod common;
mod raster;
mod backends;
mod mesh_coverage;
mod texture_footprint;
