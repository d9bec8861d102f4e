//! Experiments: the paper's Fig. 5, Fig. 6 and Table 1 rerun on our scenes, extended with the
//! direct method the paper could only propose. Like the application's commands, this module: it
//! strings scene loading, the solve, reconstruction, texture resampling, the renderer and the
//! metric together and writes images and tables; it adds no stage of its own.
//!
//! Fig. 5 and Fig. 6 work in texture space: the two-spots plane is the unit square seen by an
//! orthographic camera that maps it exactly onto the image, so pixel (x, y) of an N x N image is
//! the point (u, v) = ((x + 0.5) / N, 1 - (y + 0.5) / N) of the plane. Every image is compared with
//! the **oracle reference** (the solver's exact radiosity at every pixel centre, no
//! reconstruction); the paper's own reference, a depth-9 quadtree (513 x 513 samples), is rendered
//! too (bilinear between its samples) and its distance to the oracle is reported, so the reader
//! sees how much the choice of reference matters.
//!
//! Invariants: the images depend only on the scene, the sizes and the solver's fixed seeds
//! (deterministic for any thread count); every number printed comes from
//! [`metric::compare`] with the stated pixels per degree; the paper's numbers are quoted
//! beside ours, never mixed into them. The paper does not give the viewing geometry or scaling of its metric, so its absolute metric
//! values cannot be reproduced (its viewing geometry and scaling are unknown): compare orderings
//! and ratios.
//!
//! Layout: `figures` (Fig. 5, Fig. 6, the spot sweep), `table1`, `markdown` (the report),
//! `results` (`docs/results.md`: every method's speed, error and memory on every shipped scene),
//! `matched` (its Table 1 at matched error), `walk_error` (its error along the camera path),
//! `labels` (how those tables print sizes and textures);
//! this file holds the job: what to run, running it, and the terminal text.

mod figures;
mod labels;
mod markdown;
pub mod matched;
pub mod results;
mod table1;
pub mod walk_error;

pub use figures::{
    fig5, fig6, figure_text, paper_misfit, sensitivity, spot_fraction_at, spot_radius_10,
    spot_sweep, sweep_half_angle, sweep_row, Figure, FigureOptions, Panel, Sensitivity, SweepRow,
    CONE_EDGE_FRACTION, MAX_SWEEP_HALF_ANGLE_DEG, PAPER_FIG5, PAPER_FIG6,
};
pub use markdown::{markdown, sweep_markdown};
pub use table1::{table1, table1_markdown, PaperRow, PAPER_TABLE1};

use app::commands::stats::ModelStats;
use app::context::Context;
use base::error::{Error, Result};
use reconstruction::Estimator;
use scene::load_scene;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The shipped scenes Table 1 is computed for by default.
pub const SHIPPED_SCENES: [&str; 4] = [
    "scenes/two-spots.toml",
    "scenes/cornell-box.toml",
    "scenes/gallery.toml",
    "scenes/gallery-fine.toml",
];

/// Parses an estimator's name (`plain`, `monotone` or `hyman`), for `--estimator`.
pub fn parse_estimator(s: &str) -> Result<Estimator> {
    Estimator::parse_option("estimator", s)
}

/// Which experiment to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Which {
    /// Fig. 5.
    Fig5,
    /// Fig. 6.
    Fig6,
    /// Table 1.
    Table1,
    /// All three (and the Markdown report, if asked for).
    All,
}

impl Which {
    /// Parses `fig5`, `fig6`, `table1` or `all`.
    pub fn parse(s: &str) -> Result<Which> {
        match s {
            "fig5" => Ok(Which::Fig5),
            "fig6" => Ok(Which::Fig6),
            "table1" => Ok(Which::Table1),
            "all" => Ok(Which::All),
            _ => Err(Error::invalid_option(
                "experiment",
                s,
                "expected fig5, fig6, table1 or all",
            )),
        }
    }
}

/// An experiment job.
#[derive(Debug, Clone)]
pub struct Request {
    /// What to run.
    pub which: Which,
    /// Settings of fig5 and fig6 (and where images go).
    pub figures: FigureOptions,
    /// Table 1's scenes.
    pub scenes: Vec<PathBuf>,
    /// Table 1's frames per method (0: sizes only).
    pub frames: u32,
    /// With [`Which::All`]: the Markdown report to write.
    pub doc: Option<PathBuf>,
}

/// What an experiment job produced.
#[derive(Debug, Clone, Serialize, Default)]
pub struct Results {
    /// Fig. 5, if run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fig5: Option<Figure>,
    /// Fig. 6, if run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fig6: Option<Figure>,
    /// Table 1 rows, if run.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub table1: Vec<ModelStats>,
    /// The spot sweep (with fig5 or all).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sweep: Vec<SweepRow>,
    /// The figures on the shipped variants, with the spot moved and the viewer nearer and
    /// farther (with all).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sensitivity: Vec<Sensitivity>,
}

