//! The lab: what pixelflow-sim runs on top of the stages. [`jobs`] (solve, render, bench, stats,
//! sweep: each loads its input, checks every option, then works), [`image`] (PNG and EXR files,
//! and reading images back), [`report`] (text tables), [`plot`] (the sweep's plots),
//! [`experiment`] (the paper's figures and tables, the results page), [`export`] (glTF with
//! lightmaps or vertex colours, and reading it back), [`viewer`] (the interactive walkthrough's
//! frame source), [`generate`] (test
//! scenes of any size) and [`closed_form`] (exact answers the solver is measured against).
//!
//! The lab has no user interface: it prints nothing, reads no environment variables and reports
//! progress through [`base::progress::Observer`]; what a job may use (the memory limit, the
//! instruction set) arrives in its [`jobs::Context`].

#![warn(missing_docs)]

pub mod image;
pub mod export;
pub mod jobs;
pub mod report;
pub mod plot;
pub mod viewer;
pub mod experiment;
pub mod generate;
pub mod closed_form;
