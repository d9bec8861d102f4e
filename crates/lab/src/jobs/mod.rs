//! Jobs: what the command line runs, each built from the stages in the same three steps.
//!
//! 1. **Load the input** ([`Input::load`]): a scene file, or a solution file and the scene it
//!    names. This is cheap (parsing and checking the scene, checking the solution file's envelope)
//!    and gives every job what it needs to validate its options.
//! 2. **Plan**: every option and setting is resolved against the scene's defaults and checked
//!    (method, antialiasing, image size, renderers, region, texture size or budget, camera path),
//!    so a bad value is refused in milliseconds with an [`base::Error::InvalidOption`], before
//!    any solve.
//! 3. **Prepare and run** ([`prepare`]): solve (or read the solution), build the RRPs in compact
//!    form (what the direct method evaluates: quantized vertex data, each patch expanded when a
//!    screen region first needs it), then render, measure or tabulate. The expanded patches (which
//!    the texture methods resample), the textures and the mesh are built lazily on first use, so a
//!    job that only draws `direct` never pays for them.
//!
//! The jobs: [`solve`] (scene to solution file), [`render`] (one frame or a walkthrough to PNG,
//! EXR and statistics), [`mod@bench`] (frame times, methods interleaved), [`stats`] (the paper's
//! Table 1), [`sweep`] (speed against error over sampling densities and texture sizes),
//! [`mod@truth`] (the independent path tracer's reference image and per-polygon estimates, no
//! solve); [`walkthrough`] summarizes a walkthrough's frames. Each runs in the caller's rayon
//! pool, so the thread count is the caller's choice and the results do not depend on it.
//! Progress reaches the caller through a [`base::progress::Observer`]; the library prints
//! nothing.

pub mod bench;
pub mod compare;
pub mod equal_error;
pub mod equal_views;
pub mod export;
pub mod budget;
pub mod memory;
pub mod physics;
pub mod render;
pub mod solve;
pub mod stats;
pub mod sweep;
pub mod timing;
pub mod truth;
pub mod walkthrough;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Instant;

use base::error::{Error, Result};
use base::method::{check_texture_side, Method, Placement};
use base::output::Outputs;
use base::progress::{Observer, Stage};
use engine::frame::FrameOptions;
use lanes::Isa;
use radiosity::{self, file as solution_file, Solution, SolveOptions};
use reconstruction::compact::CompactReconstruction;
use reconstruction::mesh::MeshModel;
use reconstruction::texture::{SizePolicy, TextureSet};
use reconstruction::{Estimator, Reconstruction, Seams, Sharp, SharpLight};
use scene::{load_scene_with, LoadOptions, Scene};

/// What a job may use, given by its caller and passed down explicitly (the library holds no
/// process-wide setting): the memory limit every estimate is checked against, the instruction
/// set frames run with, and the observer progress goes to.
#[derive(Clone)]
pub struct Context<'a> {
    /// Bytes a job may hold ([`budget`]'s estimates are refused above it); `u64::MAX`: none.
    pub memory_limit: u64,
    /// The instruction set the frames' kernels run with (a choice of speed: the images are the
    /// same for every one).
    pub isa: Isa,
    /// Where progress and trace lines go.
    pub observer: &'a dyn Observer,
    /// The registry every file the job writes goes through (a clone in the caller's signal
    /// handler removes the temporaries of an interrupted write).
    pub outputs: Outputs,
}

impl<'a> Context<'a> {
    /// No memory limit, the widest instruction set the CPU has, progress to `observer`.
    pub fn new(observer: &'a dyn Observer) -> Context<'a> {
        Context {
            memory_limit: u64::MAX,
            isa: Isa::detect(),
            observer,
            outputs: Outputs::new(),
        }
    }

    /// This context with a memory limit of `bytes`.
    pub fn with_memory_limit(self, bytes: u64) -> Context<'a> {
        Context {
            memory_limit: bytes,
            ..self
        }
    }

    /// This context with progress going to `observer`.
    pub(crate) fn with_observer<'b>(&self, observer: &'b dyn Observer) -> Context<'b> {
        Context {
            memory_limit: self.memory_limit,
            isa: self.isa,
            observer,
            outputs: self.outputs.clone(),
        }
    }

    /// This context writing through `outputs`.
    pub fn with_outputs(self, outputs: Outputs) -> Context<'a> {
        Context { outputs, ..self }
    }

    /// This context with the instruction set `isa`.
    pub fn with_isa(self, isa: Isa) -> Context<'a> {
        Context { isa, ..self }
    }

    /// Frame options for a `width` x `height` image with the defaults and this context's
    /// instruction set.
    pub(crate) fn frame_options(&self, width: u32, height: u32) -> FrameOptions {
        FrameOptions {
            isa: self.isa,
            ..FrameOptions::new(width, height)
        }
    }
}

