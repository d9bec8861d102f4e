//! pixelflow-sim renders radiosity solutions the way Bastos, Goslin and Zhang proposed for the
//! PixelFlow graphics machine: an adaptive quadtree radiosity solution is reconstructed per polygon
//! as C1 bicubic Hermite patches (RRPs) that a software, SIMD-style rasterizer and a deferred
//! shading pass evaluate per pixel.
//!
//! The modules are the stages a frame passes through, in order: [`scene`] (what is rendered),
//! [`radiosity`] (the solve over [`quadtree`]s), [`reconstruction`] (the RRPs), [`raster`]
//! (regions, G-buffers), [`composition`] (depth merge of the virtual renderers), [`shading`] (the
//! deferred pass) and [`image_out`] / [`output`] (files). [`pipeline`] strings them into the jobs
//! the command line runs; [`report`] formats summaries; [`metric`] (with [`image_in`] reading the
//! files) measures images against a reference for `compare` and the experiments. [`texture`] holds the radiosity textures
//! (RAT) and their on-screen filters, not yet wired into the renderer. `docs/ARCHITECTURE.md` draws the data flow.

#![warn(missing_docs)]

pub mod composition;
pub mod error;
pub mod image_in;
pub mod image_out;
pub mod lanes;
pub mod metric;
pub mod output;
pub mod pipeline;
pub mod quadtree;
pub mod radiosity;
pub mod raster;
pub mod reconstruction;
pub mod report;
pub mod scene;
pub mod shading;
pub mod texture;

pub use error::{Error, Result};
