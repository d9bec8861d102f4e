//! pixelflow-sim renders radiosity solutions the way Bastos, Goslin and Zhang proposed for the
//! PixelFlow graphics machine: an adaptive quadtree radiosity solution is reconstructed per polygon
//! as C1 bicubic Hermite patches (RRPs) that a software, SIMD-style rasterizer and a deferred
//! shading pass evaluate per pixel.
//!
//! The modules are listed in the order data flows through them, and every `use crate::` edge
//! points from a later module to an earlier one (a test, `tests/architecture.rs`, keeps it so):
//!
//! - foundation, used by every stage: [`error`], [`lanes`] (the 8-lane SIMD type), [`output`]
//!   (atomic files), [`progress`] (the observer through which long jobs report), [`image`] (linear
//!   images and their files), [`quadtree`], [`method`] (the method names and option limits);
//! - the frame's stages: [`scene`] (what is rendered) -> [`radiosity`] (the solve) ->
//!   [`reconstruction`] (the RRPs, and the Gouraud mesh they replace) -> [`texture`] (radiosity
//!   textures, RAT) -> [`raster`] (renderers, regions, G-buffers) -> [`composition`] (depth merge
//!   of the renderers) -> [`shading`] (the deferred pass, one shader per method) -> [`frame`] (one
//!   frame through all of them, timed);
//! - after the frame: [`metric`] (distances between images) -> [`jobs`] (solve, render, bench,
//!   stats, sweep: what the command line runs) -> [`report`] (text tables) -> [`plot`] (sweep
//!   plots) -> [`experiment`] (the paper's figures and tables).
//!
//! The library has no user interface: it prints nothing, reads no environment variables and
//! reports progress through [`progress::Observer`]. `docs/ARCHITECTURE.md` draws the data flow.

#![warn(missing_docs)]

pub mod error;
pub mod lanes;
pub mod output;
pub mod progress;
pub mod image;
pub mod quadtree;
pub mod method;

pub mod scene;
pub mod radiosity;
pub mod reconstruction;
pub mod texture;
pub mod raster;
pub mod composition;
pub mod shading;
pub mod frame;

pub mod metric;
pub mod jobs;
pub mod report;
pub mod plot;
pub mod experiment;

pub use error::{Error, Result};
pub use method::Method;
