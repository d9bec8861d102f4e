//! The solve job: a scene file to a solution file, so later renders and walkthroughs never solve
//! again. The file names its scene (absolute path), stores the trees and samples (the RRPs are
//! built from them when a render loads the file, as after a solve) and is written atomically.

use std::path::Path;

use crate::context::Context;
use base::error::Result;
use radiosity::{self, file as solution_file, Solution, SolveOptions};
use scene::{load_scene_with, LoadOptions};

/// Solves `scene_path` and writes the solution to `out`. A solve over the memory limit
/// ([`crate::budget`]) is refused before it starts or stopped when it would pass it.
pub fn solve_to_file(ctx: &Context<'_>, scene_path: &Path, out: &Path) -> Result<Solution> {
    solve_scene_to_file(ctx, scene_path, out, &LoadOptions::default(), &mut |_| {})
}

/// [`solve_to_file`] with the command line's scene options, every warning of the scene (and the
/// line counting its notes) passed to `on_warning` before the solve starts, as a line starting
/// `warning: ` or `note: `.
pub fn solve_scene_to_file(
    ctx: &Context<'_>,
    scene_path: &Path,
    out: &Path,
    opts: &LoadOptions,
    on_warning: &mut dyn FnMut(&str),
) -> Result<Solution> {
    let scene = load_scene_with(scene_path, opts)?;
    base::output::check_outputs(&scene.inputs, &[("output", out)])?;
    // A solution file is named for what it is (renders also recognise it by its magic bytes).
    let what = "a solution file (binary, versioned and checksummed)";
    crate::commands::render::check_extension(
        "output",
        out,
        crate::context::SOLUTION_EXTENSION,
        what,
    )?;
    for w in &scene.warnings {
        on_warning(&format!("warning: {w}"));
    }
    if let Some(n) = crate::context::notes_line(&scene) {
        on_warning(&format!("note: {n}"));
    }
    let limit = ctx.memory_limit;
    crate::budget::check_solve(&scene, limit)?;
    let solution = radiosity::solve(
        &scene,
        &SolveOptions {
            observer: ctx.observer,
            memory_limit: crate::budget::data_limit(limit),
            snapshots: None,
        },
    )?;
    solution_file::write_solution(&ctx.outputs, out, &solution, Some(scene_path))?;
    Ok(solution)
}
