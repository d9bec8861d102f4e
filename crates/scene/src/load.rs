//! Loading a scene file: TOML text in, a validated [`Scene`] out, or an [`Error::Input`] that
//! names the file, the line and the key of the first problem.
//!
//! This is the entry point: a scene file (`scene::parse` validates its text and reads its
//! includes) or a bare model from a modelling tool (`scene::model`: an OBJ or glTF file given
//! directly, lit and framed by guess), with the command line's `-D` overrides and `--strict`.
//! The rules [`Scene`] promises to later stages (finite numbers, reflectance in [0, 1), planar
//! convex faces, at least one polygon and one light) are all established by the readers, and
//! nothing is silently changed except documented repairs: quads within
//! [`crate::PLANARITY_TOLERANCE`] are projected onto their best-fit plane, and quads beyond it
//! are split into two triangles with a warning in [`Scene::warnings`] (`scene::face`).
//!
//! Every input is untrusted: no value reaches arithmetic that could panic (indices, casts,
//! divisions) before it has been checked, and the property tests in
//! `crates/scene/tests/loading.rs` feed random and mutated files to
//! [`crate::parse_scene`].

use super::Scene;
use crate::checks::{line_of, with_files};
pub use crate::checks::{LoadOptions, MAX_FACE_CORNERS, MAX_MTL_FILES, MAX_SHADOW_RAYS};
use crate::parse::parse_scene_options;
use base::error::{Error, Location, Result};
use std::path::Path;

/// Reads and validates the scene file at `path`.
///
/// A file that cannot be read is an [`Error::Input`] (exit code 2): it is the user's input.
pub fn load_scene(path: &Path) -> Result<Scene> {
    load_scene_with(path, &LoadOptions::default())
}

/// [`load_scene`] with the command line's options: a scene file (TOML) or a bare model (`.obj`,
/// `.gltf`, `.glb`, see `scene::model`), `-D` overrides applied, then the orientation checks of
/// `scene::orientation` added to its warnings.
pub fn load_scene_with(path: &Path, opts: &LoadOptions) -> Result<Scene> {
    let mut scene = if super::model::is_model(path) {
        super::model::load_model(path, opts)?
    } else {
        let text = base::output::read_text(path, opts.input_limit).map_err(|e| {
            Error::input(Location::file(path), format!("cannot read scene file: {e}"))
        })?;
        check_is_toml(&text, path)?;
        let parsed = with_files(opts.input_limit, |r| {
            parse_scene_options(&text, path, r, opts)
        })?;
        let mut scene = parsed.scene;
        if let Some(c) = parsed.camera {
            scene
                .notes
                .push(format!("{}: not used: the scene's [camera] is", c.origin));
        }
        scene
    };
    let facing = super::orientation::warnings(&scene);
    scene.warnings.extend(facing);
    Ok(scene)
}

/// A file not named `.toml` whose text is not TOML at all is most likely another format (a
/// model from a tool, an image): refused with what the commands read instead, rather than with
/// the TOML parser's complaint alone.
fn check_is_toml(text: &str, path: &Path) -> Result<()> {
    let toml_named = path
        .extension()
        .and_then(|x| x.to_str())
        .is_some_and(|x| x.eq_ignore_ascii_case("toml"));
    if toml_named {
        return Ok(());
    }
    match toml::from_str::<toml::Table>(text) {
        Err(e) => {
            let line = e.span().map_or(1, |s| line_of(text, s.start));
            Err(Error::input(
                Location::file(path),
                format!(
                    "is not a scene file: scenes are TOML (.toml), models Wavefront OBJ (.obj, \
                     with their .mtl) or glTF 2.0 (.gltf, .glb), solutions .pfsol; export other \
                     formats as OBJ or glTF (the TOML parser says, at line {line}: {})",
                    e.message().trim_end()
                ),
            ))
        }
        _ => Ok(()),
    }
}