impl Default for Context<'static> {
    /// [`Context::new`] with no observer ([`base::progress::SILENT`]).
    fn default() -> Context<'static> {
        Context::new(&base::progress::SILENT)
    }
}

/// A job's input, loaded and checked but not solved: the scene, and the solution file if the
/// input was one.
#[derive(Debug, Clone)]
pub struct Input {
    /// The path the user gave.
    pub path: PathBuf,
    /// The scene (from the file itself, or the one the solution file names).
    pub scene: Scene,
    /// The solution file, when the input is one (its envelope is checked already).
    pub solution_file: Option<PathBuf>,
    /// The RRPs' derivative estimator (`--estimator`; default [`Estimator::default`]). A
    /// solution file's stored RRPs were built with the default; another estimator rebuilds
    /// them from the samples.
    pub estimator: Estimator,
    /// How many levels below the solver's leaves the RRPs follow the edges of the spots' light
    /// (`--sharp-levels`; default [`reconstruction::sharp::DEFAULT_LEVELS`]; 0: the spots'
    /// light is reconstructed from the samples like any other). A solution file's stored RRPs
    /// were built with the default; another value rebuilds them.
    pub sharp_levels: u32,
}

impl Input {
    /// Loads a scene file, or a solution file's scene (checking the solution file's magic,
    /// version, length and checksum). A file is a solution file by its magic bytes, or by its
    /// `.pfsol` extension (so an empty or damaged one is reported as a bad solution file, not as
    /// a scene that fails to parse). Nothing is solved.
    pub fn load(path: &Path) -> Result<Input> {
        Input::load_with(path, None)
    }

    /// [`Input::load`], a solution file's scene read from `scene` when given (`--scene`: the
    /// scene moved away from where the solution file says; its hash is still checked against
    /// the solution). Errors if `scene` is given for an input that is not a solution file.
    pub fn load_with(path: &Path, scene: Option<&Path>) -> Result<Input> {
        Input::load_opts(path, scene, &LoadOptions::default())
    }

    /// [`Input::load_with`] with the command line's scene options (`-D`, `--camera`,
    /// `--strict`), applied to the scene file or to a solution file's scene.
    pub fn load_opts(path: &Path, scene: Option<&Path>, opts: &LoadOptions) -> Result<Input> {
        let named_solution = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case(SOLUTION_EXTENSION));
        if named_solution || is_solution_file(path) {
            let scene_path = match scene {
                Some(s) => s.to_path_buf(),
                None => solution_file::read_scene_path(path)?,
            };
            Ok(Input {
                path: path.to_path_buf(),
                scene: load_scene_with(&scene_path, opts)?,
                solution_file: Some(path.to_path_buf()),
                estimator: Estimator::default(),
                sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
            })
        } else {
            if let Some(s) = scene {
                return Err(Error::invalid_option(
                    "--scene",
                    s.display().to_string(),
                    format!(
                        "names the scene of a solution file, and {} is a scene file",
                        path.display()
                    ),
                ));
            }
            Ok(Input {
                path: path.to_path_buf(),
                scene: load_scene_with(path, opts)?,
                solution_file: None,
                estimator: Estimator::default(),
                sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
            })
        }
    }
}

/// One line for a scene's notes (repairs that change nothing the image shows), for the commands
/// that do not list them: how many, and the command that does; `None` without notes.
pub fn notes_line(scene: &scene::Scene) -> Option<String> {
    let n = scene.notes.len();
    (n > 0).then(|| {
        format!(
            "{n} repair{} of the scene's input that change nothing the image shows (faces split \
             or triangulated, repeats counted once): `pixelflow-sim check {}` lists them",
            if n == 1 { "" } else { "s" },
            scene.source.display()
        )
    })
}

/// The extension of solution files (`solve -o x.pfsol`).
pub(crate) const SOLUTION_EXTENSION: &str = "pfsol";

/// Whether `path` is a solution file (by its magic bytes) rather than a scene. Only a regular
/// file is probed: reading a pipe's first bytes would take them from the scene read next
/// (`check <(cat scene.toml)`), and a solution names its scene relative to its own folder,
/// which a pipe does not have.
pub(crate) fn is_solution_file(path: &Path) -> bool {
    use std::io::Read;
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return false;
    }
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .map(|_| &magic == solution_file::MAGIC)
        .unwrap_or(false)
}

