//! A scene made ready to draw: [`prepare`] solves it (or reads its solution file) and builds the
//! RRPs in compact form (what the direct method evaluates: quantized vertex data, each patch
//! expanded when a screen region first needs it). The expanded patches (which the texture methods
//! resample), the textures and the mesh are built lazily on first use, so a job that only draws
//! `direct` never pays for them. [`prepare_progressively`] does the same while handing the
//! solve's snapshots to a viewer.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Instant;

use base::error::{Error, Result};
use base::method::Placement;
use radiosity::{self, file as solution_file, Solution, SolveOptions};
use reconstruction::compact::CompactReconstruction;
use reconstruction::mesh::MeshModel;
use reconstruction::texture::{Extent, SizePolicy, TextureSet};
use reconstruction::{Estimator, Reconstruction, Seams, Sharp, SharpLight};
use scene::Scene;

use crate::budget;
use crate::context::{Context, Input, TextureOptions};

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
    pub(crate) fn file_error(&self, e: Error) -> Error {
        blame(e, self.solution_file.as_deref(), "")
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

    /// What every polygon's texture size is chosen from: its quadtree depth capped at the
    /// scene's `radiosity.max_depth`, and its aspect ([`TextureSet::extents`]).
    pub fn texture_extents(&self) -> Result<Vec<Extent>> {
        TextureSet::extents(
            &self.solution.polygons,
            &self.scene.polygons,
            self.scene.radiosity.max_depth,
        )
        .map_err(|e| self.file_error(e))
    }

    /// The radiosity textures under [`Prepared::texture_policy`], built on first use (a scene
    /// rendered only with the direct method never pays for them), with their build time in ms.
    ///
    /// Refused with [`Error::Memory`] before anything is built when their estimate
    /// ([`budget::texture_bytes`]) and what is held already pass the job's memory limit.
    pub fn textures(&self) -> Result<(&TextureSet, f64)> {
        if self.textures.get().is_none() {
            let extents = self.texture_extents()?;
            let cs = self.compact.stats();
            let mut e = budget::Estimate::new(
                "the radiosity textures",
                "lower `texture-size` or [render] texture_size, give `texture-budget`, or \
                 raise `memory-limit`",
            );
            e.add("held", self.held_bytes()).add(
                "textures and expanded RRPs",
                budget::texture_bytes(
                    &extents,
                    self.texture_policy,
                    cs.leaves as u64,
                    cs.nodes as u64,
                )?,
            );
            e.check(self.memory_limit)?;
            let t = Instant::now();
            let set = TextureSet::build(
                self.expanded()?.0,
                &extents,
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
    /// time in ms. With the spots' sharp light ([`Input::sharp_levels`] above 0, a scene with
    /// spots) its vertices follow the spots' edges as the patches do
    /// ([`reconstruction::sharp::followed_samples`]), so every method draws the same data.
    ///
    /// Refused with [`Error::Memory`] before it is built when its estimate
    /// (`budget::mesh_bytes`) and what is held already pass the job's memory limit.
    pub fn mesh(&self) -> Result<(&MeshModel, f64)> {
        if self.mesh.get().is_none() {
            let t = Instant::now();
            let spots = spot_light(&self.scene, &self.solution, self.sharp_levels)
                .map_err(|e| self.file_error(e))?;
            let followed = spots.as_ref().map(|s| {
                reconstruction::sharp::followed_samples(&self.solution.polygons, s.sharp())
            });
            let polygons = followed.as_deref().unwrap_or(&self.solution.polygons);
            let (leaves, t_vertices) = match &followed {
                Some(f) => f.iter().fold((0u64, 0u64), |(l, tv), sq| {
                    let t = &sq.tree;
                    (l + t.leaf_count() as u64, tv + t.t_vertices().len() as u64)
                }),
                None => (self.solution.stats.elements, self.solution.stats.t_vertices),
            };
            let mut e = budget::Estimate::new(
                "the Gouraud mesh",
                "raise radiosity.tolerance or lower radiosity.max_depth, or raise `memory-limit`",
            );
            e.add("held", self.held_bytes())
                .add("mesh", budget::mesh_bytes(leaves, t_vertices));
            e.check(self.memory_limit)?;
            let mesh = MeshModel::build_with(&self.scene, polygons, &self.seams)
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
        input_limit,
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
    let (solution, from_file, solve_ms) = match &file {
        Some(path) => {
            let solution = solution_file::read_solution_up_to(path, &scene, input_limit)?;
            (solution, Some(path.as_path()), 0.0)
        }
        None => {
            let t = Instant::now();
            let solution = solve_sending(ctx, &scene, &seams, recipe, snapshots)?;
            (solution, None, t.elapsed().as_secs_f64() * 1e3)
        }
    };
    let t = Instant::now();
    let compact = compact_of(&scene, &solution, from_file, recipe, &seams)?;
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

/// The compact RRPs of `solution`, read from the file `file` or solved in this run: built from
/// its samples either way (a solution file stores no RRPs), so both draw the same images.
fn compact_of(
    scene: &Scene,
    solution: &Solution,
    file: Option<&Path>,
    recipe: Recipe,
    seams: &Seams,
) -> Result<CompactReconstruction> {
    // Samples read from a file that cannot be reconstructed (values so large the patches
    // overflow f32) are a bad file, exit 2, like any other inconsistency behind a valid
    // checksum; from a fresh solve they are a failure of this program.
    reconstruct(
        scene,
        solution,
        recipe.estimator,
        recipe.sharp_levels,
        seams,
    )
    .map_err(|e| blame(e, file, "its samples cannot be reconstructed: "))
}

/// [`Prepared::file_error`] for a solution read from `file` (or solved in this run), the
/// message of a corrupt file starting with `what`.
fn blame(e: Error, file: Option<&Path>, what: &str) -> Error {
    match (e, file) {
        (Error::Inconsistent(m), Some(path)) => Error::solution(
            path,
            base::error::SolutionProblem::Corrupt,
            format!("corrupt solution file: {what}{m}"),
        ),
        (Error::Inconsistent(m), None) => {
            Error::internal(format!("this run's own solution is inconsistent: {m}"))
        }
        (e, _) => e,
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
/// material ([`scene::adjacency`], [`reconstruction::seam`]), but not those along the lines the
/// loader cut because the light steps there ([`Seams::of_scene`]).
pub fn seams_of(scene: &Scene) -> Seams {
    Seams::of_scene(scene)
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
