//! A scene's camera path timed in a worker process ([`crate::timing`]): the request names the
//! scene, its solution file and the methods; the worker flies the path with each method and
//! replies with every frame's time. The results page's walkthrough rates come from here.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::timing::WorkerTask;
use app::commands::walkthrough::walk;
use app::context::{scene_texture_policy, Context, Input};
use app::prepare::prepare;
use base::error::{Error, Result};
use base::method::Method;

/// What a walkthrough's timing worker is asked: the scene, its solution in a file, the methods.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WalkWorkerRequest {
    /// The scene file (solved at its own settings).
    pub scene: PathBuf,
    /// Its solution file.
    pub solution: PathBuf,
    /// Method names, in the order of the reply.
    pub methods: Vec<String>,
    /// Worker threads (the parent's).
    pub threads: usize,
}

/// A timing worker's walkthrough job: per method, every frame's wall-clock time, ms, at the
/// scene's image size, textures sized and placed as the scene says.
fn walk_times(job: &Context<'_>, w: &WalkWorkerRequest) -> Result<Vec<Vec<f64>>> {
    let mut input = Input::load(&w.scene)?;
    input.solution_file = Some(w.solution.clone());
    let policy = scene_texture_policy(&input.scene);
    let placement = input.scene.render.texel_placement;
    let p = prepare(job, input, policy, placement)?;
    let path = p.scene.camera_path.clone().ok_or_else(|| {
        Error::invalid_option(
            "time-worker",
            w.scene.display().to_string(),
            "has no camera path",
        )
    })?;
    let opts = job.frame_options(p.scene.width, p.scene.height);
    w.methods
        .iter()
        .map(|name| {
            let frames = walk(&p, Method::parse(name)?, &path, &opts)?;
            Ok(frames.iter().map(|s| s.frame_ms).collect())
        })
        .collect()
}

impl WorkerTask for WalkWorkerRequest {
    const JOB: &'static str = "walkthrough";

    fn threads(&self) -> usize {
        self.threads
    }

    fn times(&self, job: &Context<'_>) -> Result<Vec<Vec<f64>>> {
        walk_times(job, self)
    }
}