/// Command-line choices of the texture methods (all optional; the scene's `[render]` gives the
/// defaults).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TextureOptions {
    /// One texture side for every polygon (`--texture-size`, a power of two).
    pub size: Option<u32>,
    /// A texture memory budget in bytes at 12 bits per channel with mip chains
    /// (`--texture-budget`).
    pub budget: Option<u64>,
    /// The bicubic filter's (B, C) (`--bicubic B,C`; default Mitchell–Netravali 1/3, 1/3).
    pub bicubic: Option<(f32, f32)>,
    /// Where the texels sit, by name (`--texel-placement centre|corner`), checked by
    /// [`TextureOptions::placement`] in the plan.
    pub placement: Option<String>,
}

impl TextureOptions {
    /// The size policy these options choose for `scene`, checked against it: a size (a power of
    /// two in range), a budget (at least what 1 x 1 textures of every polygon of the scene take),
    /// or the scene's `scene_texture_policy`. Giving both a size and a budget is an error.
    pub fn policy(&self, scene: &Scene) -> Result<SizePolicy> {
        let policy = match (self.size, self.budget) {
            (Some(n), Some(_)) => {
                return Err(Error::invalid_option(
                    "--texture-size",
                    n.to_string(),
                    "excludes --texture-budget; give one of them",
                ))
            }
            (Some(n), None) => {
                check_texture_side("--texture-size", n)?;
                SizePolicy::Fixed(n)
            }
            (None, Some(b)) => SizePolicy::Budget(b),
            (None, None) => scene_texture_policy(scene),
        };
        // Whether a budget can be met depends only on the polygon count (every texture can
        // shrink to 1 x 1), which the scene gives before any solve.
        TextureSet::sides(&vec![0; scene.polygons.len()], policy)?;
        Ok(policy)
    }

    /// The texel placement: `--texel-placement` if given (an unknown name is an
    /// [`Error::InvalidOption`] naming it), else the scene's `[render] texel_placement`.
    pub fn placement(&self, scene: &Scene) -> Result<Placement> {
        match &self.placement {
            Some(name) => Placement::parse_option("--texel-placement", name),
            None => Ok(scene.render.texel_placement),
        }
    }

    /// `method` with these options' bicubic parameters applied (checked).
    pub fn method(&self, method: Method) -> Result<Method> {
        match self.bicubic {
            Some((b, c)) => method.with_bicubic(b, c),
            None => Ok(method),
        }
    }
}

/// The texture size policy a scene asks for: `[render] texture_size` 0 means per polygon from
/// its quadtree depth, any other value one fixed size.
pub(crate) fn scene_texture_policy(scene: &Scene) -> SizePolicy {
    match scene.render.texture_size {
        0 => SizePolicy::FromDepth,
        n => SizePolicy::Fixed(n),
    }
}

/// A scene with its solution and reconstruction: everything a frame needs.
pub struct Prepared {
    /// The scene.
    pub scene: Scene,
    /// Its radiosity solution (solved now, or read from a file).
    pub solution: Solution,
    /// The RRPs of every polygon in compact form: what the direct method holds and evaluates.
    pub compact: CompactReconstruction,
    /// Time spent solving in this run (0 when read from a file), ms.
    pub solve_ms: f64,
    /// Time spent building the compact RRPs, ms.
    pub reconstruction_ms: f64,
    /// The derivative estimator the RRPs (compact and expanded) are built with.
    pub estimator: Estimator,
    /// The polygon borders the RRPs (compact and expanded) are joined along ([`seams_of`]).
    pub seams: Seams,
    /// Levels below the solver's leaves the RRPs follow the spots' edges ([`Input::sharp_levels`]).
    pub sharp_levels: u32,
    /// How the texture methods size their textures (fixed by [`prepare`]).
    texture_policy: SizePolicy,
    /// Where the texture methods place their texels (fixed by [`prepare`]).
    texture_placement: Placement,
    /// The memory limit the lazily built textures and mesh are checked against.
    memory_limit: u64,
    /// The solution file the solution was read from (`None`: solved in this run).
    pub solution_file: Option<PathBuf>,
    expanded: OnceLock<(Reconstruction, f64)>,
    textures: OnceLock<(TextureSet, f64)>,
    mesh: OnceLock<(MeshModel, f64)>,
}

impl Prepared {
    /// How the texture methods size their textures.
    pub fn texture_policy(&self) -> SizePolicy {
        self.texture_policy
    }

