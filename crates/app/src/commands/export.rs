//! The export job: a scene or solution file to glTF ([`export`]), the lightmap atlas
//! from the textures `render --method texture-*` draws (same sizes, centre-placed texels), or
//! the Gouraud mesh with `mesh`.

use std::path::{Path, PathBuf};

use crate::context::Context;
use crate::context::Input;
use crate::context::TextureOptions;
use crate::prepare::prepare;
use base::error::{Error, Result};
use export::{export_lightmap, export_mesh, Container, ExportReport};
use reconstruction::texture::Placement;

/// What `pixelflow-sim export` was asked to do.
#[derive(Debug, Clone, Default)]
pub struct ExportRequest {
    /// The scene's command-line options (`-D`, `--camera`, `--strict`).
    pub load: scene::LoadOptions,
    /// Scene file or solution file.
    pub input: PathBuf,
    /// The scene of a solution file, when not where the file says (`--scene`).
    pub scene: Option<PathBuf>,
    /// The glTF to write (`.glb` or `.gltf`).
    pub output: PathBuf,
    /// The adaptive mesh with vertex colours instead of the lightmap.
    pub mesh: bool,
    /// Largest atlas page side (a power of two).
    pub page_size: u32,
    /// Texture sizes (as `render`'s texture methods take them).
    pub texture: TextureOptions,
    /// Exposure in stops (default: the scene's).
    pub exposure: Option<f64>,
}

/// Default largest atlas page side: what every desktop and mobile GPU of the last decade
/// samples.
pub const DEFAULT_PAGE: u32 = 4096;

/// Runs an export: checks the options, loads (or solves) the input, writes the glTF.
pub fn run_export(ctx: &Context<'_>, req: &ExportRequest) -> Result<ExportReport> {
    Container::of(&req.output)?;
    if !req.mesh {
        export::atlas::check_page(req.page_size)?;
    }
    if req
        .texture
        .placement
        .as_deref()
        .is_some_and(|p| p != "centre")
    {
        return Err(Error::invalid_option(
            "texel-placement",
            req.texture.placement.clone().unwrap_or_default(),
            "an atlas holds centre-placed texels (texel centres at (i + 0.5) / n, as engines sample)",
        ));
    }
    if let Some(n) = req.texture.anisotropy {
        return Err(Error::invalid_option(
            "anisotropy",
            n.to_string(),
            "an export writes the textures; the engine that draws them filters them",
        ));
    }
    let input = Input::load_opts(&req.input, req.scene.as_deref(), &req.load)?;
    check_export_outputs(&input, req)?;
    let policy = req.texture.policy(&input.scene)?;
    let exposure = req.exposure.unwrap_or(input.scene.display.exposure);
    if !exposure.is_finite() {
        return Err(Error::invalid_option(
            "exposure",
            exposure.to_string(),
            "must be finite",
        ));
    }
    let p = prepare(ctx, input, policy, Placement::Centre)?;
    if req.mesh {
        let (mesh, _) = p.mesh()?;
        export_mesh(&p.scene, mesh, exposure, &req.output, &ctx.outputs)
    } else {
        let (set, _) = p.textures()?;
        let (recon, _) = p.expanded()?;
        export_lightmap(
            &p.scene,
            set,
            recon,
            req.page_size,
            exposure,
            &req.output,
            &ctx.outputs,
        )
    }
}

/// Atlas pages whose names are checked before the work: an export writes as many pages as its
/// atlas needs, known only once the textures are built, and no shipped or generated scene needs
/// more than a few.
pub const PAGES_CHECKED: usize = 256;

/// Checks every file an export may write, before any work (`base::output::check_outputs`):
/// the glTF, its buffer beside it (`.gltf`), and the atlas pages beside it (PNG for `.gltf`,
/// linear EXR always, up to [`PAGES_CHECKED`] of each), against the scene's and the solution's
/// files, links, directories and each other.
fn check_export_outputs(input: &Input, req: &ExportRequest) -> Result<()> {
    let mut inputs = input.scene.inputs.clone();
    inputs.extend(input.solution_file.clone());
    inputs.push(req.input.clone());
    let container = Container::of(&req.output)?;
    let mut paths = vec![req.output.clone()];
    if container == Container::Gltf {
        paths.push(export::sibling(&req.output, ".bin"));
    }
    if !req.mesh {
        for k in 0..PAGES_CHECKED {
            paths.push(export::sibling(&req.output, &format!(".lightmap-{k}.exr")));
            if container == Container::Gltf {
                paths.push(export::sibling(&req.output, &format!(".lightmap-{k}.png")));
            }
        }
    }
    let named: Vec<(&str, &Path)> = paths.iter().map(|p| ("output", p.as_path())).collect();
    base::output::check_outputs(&inputs, &named)
}
