//! The vocabulary every stage of pixelflow-sim shares: [`error`] (one error type, with the exit
//! codes the binary maps it to), [`output`] (atomic files and size-limited reads), [`progress`]
//! (the observer through which long jobs report), [`method`] (the rendering methods' names and
//! option limits), [`image`] (linear-RGB images) and [`quadtree`] (the (u, v) domain every
//! polygon's radiosity lives on, shared by the solver, the reconstruction and the textures).
//!
//! Invariants: nothing here knows a scene or a renderer, and nothing here prints or reads the
//! environment; every other crate depends on this one and this one on none of them.

#![forbid(unsafe_code)]

pub mod error;
pub mod output;
pub mod progress;
pub mod image;
pub mod quadtree;
pub mod method;
pub mod rng;

pub use error::{Error, Result};
pub use method::Method;