    /// Where the texture methods place their texels.
    pub fn texture_placement(&self) -> Placement {
        self.texture_placement
    }

    /// Whose fault [`Error::Inconsistent`] data of a later stage is: read from a solution file
    /// (a value no solve would produce behind a valid checksum), the file's, an
    /// [`Error::Solution`] ([`base::error::SolutionProblem::Corrupt`], exit 2); computed by this
    /// run's own solve, this program's, an [`Error::Internal`]. Every other error passes through
    /// as it is (an internal error stays one, whatever was read).
    fn file_error(&self, e: Error) -> Error {
        match (e, &self.solution_file) {
            (Error::Inconsistent(m), Some(path)) => Error::solution(
                path,
                base::error::SolutionProblem::Corrupt,
                format!("corrupt solution file: {m}"),
            ),
            (Error::Inconsistent(m), None) => {
                Error::internal(format!("this run's own solution is inconsistent: {m}"))
            }
            (e, _) => e,
        }
    }

    /// Bytes held before any method's data: the solution's trees and samples and the compact
    /// RRPs.
    pub(crate) fn held_bytes(&self) -> u64 {
        let st = &self.solution.stats;
        let nodes: u64 = self
            .solution
            .polygons
            .iter()
            .map(|p| p.tree.nodes().len() as u64)
            .sum();
        radiosity::sizes::state_bytes(nodes, st.vertices)
            .saturating_add(self.compact.stats().total_bytes as u64)
    }

    /// The RRPs with every patch expanded to power basis (unquantized vertex data), built on
    /// first use (the texture methods resample them; the direct method does not need them), with
    /// their build time in ms.
    pub fn expanded(&self) -> Result<(&Reconstruction, f64)> {
        if self.expanded.get().is_none() {
            let t = Instant::now();
            let spots = spot_light(&self.scene, &self.solution, self.sharp_levels)
                .map_err(|e| self.file_error(e))?;
            let r = Reconstruction::build_with(
                &self.solution.polygons,
                self.estimator,
                &self.seams,
                spots.as_ref().map(SpotLight::sharp),
            )
            .map_err(|e| self.file_error(e))?;
            let _ = self.expanded.set((r, t.elapsed().as_secs_f64() * 1e3));
        }
        let (r, ms) = self
            .expanded
            .get()
            .ok_or_else(|| Error::internal("expanded RRPs missing after build"))?;
        Ok((r, *ms))
    }

    /// The radiosity textures under [`Prepared::texture_policy`], built on first use (a scene
    /// rendered only with the direct method never pays for them), with their build time in ms.
    ///
    /// Refused with [`Error::Memory`] before anything is built when their estimate
    /// ([`budget::texture_bytes`]) and what is held already pass the job's memory limit.
    pub fn textures(&self) -> Result<(&TextureSet, f64)> {
        if self.textures.get().is_none() {
            let depths =
                TextureSet::depths(&self.solution.polygons, self.scene.radiosity.max_depth);
            let cs = self.compact.stats();
            let mut e = budget::Estimate::new(
                "the radiosity textures",
                "lower --texture-size or [render] texture_size, give --texture-budget, or \
                 raise --memory-limit",
            );
            e.add("held", self.held_bytes()).add(
                "textures and expanded RRPs",
                budget::texture_bytes(
                    &depths,
                    self.texture_policy,
                    cs.leaves as u64,
                    cs.nodes as u64,
                )?,
            );
            e.check(self.memory_limit)?;
            let t = Instant::now();
            let set = TextureSet::build(
                self.expanded()?.0,
                &depths,
                self.texture_policy,
                self.texture_placement,
            )
            .map_err(|e| self.file_error(e))?;
            let _ = self.textures.set((set, t.elapsed().as_secs_f64() * 1e3));
        }
        let (set, ms) = self
            .textures
            .get()
            .ok_or_else(|| Error::internal("texture set missing after build"))?;
        Ok((set, *ms))
    }

    /// The Gouraud mesh of the solution (T-vertex fans), built on first use, with its build
    /// time in ms.
    ///
    /// Refused with [`Error::Memory`] before it is built when its estimate
    /// (`budget::mesh_bytes`) and what is held already pass the job's memory limit.
    pub fn mesh(&self) -> Result<(&MeshModel, f64)> {
        if self.mesh.get().is_none() {
            let st = &self.solution.stats;
            let mut e = budget::Estimate::new(
                "the Gouraud mesh",
                "raise radiosity.tolerance or lower radiosity.max_depth, or raise --memory-limit",
            );
            e.add("held", self.held_bytes())
                .add("mesh", budget::mesh_bytes(st.elements, st.t_vertices));
            e.check(self.memory_limit)?;
            let t = Instant::now();
            let mesh = MeshModel::build_with(&self.scene, &self.solution.polygons, &self.seams)
                .map_err(|e| self.file_error(e))?;
            let _ = self.mesh.set((mesh, t.elapsed().as_secs_f64() * 1e3));
        }
        let (mesh, ms) = self
            .mesh
            .get()
            .ok_or_else(|| Error::internal("mesh missing after build"))?;
        Ok((mesh, *ms))
    }
}

