//! The PixelFlow engine: one frame from polygons to pixels, the way PixelFlow drew it. The
//! stages, in the order data passes through them: [`raster`] (geometry, setup, binning over
//! virtual renderers and screen regions, the SIMD rasterizer writing region G-buffers) ->
//! [`composition`] (the depth merge of the renderers' G-buffers) -> [`shading`] (the deferred
//! pass, one shader per method) -> [`frame`] (the stages wired together per region, timed, with
//! buffers kept across frames).
//!
//! Invariants: the image depends only on the scene, the camera, the shader's data and the
//! options, never on the thread count, the renderer count or the instruction set the kernels
//! ran with ([`frame::FrameOptions::isa`]); the shading pass never sees the scene.

pub mod raster;
pub mod composition;
pub mod shading;
pub mod frame;

/// The optimization level this crate was compiled at (cargo's `OPT_LEVEL`: `"3"` for a release
/// build). The benchmarks refuse to time anything less: under `cargo bench` the workspace's
/// test-build overrides compile the engine at level 1 and its base at 0 (`cargo bench
/// -p pixelflow-bench --profile release` builds every crate at 3).
#[cfg(feature = "bench")]
pub const OPT_LEVEL: &str = env!("PIXELFLOW_ENGINE_OPT_LEVEL");
