//! The commands the binary runs, each built from the stages in the same three steps.
//!
//! 1. **Load the input** ([`crate::Input::load`]): a scene file, or a solution file and the scene
//!    it names. This is cheap (parsing and checking the scene, checking the solution file's
//!    envelope) and gives every command what it needs to validate its options.
//! 2. **Plan**: every option and setting is resolved against the scene's defaults and checked
//!    (method, antialiasing, image size, renderers, region, texture size or budget, camera path),
//!    so a bad value is refused in milliseconds with an [`base::Error::InvalidOption`], before
//!    any solve.
//! 3. **Prepare and run** ([`crate::prepare()`]): solve (or read the solution) and reconstruct,
//!    then render, measure or tabulate.
//!
//! The commands: [`solve`] (scene to solution file), [`render`] (one frame or a walkthrough to
//! PNG, EXR and statistics), [`mod@bench`] (frame times, methods interleaved), [`stats`] (the
//! paper's Table 1), [`compare`] (two images by the metric), [`mod@truth`] (the independent path
//! tracer's reference image and per-polygon estimates, no solve), [`export`] (glTF);
//! [`walkthrough`] summarizes a walkthrough's frames. Each runs in the caller's rayon pool, so
//! the thread count is the caller's choice and the results do not depend on it. Progress reaches
//! the caller through a [`base::progress::Observer`]; the library prints nothing.

pub mod bench;
pub mod compare;
pub mod export;
pub mod render;
pub mod solve;
pub mod stats;
pub mod truth;
pub mod walkthrough;