/// Solves the input's scene (or reads its solution file) and builds the reconstruction; the
/// textures will be sized by `texture_policy` and their texels placed by `texture_placement`.
/// This is where a job's work starts: plan and validate before calling it.
pub fn prepare(
    ctx: &Context<'_>,
    input: Input,
    texture_policy: SizePolicy,
    texture_placement: Placement,
) -> Result<Prepared> {
    prepare_progressively(ctx, input, texture_policy, texture_placement, None)
}

/// [`prepare`], handing every snapshot of the solve ([`SolveOptions::snapshots`]) to
/// `snapshots` reconstructed as the final solution will be (a solution read from a file has
/// none): what a viewer draws while the solve runs. A snapshot that cannot be reconstructed
/// is skipped (the final solution reports the error).
pub fn prepare_progressively(
    ctx: &Context<'_>,
    input: Input,
    texture_policy: SizePolicy,
    texture_placement: Placement,
    snapshots: Option<&(dyn Fn(Prepared) + Sync)>,
) -> Result<Prepared> {
    let Input {
        scene,
        solution_file: file,
        estimator,
        sharp_levels,
        ..
    } = input;
    let recipe = Recipe {
        texture_policy,
        texture_placement,
        memory_limit: ctx.memory_limit,
        estimator,
        sharp_levels,
    };
    let seams = seams_of(&scene);
    let (solution, stored, solve_ms) = match &file {
        Some(path) => {
            let (solution, rrps) = solution_file::read_solution(path, &scene)?;
            (solution, Some((path.as_path(), rrps)), 0.0)
        }
        None => {
            let t = Instant::now();
            let solution = solve_sending(ctx, &scene, &seams, recipe, snapshots)?;
            (solution, None, t.elapsed().as_secs_f64() * 1e3)
        }
    };
    let t = Instant::now();
    let compact = compact_of(&scene, &solution, stored, recipe, &seams)?;
    let reconstruction_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut p = recipe.prepared(
        scene,
        seams,
        solution,
        compact,
        (solve_ms, reconstruction_ms),
    );
    p.solution_file = file;
    Ok(p)
}

/// What every [`Prepared`] of one job holds beside its scene, solution and RRPs.
#[derive(Clone, Copy)]
struct Recipe {
    texture_policy: SizePolicy,
    texture_placement: Placement,
    memory_limit: u64,
    estimator: Estimator,
    sharp_levels: u32,
}

impl Recipe {
    /// A prepared solution solved in this run, `(solve, reconstruction)` its times in ms.
    fn prepared(
        self,
        scene: Scene,
        seams: Seams,
        solution: Solution,
        compact: CompactReconstruction,
        (solve_ms, reconstruction_ms): (f64, f64),
    ) -> Prepared {
        Prepared {
            solution_file: None,
            texture_policy: self.texture_policy,
            texture_placement: self.texture_placement,
            memory_limit: self.memory_limit,
            scene,
            solution,
            compact,
            solve_ms,
            reconstruction_ms,
            estimator: self.estimator,
            seams,
            sharp_levels: self.sharp_levels,
            expanded: OnceLock::new(),
            textures: OnceLock::new(),
            mesh: OnceLock::new(),
        }
    }
}

/// Solves `scene` under the job's memory limit, handing each snapshot of the solve to
/// `snapshots` reconstructed as `recipe` says (a snapshot that cannot be reconstructed is
/// skipped: the final solution reports the error).
fn solve_sending(
    ctx: &Context<'_>,
    scene: &Scene,
    seams: &Seams,
    recipe: Recipe,
    snapshots: Option<&(dyn Fn(Prepared) + Sync)>,
) -> Result<Solution> {
    budget::check_solve(scene, ctx.memory_limit)?;
    let snapshot = snapshots.map(|send| {
        move |solution: Solution| {
            let t = Instant::now();
            let Recipe {
                estimator,
                sharp_levels,
                ..
            } = recipe;
            let Ok(compact) = reconstruct(scene, &solution, estimator, sharp_levels, seams) else {
                return;
            };
            let times = (solution.stats.solve_ms, t.elapsed().as_secs_f64() * 1e3);
            send(recipe.prepared(scene.clone(), seams.clone(), solution, compact, times))
        }
    });
    radiosity::solve(
        scene,
        &SolveOptions {
            observer: ctx.observer,
            memory_limit: budget::data_limit(ctx.memory_limit),
            snapshots: snapshot.as_ref().map(|f| f as &(dyn Fn(Solution) + Sync)),
        },
    )
}

