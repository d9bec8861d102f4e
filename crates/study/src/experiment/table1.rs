//! Table 1 of the paper: the `stats` of each scene, laid out beside the paper's three models.

use app::commands::stats::{model_stats, ModelStats};
use app::context::Context;
use app::context::TextureOptions;
use app::prepare::prepare_path;
use app::prepare::Prepared;
use base::error::Result;
use base::method::Filter;
use base::progress::Silent;
use engine::frame::FrameOptions;
use std::path::{Path, PathBuf};

/// One row of the paper's Table 1 (Bastos, Goslin and Zhang).
#[derive(Debug, Clone, Copy)]
pub struct PaperRow {
    /// Model name.
    pub model: &'static str,
    /// Original triangles.
    pub orig_tris: u64,
    /// Polygonal radiosity model triangles and vertices.
    pub poly: (u64, u64),
    /// Its frame rate (as printed).
    pub poly_fps: &'static str,
    /// RAT model triangles and vertices.
    pub rat: (u64, u64),
    /// Its frame rate (as printed; the meter capped at 30).
    pub rat_fps: &'static str,
    /// Model sizes in MB: poly, RAT.
    pub mb: (f64, f64),
    /// Texture memory, MB.
    pub texture_mb: f64,
    /// Number of textures.
    pub textures: u64,
}

/// The paper's Table 1, for printing beside ours.
pub const PAPER_TABLE1: [PaperRow; 3] = [
    PaperRow {
        model: "grotto",
        orig_tris: 804,
        poly: (158_670, 208_052),
        poly_fps: "3.8",
        rat: (804, 1_608),
        rat_fps: ">30",
        mb: (2.23, 0.23),
        texture_mb: 4.64,
        textures: 402,
    },
    PaperRow {
        model: "lavapit",
        orig_tris: 1_336,
        poly: (55_158, 71_648),
        poly_fps: "7.5",
        rat: (7_188, 9_195),
        rat_fps: ">30",
        mb: (1.02, 1.09),
        texture_mb: 1.41,
        textures: 172,
    },
    PaperRow {
        model: "mausoleum",
        orig_tris: 1_022,
        poly: (41_342, 51_916),
        poly_fps: "20.0",
        rat: (8_208, 10_604),
        rat_fps: ">30",
        mb: (0.82, 1.40),
        texture_mb: 1.90,
        textures: 41,
    },
];

/// Table 1 for several scenes (`stats` of each, frames measured if `frames > 0`).
pub fn table1(
    job: &Context<'_>,
    scenes: &[PathBuf],
    frames: u32,
    opts: &FrameOptions,
) -> Result<Vec<ModelStats>> {
    scenes
        .iter()
        .map(|s| {
            let p: Prepared =
                prepare_path(&job.with_observer(&Silent), s, &TextureOptions::default())?;
            model_stats(&p, frames, opts, Filter::MITCHELL)
        })
        .collect()
}

/// Table 1 as a Markdown table: the paper's three models, then ours, in the paper's columns
/// (frame rates in fps; sizes in decimal MB; texture memory at 12 bits per channel without mip
/// chains, the closest to the RealityEngine's 12-bit texels), plus the direct method's rate and
/// the RRP memory, stored (the trees and samples they are built from) and as held.
pub fn table1_markdown(rows: &[ModelStats]) -> String {
    let mut t = String::from(
        "| model | orig tris | poly tris | poly verts | poly fps | RAT tris | RAT verts | \
         RAT fps (bilinear / bicubic) | direct fps | poly MB | RAT MB | texture memory MB | \
         textures | RRP MB stored / held |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let g = app::report::grouped;
    for r in PAPER_TABLE1 {
        t += &format!(
            "| {} (paper) | {} | {} | {} | {} | {} | {} | {} | - | {:.2} | {:.2} | {:.2} | {} | - |\n",
            r.model,
            g(r.orig_tris),
            g(r.poly.0),
            g(r.poly.1),
            r.poly_fps,
            g(r.rat.0),
            g(r.rat.1),
            r.rat_fps,
            r.mb.0,
            r.mb.1,
            r.texture_mb,
            r.textures
        );
    }
    for s in rows {
        let fps = |m: &str| {
            s.frames
                .iter()
                .find(|r| r.method == m)
                .map_or("-".into(), |r| format!("{:.1}", r.fps))
        };
        let name = Path::new(&s.scene)
            .file_stem()
            .map_or(s.scene.clone(), |x| x.to_string_lossy().into_owned());
        t += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} / {} | {} | {:.2} | {:.2} | {:.2} | {} | {:.2} / {:.2} |\n",
            name,
            g(s.original.triangles),
            g(s.mesh.triangles),
            g(s.mesh.vertices),
            fps("mesh"),
            g(s.rat_triangles),
            g(s.rat_vertices),
            fps("texture-bilinear"),
            fps("texture-bicubic"),
            fps("direct"),
            s.mesh.bytes as f64 / 1e6,
            s.rat_bytes as f64 / 1e6,
            s.texture_memory.bytes[1] as f64 / 1e6,
            g(s.texture_memory.textures as u64),
            s.rrp_stored_bytes as f64 / 1e6,
            s.rrp_bytes as f64 / 1e6
        );
    }
    t
}
