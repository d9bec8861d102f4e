//! The truth crate's integration tests, one test binary for all of them: the physics against
//! closed forms (a furnace, an area emitter and a spot light over a floor), the honesty of the
//! standard errors, determinism across thread counts, and the camera against the renderer's
//! projection.

mod camera;
mod closed_form;
mod common;
mod determinism;
mod furnace;