/// The compact RRPs of `solution`. A solution file stores the compact RRPs its solve built
/// with the default estimator and sharp levels (`stored`: the file and its RRPs): they are
/// decoded (checked) instead of built again; a file without them, other settings or a fresh
/// solve builds them from the samples.
fn compact_of(
    scene: &Scene,
    solution: &Solution,
    stored: Option<(&Path, Vec<u8>)>,
    recipe: Recipe,
    seams: &Seams,
) -> Result<CompactReconstruction> {
    let defaults = recipe.estimator == Estimator::default()
        && recipe.sharp_levels == reconstruction::sharp::DEFAULT_LEVELS;
    let build = || {
        reconstruct(
            scene,
            solution,
            recipe.estimator,
            recipe.sharp_levels,
            seams,
        )
    };
    match stored {
        Some((path, rrps)) if !rrps.is_empty() && defaults => {
            let corrupt = |m: String| {
                Error::solution(
                    path,
                    base::error::SolutionProblem::Corrupt,
                    format!("corrupt solution file: its RRPs: {m}"),
                )
            };
            let c = CompactReconstruction::decode(&rrps).map_err(|e| corrupt(e.to_string()))?;
            if c.polygon_count() != scene.polygons.len() {
                return Err(corrupt(format!(
                    "{} polygons, the scene has {}",
                    c.polygon_count(),
                    scene.polygons.len()
                )));
            }
            Ok(c)
        }
        // Samples read from a file that cannot be reconstructed (values so large the patches
        // overflow f32) are a bad file, exit 2, like any other inconsistency behind a valid
        // checksum; from a fresh solve they are a failure of this program.
        Some((path, _)) => build().map_err(|e| match e {
            Error::Inconsistent(m) => Error::solution(
                path,
                base::error::SolutionProblem::Corrupt,
                format!("corrupt solution file: its samples cannot be reconstructed: {m}"),
            ),
            e => e,
        }),
        None => build().map_err(|e| match e {
            Error::Inconsistent(m) => {
                Error::internal(format!("this run's own solution is inconsistent: {m}"))
            }
            e => e,
        }),
    }
}

/// The compact RRPs of `solution` on `scene` with `estimator`, following the spots' edges
/// `sharp_levels` below the leaves, joined along `seams`.
fn reconstruct(
    scene: &Scene,
    solution: &Solution,
    estimator: Estimator,
    sharp_levels: u32,
    seams: &Seams,
) -> Result<CompactReconstruction> {
    let spots = spot_light(scene, solution, sharp_levels)?;
    let sharp = spots.as_ref().map(SpotLight::sharp);
    CompactReconstruction::build_with(&solution.polygons, estimator, seams, sharp)
}

/// The seams every reconstruction of `scene` joins: the shared edges of coplanar polygons of one
/// material ([`scene::adjacency`], [`reconstruction::seam`]).
pub fn seams_of(scene: &Scene) -> Seams {
    let adjacency = scene.adjacency();
    Seams::of(&scene.polygons, &scene.materials, &adjacency)
}

/// The spot lights of a scene as sharp light for its RRPs ([`reconstruction::sharp`]): their
/// part of the solution, known exactly at any point ([`radiosity::SpotParts`]).
pub struct SpotLight<'a> {
    parts: radiosity::SpotParts<'a>,
    levels: u32,
}

impl SpotLight<'_> {
    /// The light and its levels as the reconstruction takes them.
    pub fn sharp(&self) -> Sharp<'_> {
        Sharp {
            light: self,
            levels: self.levels,
        }
    }
}

impl SharpLight for SpotLight<'_> {
    fn terms(&self, polygon: usize) -> Vec<u32> {
        self.parts.reaching(polygon)
    }

    fn part(&self, polygon: usize, term: u32, u: f64, v: f64) -> Option<[f64; 3]> {
        self.parts.part(polygon, term, u, v).map(|p| p.to_array())
    }

    fn smooth(&self, polygon: usize, term: u32, u: f64, v: f64) -> [f64; 3] {
        self.parts.smooth(polygon, term, u, v).to_array()
    }
}