/// The figure scene's shipped variants, beside it in `scenes/`: the wider spot the figures used
/// before they were fitted to the paper, and the spot narrower than the sample spacing.
pub const FIGURE_VARIANTS: [&str; 3] = [
    "two-spots-paper.toml",
    "two-spots.toml",
    "two-spots-narrow.toml",
];

/// Falloff exponents of the spot sweep, joined by the scene's own and run from narrow to wide:
/// from the narrow spot of `scenes/two-spots-narrow.toml` (60, its 10 % radius half the coarse
/// grid's spacing) to one whose grid neighbours keep most of the peak, closer together between
/// 12 and 30, where the figures' ratios pass the paper's.
pub(crate) const SWEEP_FALLOFFS: [f64; 12] = [
    60.0, 40.0, 30.0, 25.0, 22.0, 20.0, 18.0, 15.0, 12.0, 8.0, 3.0, 1.0,
];

/// The sweep's falloffs: `own` (the scene's) with `SWEEP_FALLOFFS`, narrowest spot first,
/// each once.
pub fn sweep_falloffs(own: Option<f64>) -> Vec<f64> {
    let mut v: Vec<f64> = own.into_iter().chain(SWEEP_FALLOFFS).collect();
    v.sort_by(|a, b| b.total_cmp(a));
    v.dedup();
    v
}

/// Runs `req`, calling `wrote` for every file written.
pub fn run(job: &Context<'_>, req: &Request, wrote: &mut dyn FnMut(&Path)) -> Result<Results> {
    check_doc(req)?;
    let mut r = Results::default();
    let figures = FigureOptions {
        isa: job.isa,
        outputs: job.outputs.clone(),
        ..req.figures.clone()
    };
    let any = |w: Which| req.which == w || req.which == Which::All;
    let report_images = |f: &Figure, wrote: &mut dyn FnMut(&Path)| {
        if let Some(dir) = &req.figures.out_dir {
            for p in f.panels.iter().filter(|p| !p.file.is_empty()) {
                wrote(&dir.join(&p.file));
            }
        }
    };
    if any(Which::Fig5) {
        let f = fig5(&figures)?;
        report_images(&f, wrote);
        r.fig5 = Some(f);
    }
    if any(Which::Fig5) {
        let scene = load_scene(&req.figures.scene)?;
        let own = scene.spots.first().map(|s| s.falloff);
        r.sweep = spot_sweep(&figures, &sweep_falloffs(own))?;
    }
    if req.which == Which::All {
        r.sensitivity = sensitivity(&figures, &FIGURE_VARIANTS)?;
    }
    if any(Which::Fig6) {
        let f = fig6(&figures)?;
        report_images(&f, wrote);
        r.fig6 = Some(f);
    }
    if any(Which::Table1) {
        let opts = job.frame_options(1024, 1024);
        r.table1 = table1(job, &req.scenes, req.frames, &opts)?;
    }
    if let (Which::All, Some(doc)) = (req.which, &req.doc) {
        let md = markdown(&r, req, doc)?;
        job.outputs.write_atomic(doc, md.as_bytes())?;
        wrote(doc);
    }
    Ok(r)
}

/// Refuses (exit 2, before any work) a `--doc` page that is, or resolves to, one of the
/// experiment's input files: the figures' scene and Table 1's scenes, with what they include.
fn check_doc(req: &Request) -> Result<()> {
    let Some(doc) = &req.doc else {
        return Ok(());
    };
    let mut inputs = Vec::new();
    for scene in std::iter::once(&req.figures.scene).chain(&req.scenes) {
        match load_scene(scene) {
            Ok(s) => inputs.extend(s.inputs),
            // Still refuse the scene file itself; its own error comes when it is used.
            Err(_) => inputs.push(scene.clone()),
        }
    }
    base::output::check_outputs(&inputs, &[("doc", doc)])
}

/// Every table of `r` as text.
pub fn results_text(r: &Results) -> String {
    let mut t = String::new();
    for f in [&r.fig5, &r.fig6].into_iter().flatten() {
        t += &figure_text(f);
        t += "\n";
    }
    if !r.sweep.is_empty() {
        t += "spot sweep (first spot's falloff varied, its cone widened; perceptual distances):\n";
        t += &sweep_markdown(&r.sweep);
        t += "\n";
    }
    if !r.table1.is_empty() {
        t += "table1 (paper's models first; fps at 1024 x 1024 on this machine):\n";
        t += &table1_markdown(&r.table1);
        for s in &r.table1 {
            t += "\n";
            t += &app::report::model_stats_text(s);
        }
    }
    t
}
