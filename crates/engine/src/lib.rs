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