/// The sharp light of `scene`'s spots under `solution` with `levels` ([`Input::sharp_levels`]);
/// `None` (nothing to follow, nothing built) for a scene without spots or with `levels` 0.
pub fn spot_light<'a>(
    scene: &'a Scene,
    solution: &Solution,
    levels: u32,
) -> Result<Option<SpotLight<'a>>> {
    if scene.spots.is_empty() || levels == 0 {
        return Ok(None);
    }
    Ok(Some(SpotLight {
        parts: radiosity::SpotParts::new(solution, scene)?,
        levels,
    }))
}

/// Loads `path`, checks `texture`'s options against its scene, then solves and reconstructs:
/// [`Input::load`], [`TextureOptions::policy`] and [`prepare`] in one call.
pub fn prepare_path(ctx: &Context<'_>, path: &Path, texture: &TextureOptions) -> Result<Prepared> {
    let input = Input::load(path)?;
    let policy = texture.policy(&input.scene)?;
    let placement = texture.placement(&input.scene)?;
    prepare(ctx, input, policy, placement)
}

/// A frame's pixels as an image (to measure it).
pub(crate) fn frame_image(f: engine::frame::Frame) -> Result<crate::image::LinearImage> {
    crate::image::LinearImage::new(f.width, f.height, f.pixels)
}

/// Renders one frame of a prepared scene with `method`, in a new frame context (a cold frame;
/// [`render_frame_in`] reuses one).
pub fn render_frame(
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
) -> Result<engine::frame::Frame> {
    let mut ctx = engine::frame::FrameContext::new();
    let stats = render_frame_in(&mut ctx, p, method, camera, opts)?;
    Ok(ctx.into_frame(stats))
}

/// The stage a reference frame reports (every sample of it is a gather from the whole solution:
/// tens of seconds a frame where the other methods take milliseconds).
pub const REFERENCE_STAGE: &str = "reference";

/// [`render_frame`] with progress to `observer`: a reference frame runs as stage
/// [`REFERENCE_STAGE`] ([`render_frame_in_observed`]); the pixels are the same for any observer.
pub fn render_frame_observed(
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
    observer: &dyn Observer,
) -> Result<engine::frame::Frame> {
    let mut ctx = engine::frame::FrameContext::new();
    let stats = render_frame_in_observed(&mut ctx, p, method, camera, opts, observer)?;
    Ok(ctx.into_frame(stats))
}

/// [`render_frame_in`] with progress to `observer`. A reference frame reports stage
/// [`REFERENCE_STAGE`]: the fraction of its samples evaluated, out of the samples a first pass
/// with a shader that evaluates nothing counted (rasterization and composition only,
/// milliseconds; every pixel it wrote is written again). Other methods report nothing (a frame
/// takes milliseconds). The pixels and counters are those of [`render_frame_in`].
pub fn render_frame_in_observed(
    ctx: &mut engine::frame::FrameContext,
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
    observer: &dyn Observer,
) -> Result<engine::frame::FrameStats> {
    use engine::shading::Shader;
    use std::sync::atomic::{AtomicU64, Ordering};
    if method != Method::Reference {
        return render_frame_in(ctx, p, method, camera, opts);
    }
    let stage = std::sync::Mutex::new(Stage::start(observer, REFERENCE_STAGE));
    let oracle = radiosity::Oracle::new(&p.solution, &p.scene).map_err(|e| p.file_error(e))?;
    let nothing = |_: u32, _: f32, _: f32| glam::Vec3::ZERO;
    let total = ctx
        .render(&p.scene, camera, &Shader::Reference(&nothing), method, opts)?
        .pixels_shaded
        .max(1);
    // About a thousand reports a frame; a worker that finds the stage busy skips its report.
    let step = (total / 1000).max(1);
    let done = AtomicU64::new(0);
    let f = |poly: u32, u: f32, v: f32| {
        let c = oracle.radiosity(poly as usize, u as f64, v as f64);
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        if n.is_multiple_of(step) {
            if let Ok(mut s) = stage.try_lock() {
                s.advance(n as f64 / total as f64);
            }
        }
        c
    };
    let stats = ctx.render(&p.scene, camera, &Shader::Reference(&f), method, opts)?;
    if let Ok(mut s) = stage.lock() {
        s.advance(1.0);
    }
    Ok(stats)
}

