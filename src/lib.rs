//! pixelflow-sim renders radiosity solutions the way Bastos, Goslin and Zhang proposed for the
//! PixelFlow graphics machine: an adaptive quadtree radiosity solution is reconstructed per polygon
//! as C1 bicubic Hermite patches (RRPs) that a software, SIMD-style rasterizer and a deferred
//! shading pass evaluate per pixel.
//!
//! The modules are the stages a frame passes through, in order: [`scene`] (what is rendered),
//! [`radiosity`] (the solve over [`quadtree`]s), [`reconstruction`] (the RRPs, and the Gouraud
//! mesh they replace), [`texture`] (the radiosity textures, RAT), [`raster`] (regions,
//! G-buffers), [`composition`] (depth merge of the virtual renderers), [`shading`] (the deferred
//! pass, one shader per method), [`image_out`] / [`output`] (files) and [`metric`] (distances
//! between images, with [`image_in`] to read them). [`pipeline`] and [`experiment`] string the
//! stages into the jobs the command line runs; [`report`] formats summaries. The library draws
//! nothing and reads no environment: long calls report progress and trace lines to the caller's
//! [`progress::Observer`].
//! `docs/ARCHITECTURE.md` draws the data flow.

#![warn(missing_docs)]

pub mod composition;
pub mod error;
pub mod experiment;
pub mod image_in;
pub mod image_out;
pub mod lanes;
pub mod metric;
pub mod output;
pub mod pipeline;
pub mod progress;
pub mod quadtree;
pub mod radiosity;
pub mod raster;
pub mod reconstruction;
pub mod report;
pub mod scene;
pub mod shading;
pub mod texture;

pub use error::{Error, Result};