/// Builds, once per job, what `method` draws from (the textures, the mesh), so that neither a
/// reservation nor a frame timed after it pays for that.
pub(crate) fn build_method_data(p: &Prepared, method: Method) -> Result<()> {
    match method {
        Method::Texture(_) => p.textures().map(|_| ()),
        Method::Mesh => p.mesh().map(|_| ()),
        Method::Direct | Method::Reference => Ok(()),
    }
}

/// Reserves in `ctx` what frames of `method` at `opts` need ([`engine::frame::FrameContext::reserve_scene`]
/// with the scene `method` draws: the mesh's triangles for the mesh method; for the direct method
/// also every worker's patch cache, [`engine::frame::FrameContext::reserve_source`]).
pub fn reserve_frames(
    ctx: &mut engine::frame::FrameContext,
    p: &Prepared,
    method: Method,
    opts: &engine::frame::FrameOptions,
) -> Result<()> {
    match method {
        Method::Mesh => ctx.reserve_scene(opts, &p.mesh()?.0.scene),
        Method::Direct => {
            ctx.reserve_scene(opts, &p.scene)?;
            ctx.reserve_source(&p.compact);
            Ok(())
        }
        _ => ctx.reserve_scene(opts, &p.scene),
    }
}

/// Renders one frame of a prepared scene with `method` into `ctx` (its pixels:
/// [`engine::frame::FrameContext::view`]), reusing the context's buffers.
pub fn render_frame_in(
    ctx: &mut engine::frame::FrameContext,
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
) -> Result<engine::frame::FrameStats> {
    use engine::shading::Shader;
    match method {
        Method::Direct => ctx.render(&p.scene, camera, &Shader::Patches(&p.compact), method, opts),
        Method::Texture(filter) => {
            let (set, _) = p.textures()?;
            ctx.render(
                &p.scene,
                camera,
                &Shader::Texture { set, filter },
                method,
                opts,
            )
        }
        Method::Mesh => {
            let (mesh, _) = p.mesh()?;
            ctx.render(&mesh.scene, camera, &Shader::Patches(mesh), method, opts)
        }
        Method::Reference => {
            let oracle =
                radiosity::Oracle::new(&p.solution, &p.scene).map_err(|e| p.file_error(e))?;
            let f = |poly: u32, u: f32, v: f32| oracle.radiosity(poly as usize, u as f64, v as f64);
            ctx.render(&p.scene, camera, &Shader::Reference(&f), method, opts)
        }
    }
}

#[cfg(test)]
mod reference_stage_tests {
    use super::*;
    use base::progress::{Event, Recorder};

    /// A reference frame reports its own stage, from 0 to 1 then finished, and its pixels are
    /// those of the unobserved frame, bit for bit.
    #[test]
    fn the_reference_method_reports_a_stage() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/two-spots.toml");
        let mut input = Input::load(&path).expect("scene loads");
        input.scene.radiosity.max_depth = input.scene.radiosity.min_depth.max(3);
        input.scene.radiosity.shadow_rays = 4;
        let p = prepare(
            &Context::default(),
            input,
            SizePolicy::FromDepth,
            Placement::Centre,
        )
        .expect("solves");
        let opts = Context::default().frame_options(48, 32);
        let r = Recorder::default();
        let seen = render_frame_observed(&p, Method::Reference, &p.scene.camera, &opts, &r)
            .expect("renders");
        let plain = render_frame(&p, Method::Reference, &p.scene.camera, &opts).expect("renders");
        let bits = |f: &engine::frame::Frame| -> Vec<u32> {
            f.pixels
                .iter()
                .flat_map(|c| c.to_array().map(f32::to_bits))
                .collect()
        };
        assert!(
            bits(&seen) == bits(&plain),
            "the observer changed the pixels"
        );
        let events = r.events();
        assert_eq!(
            events.first(),
            Some(&Event::Progress(REFERENCE_STAGE.into(), 0.0))
        );
        assert_eq!(
            events.last(),
            Some(&Event::Finished(REFERENCE_STAGE.into()))
        );
        let fractions: Vec<f64> = events
            .iter()
            .filter_map(|e| match e {
                Event::Progress(s, f) if s == REFERENCE_STAGE => Some(*f),
                _ => None,
            })
            .collect();
        assert_eq!(fractions.last(), Some(&1.0));
        assert!(fractions.windows(2).all(|w| w[0] <= w[1]), "{fractions:?}");
        // Other methods take milliseconds and report nothing.
        let direct = Recorder::default();
        render_frame_observed(&p, Method::Direct, &p.scene.camera, &opts, &direct)
            .expect("renders");
        assert!(direct.events().is_empty());
    }
}
