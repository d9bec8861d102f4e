//! Radiosity: the second stage a frame passes through. It turns a [`Scene`] into a [`Solution`]:
//! for every polygon an unrestricted, adaptively subdivided quadtree over its (u, v) domain with a
//! true RGB radiosity sample at every leaf vertex, T-vertices included. The reconstruction stage
//! reads these samples; nothing downstream ever sees an interpolated value.
//!
//! The solve is progressive refinement (`shoot`) with exact point-to-polygon form factors
//! (`formfactor`) and shadow rays through the scene's BVH, each weighted by the form-factor
//! kernel; a reflecting patch's light is distributed over it by its shape, measured from the
//! solution's own samples (`transfer::shape`); the light transfer itself lives in one
//! function (`transfer`) shared with the [`Oracle`], which answers the radiosity at any point
//! from the converged history (per-shooter totals). Because a vertex's stored value is computed by
//! the oracle's own gather, `Solution::radiosity` at a vertex returns the stored sample bit for
//! bit. Solutions are saved and loaded by [`file`](mod@file).
//!
//! **Scale.** Every cost of the solve grows with what a shooter or a point can see, not with the
//! scene: each shooter's receivers are found once, as a sparse table with an index per
//! receiver (`transfer`); a shot touches its receivers, a gather the shooters that reach its
//! point, and the next shooter comes from a tournament tree (`shoot`). Receivers are found by
//! testing every polygon for scenes of up to about 1,000 polygons (`exact` visibility) and by
//! probe rays beyond (`sampled`, [`scene::Visibility`]). Why this method, by measurement: on a
//! building of 4 x 4 rooms (2,320 polygons) a solver that classifies and keeps every pair and
//! gathers over every shooter spends 57 s, 34 s of it in gathers, and 1.94 M of its 2.08 M
//! unculled pairs are pairs in different rooms whose every shadow ray a wall stops: the cost is
//! interactions that carry no light, not the many weak ones that hierarchical radiosity with
//! clustering (Hanrahan, Salzman and Aupperle 1991; Smits, Arvo and Greenberg 1994)
//! approximates. Dropping them keeps what this solver is built on: exact point-to-polygon form
//! factors and an [`Oracle`] whose answer at a vertex is the stored sample, bit for bit (links
//! and push-pull would make a stored value something the reference renderer cannot recompute).
//! Proving a pair blocked by one occluder (coplanar wall pieces merged) would not do: a closed
//! room is hidden by the union of its walls, never by one plane, so it would keep most pairs
//! between rooms. Probe rays lose the light of receivers they miss; measured, it moves a
//! building's images less than a change of seed does (docs/performance.md).
//!
//! Invariants: values are linear RGB radiosity (emission included), finite and >= 0 (any
//! non-finite value would be a bug; [`sanitize`] maps it to 0 rather than let it reach an image);
//! the solution depends only on the scene (fixed seeds, fixed reduction order), not on the number
//! of threads of the caller's rayon pool nor on the [`Observer`] the caller passes in
//! [`SolveOptions`], which receives the solve's progress (stage `STAGE`) and, when it asks for
//! them, the solver's trace lines (phase times, shots, vertices, unshot fraction).

#![forbid(unsafe_code)]

mod faces;
pub mod file;
mod formfactor;
mod shoot;
mod spots;
#[cfg(test)]
pub(crate) mod test_scenes;
mod transfer;
mod visible;

/// What the solve's data structures take, for estimating a solve's memory before it starts (the
/// jobs' budget): bytes per tree node, vertex and pair, the coarse transfers' cache, and the
/// depths a solve starts at and can reach.
pub mod sizes {
    pub use crate::shoot::{
        depth_bound, min_element_size, state_bytes, COARSE_CACHE_ENTRIES, DIVE_NODES,
        SHADOW_EDGE_LEVELS,
    };
    pub use crate::transfer::{pair_table_bound, patch_depth, EDGE_INSET, PAIR_BYTES};
}

use std::time::Instant;

use glam::{DVec3, Vec3};

use base::error::{Error, Location, Result};
use base::progress::{Observer, Stage, SILENT};
use base::quadtree::{SampledQuadtree, MAX_DEPTH};
pub use faces::{face_means, FaceMean};
use scene::Scene;
pub use spots::SpotParts;
pub use transfer::shape::PatchShape;
pub use transfer::ShooterKind;
use transfer::Transfer;

/// The stage name under which [`solve`] reports progress. Its fraction is the solve's distance
/// to convergence on a log scale: -ln(unshot fraction) / -ln(`convergence`).
pub const STAGE: &str = "solve";

/// Options of one solve that are not part of the scene. None of them changes the solution.
#[derive(Clone, Copy)]
pub struct SolveOptions<'a> {
    /// Receives the progress of stage `STAGE` and, if it asks for them, trace lines.
    pub observer: &'a dyn Observer,
    /// Bytes the solve's state may hold (quadtrees, samples, pair tables; see
    /// [`shoot::state_bytes`]): a refinement pass that would pass it ends the solve with
    /// [`Error::Memory`]. It never changes a solution that fits.
    pub memory_limit: u64,
    /// Receives the solution so far each time every sample holds the light of the history
    /// so far: after the direct light and its refinement, then after every indirect round but
    /// the last (the solve returns that one). Progressive radiosity's promise, a usable
    /// picture early that refines while one looks: the viewer draws each as it comes. A
    /// snapshot's energy account is empty; sending one changes nothing in the solve.
    pub snapshots: Option<&'a (dyn Fn(Solution) + Sync)>,
}

impl Default for SolveOptions<'_> {
    /// Silent, no memory limit.
    fn default() -> Self {
        SolveOptions {
            observer: &SILENT,
            memory_limit: u64::MAX,
            snapshots: None,
        }
    }
}

impl std::fmt::Debug for SolveOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SolveOptions")
            .field("tracing", &self.observer.tracing())
            .field("memory_limit", &self.memory_limit)
            .finish_non_exhaustive()
    }
}

/// One shooter of the history: what it is and the total radiosity it shot.
#[derive(Debug, Clone, PartialEq)]
pub struct Shooter {
    /// Spot, emitter or reflecting patch.
    pub kind: ShooterKind,
    /// Total radiosity shot (W/m^2 per channel). For a spot light: 1 once it has shot (its
    /// intensity is in the scene), 0 otherwise.
    pub total: DVec3,
    /// For a reflecting patch, how its light is distributed over it (`None`: uniform).
    pub shape: Option<PatchShape>,
}

/// Statistics of a solve.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SolveStats {
    /// Leaves of all quadtrees (the elements).
    pub elements: u64,
    /// Stored samples (vertices of all quadtrees).
    pub vertices: u64,
    /// Vertices that lie inside an edge of a neighbouring, larger leaf.
    pub t_vertices: u64,
    /// Number of leaves per depth, over all polygons.
    pub depth_histogram: Vec<u64>,
    /// Shots taken (spots, emitters and patches; a patch may shoot more than once).
    pub shots: u64,
    /// Shadow rays cast during the solve (including the final gather). A statistic of the run,
    /// like `solve_ms`: fewer where a gather reuses the geometry kept from an earlier one
    /// (`transfer::seen`), whose room follows the memory limit; not stored
    /// in solution files (0 in one read from a file).
    pub rays_cast: u64,
    /// Shots taken before each refinement pass (one entry per pass). A pass re-estimates the
    /// unshot power from more samples, so `unshot_history` may rise right after it (new samples
    /// can reveal light the coarser vertices missed); between passes it never rises.
    pub refined_after: Vec<u64>,
    /// Emitted power, summed over channels (W).
    pub emitted_power: f64,
    /// Unshot power over emitted power at the end, in the channel where that ratio is largest
    /// (convergence is judged per channel).
    pub unshot_fraction: f64,
    /// Unshot fraction (largest channel) after every shot, in shot order.
    pub unshot_history: Vec<f64>,
    /// Where the emitted power went (see [`EnergyAccount`]).
    pub energy: EnergyAccount,
    /// Leaves the refinement split to the depth or size guard while the error test still
    /// failed at them (see [`GuardStops`]).
    pub guard_stops: GuardStops,
    /// Wall-clock solve time in milliseconds. Not saved in solution files (it would make two
    /// solves of one scene differ); 0 for a solution read from a file.
    pub solve_ms: f64,
}

/// Where refinement stopped at a guard (`radiosity.max_depth`, or the smallest element the
/// scene's size allows, [`shoot::min_element_size`], or the nodes a polygon may hold past
/// them, [`shoot::DIVE_NODES`]) while the error test still failed: each
/// leaf that split although its children may not split again counts once. A leaf whose light
/// deviates from the bilinear prediction counts in `leaves`, with that deviation over the
/// leaf's level as its excess: an estimate of the relative error its children keep (about a
/// quarter of it where the light is smooth, all of it at a spot's cone edge). A leaf failing
/// only because a shadow boundary crosses it counts in `shadow_leaves`: a boundary is a step at
/// any depth, so those leaves reach the guard by design.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GuardStops {
    /// Leaves split to the guard with their light still failing the error test (off the
    /// bilinear prediction, or an extremum between their samples).
    pub leaves: u64,
    /// The polygon with the largest excess.
    pub worst_polygon: u32,
    /// That excess: the estimated error relative to the leaf's level.
    pub worst_excess: f64,
    /// Leaves split to the guard only for a shadow boundary crossing them.
    pub shadow_leaves: u64,
    /// Leaves split to the guard with the error test failing where a spot's cone edge crosses
    /// them: a step at any depth, which the reconstruction draws exactly from the spot's own
    /// light ([`SpotParts`]); not in `leaves`, nor in the light they may misplace.
    pub edge_leaves: u64,
    /// The light the stopped leaves may still misplace, summed over them, in luminance watts:
    /// a quarter of each one's excess (what its children keep where the light is smooth)
    /// times its level (the luminance of rho G) times its area; an estimate, checked against
    /// a deeper solve on the gallery (`KEPT_SHARE` in the refinement).
    pub error_power: f64,
    /// The light the scene's surfaces reflect (the luminance of rho G integrated over every
    /// polygon), what [`GuardStops::error_power`] is judged against.
    pub reflected_power: f64,
}

/// A solve whose energy account lost more than this share of the emitted power (in a channel)
/// beyond what escaped lost light it should not have: `solve` and `render` warn. Looser than
/// [`ENERGY_ERROR_WARN`], the bound on light created: the solve's quadrature of the receivers'
/// light and the patches' shapes applied only where they matter lose up to 1 % on the shipped
/// scenes, and nothing in it creates light.
pub const ENERGY_LOSS_WARN: f64 = 0.02;

impl SolveStats {
    /// The warnings a solve's statistics give about its light (empty when all is well): its
    /// energy account created light (by more than [`ENERGY_ERROR_WARN`] of the emitted power)
    /// or lost it (by more than [`ENERGY_LOSS_WARN`]), and it stopped with more light unshot
    /// than `convergence` (the scene's `radiosity.convergence`) allows.
    pub fn light_warnings(&self, convergence: f64) -> Vec<String> {
        let mut out = Vec::new();
        let e = &self.energy;
        let error = e.error();
        if !(-ENERGY_ERROR_WARN..=ENERGY_LOSS_WARN).contains(&error) {
            let total = 1.0 - error;
            out.push(format!(
                "the solve's energy account does not balance: absorbed + unshot + escaped is \
                 {:.1} % of the emitted light ({} {:.1} %); {}",
                100.0 * total,
                if error < 0.0 { "created" } else { "lost" },
                100.0 * error.abs(),
                if error < 0.0 && self.guard_stops.leaves > 0 {
                    "elements too coarse for the light where refinement stopped at a guard \
                     (see the note on refinement: a polygon far larger than its light's detail \
                     needs splitting into smaller polygons), or light bouncing between \
                     surfaces closer than the solve resolves (a light facing a wall a few \
                     centimetres away); the solve's trace shows the account"
                } else if error < 0.0 {
                    "light bouncing between surfaces closer than the solve resolves (a light \
                     facing a wall a few centimetres away) is the usual cause; the solve's \
                     trace shows the account"
                } else {
                    "raise radiosity.max_depth or lower radiosity.tolerance"
                }
            ));
        }
        if self.unshot_fraction > convergence * (1.0 + 1e-9) {
            out.push(format!(
                "the solve stopped after {} rounds with {:.2} % of the light still unshot, more \
                 than radiosity.convergence ({:.2} %): the image is darker than the scene's \
                 light, by about that share; light trapped between close surfaces needs many \
                 bounces",
                self.refined_after.len().saturating_sub(1),
                100.0 * self.unshot_fraction,
                100.0 * convergence
            ));
        }
        out
    }
}

impl GuardStops {
    /// Where the worst leaf is: its polygon's file and line in `scene` (or its index).
    pub fn worst_origin(&self, scene: &Scene) -> String {
        let r = self.worst_polygon as usize;
        if r < scene.polygons.len() {
            scene.origin(r)
        } else {
            format!("polygon {r}")
        }
    }

    /// The warning a solve of `scene` that stopped at a guard where its light is still off
    /// the bilinear prediction gives (`None` if none did; shadow boundaries alone give none).
    pub fn warning(&self, scene: &Scene) -> Option<String> {
        let share = self.error_share();
        if self.leaves == 0 || share <= scene.radiosity.tolerance {
            return None;
        }
        let at = self.worst_origin(scene);
        let hint = match self.too_large(scene) {
            Some((longest, finest, detail)) => format!(
                "that polygon is {longest:.3e} long: its finest element (1/{} of it, \
                 {finest:.3e}) is coarser than its light varies ({detail:.3e}), whatever \
                 max_depth is; cut it into polygons under {:.3e} long",
                1u64 << MAX_DEPTH,
                detail * f64::from(1u32 << MAX_DEPTH)
            ),
            None => "raise radiosity.max_depth where memory allows".to_string(),
        };
        Some(format!(
            "refinement stopped at radiosity.max_depth = {} (or the smallest element, the \
             scene's size / 2^max_depth, or the {} nodes a polygon may hold past them) on {} \
             leaves whose light still fails the error test \
             (off the bilinear prediction, or peaking between samples), which may misplace up \
             to {:.1} % of the light the scene reflects (tolerance {:.1} %); worst at {at}: \
             {:.1} % of its level; {hint}",
            scene.radiosity.max_depth,
            shoot::DIVE_NODES,
            self.leaves,
            100.0 * share,
            100.0 * scene.radiosity.tolerance,
            100.0 * self.worst_excess,
        ))
    }

    /// [`GuardStops::error_power`] over [`GuardStops::reflected_power`]: the share of the
    /// scene's reflected light the stopped leaves may misplace (infinite when they hold light
    /// in a scene that reflects none, 0 when they hold none).
    pub fn error_share(&self) -> f64 {
        if self.error_power <= 0.0 {
            0.0
        } else if self.reflected_power > 0.0 {
            self.error_power / self.reflected_power
        } else {
            f64::INFINITY
        }
    }

    /// Whether the worst polygon is too large for any depth to resolve its light: its finest
    /// element (its longest edge over 2^[`MAX_DEPTH`], the quadtree's deepest level) against
    /// the scale its nearest light varies over (the light's distance from the polygon's plane
    /// plus its radius, over `LIGHT_DEPTH_FACTOR`, as refinement judges it). `Some((longest
    /// edge, finest element, that scale))` when it is.
    fn too_large(&self, scene: &Scene) -> Option<(f64, f64, f64)> {
        let r = self.worst_polygon as usize;
        let p = scene.polygons.get(r)?;
        let vs = p.vertices();
        let longest = (0..vs.len())
            .map(|i| (vs[(i + 1) % vs.len()] - vs[i]).length())
            .fold(0.0f64, f64::max);
        let n = p.normal;
        let spots = scene.spots.iter().map(|s| (s.position, 0.0));
        let emitters = (0..scene.polygons.len())
            .filter(|&i| i != r && scene.material_of(i).is_emitter())
            .map(|i| scene.polygons[i].bounding_sphere());
        let detail = spots
            .chain(emitters)
            .map(|(c, radius)| ((c - vs[0]).dot(n).abs() + radius) / shoot::LIGHT_DEPTH_FACTOR)
            .fold(f64::INFINITY, f64::min);
        let finest = longest / f64::from(1u32 << MAX_DEPTH);
        (detail.is_finite() && finest > detail).then_some((longest, finest, detail))
    }

    /// Counts one leaf split to the guard with its light off the bilinear prediction where a
    /// spot's cone edge crosses it.
    pub(crate) fn record_edge(&mut self) {
        self.edge_leaves += 1;
    }

    /// Counts one leaf of polygon `r` split to the guard with its light off the bilinear
    /// prediction by `excess` of its level, `power` the light it may misplace.
    pub(crate) fn record(&mut self, r: u32, excess: f64, power: f64) {
        self.leaves += 1;
        self.error_power += power;
        if excess > self.worst_excess {
            self.worst_excess = excess;
            self.worst_polygon = r;
        }
    }
}

/// Where a solve's emitted power went, per channel, in watts: emitted = absorbed + unshot +
/// lost. `lost` is light that left an open scene plus the solve's own energy error (on a
/// closed scene, only the latter); `escaped` estimates the first on its own (rays from every
/// shooter that hit nothing), so `lost - escaped` is the error ([`EnergyAccount::error`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EnergyAccount {
    /// Spots' and emitters' power.
    pub emitted: DVec3,
    /// Absorbed by the surfaces: (1 - rho) times the power arriving on each front, plus all
    /// the power arriving on back faces (one-sided polygons' backs are black).
    pub absorbed: DVec3,
    /// Reflected light the solve stopped before shooting.
    pub unshot: DVec3,
    /// The rest: emitted - absorbed - unshot.
    pub lost: DVec3,
    /// The light that left the scene (every shooter's power shot times the share of its rays
    /// that hit nothing).
    pub escaped: DVec3,
}

/// A solve whose energy account is off by more than this share of the emitted power (in a
/// channel) created or lost light it should not have: `solve` and `render` warn.
pub const ENERGY_ERROR_WARN: f64 = 0.005;

impl EnergyAccount {
    /// `lost` over `emitted` in the channel where its magnitude is largest (0 when nothing is
    /// emitted).
    pub fn lost_fraction(&self) -> f64 {
        self.largest(self.lost)
    }

    /// The solve's energy error, `lost - escaped` (negative: light created), over `emitted`
    /// in the channel where its magnitude is largest (0 when nothing is emitted).
    pub fn error(&self) -> f64 {
        self.largest(self.lost - self.escaped)
    }

    /// `v` over `emitted` in the channel where its magnitude is largest.
    fn largest(&self, v: DVec3) -> f64 {
        (0..3)
            .filter(|&k| self.emitted[k] > 0.0)
            .map(|k| v[k] / self.emitted[k])
            .fold(0.0f64, |a, b| if b.abs() > a.abs() { b } else { a })
    }
}

/// A radiosity solution.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// One sampled quadtree per scene polygon, in scene order, its nodes in the canonical order
    /// of [`Quadtree::grow`](base::quadtree::Quadtree::grow) (so the split bits that a solution
    /// file stores rebuild it exactly). Values: linear RGB radiosity, emission included, finite
    /// and >= 0.
    pub polygons: Vec<SampledQuadtree>,
    /// The shooting history: every shooter in id order (spots, emitters, patches) with its total.
    pub shooters: Vec<Shooter>,
    /// Statistics.
    pub stats: SolveStats,
    /// [`scene_hash`] of the scene this solves.
    pub scene_hash: u64,
}

/// Largest shadow-ray count accepted per receiver point and shooter.
pub const MAX_SHADOW_RAYS: u32 = 4096;

fn check_settings(scene: &Scene) -> Result<()> {
    let s = &scene.radiosity;
    let loc = |k: &str| Location::file(&scene.source).with_key(format!("radiosity.{k}"));
    if !(s.tolerance.is_finite() && s.tolerance >= 0.0) {
        return Err(Error::input(
            loc("tolerance"),
            "must be a finite number >= 0",
        ));
    }
    if s.max_depth > MAX_DEPTH {
        return Err(Error::input(
            loc("max_depth"),
            format!("is {}, must be at most {MAX_DEPTH}", s.max_depth),
        ));
    }
    if s.min_depth > s.max_depth {
        return Err(Error::input(
            loc("min_depth"),
            format!(
                "is {}, must be at most max_depth ({})",
                s.min_depth, s.max_depth
            ),
        ));
    }
    if !(s.convergence.is_finite() && s.convergence > 0.0 && s.convergence <= 1.0) {
        return Err(Error::input(loc("convergence"), "must be in (0, 1]"));
    }
    if s.shadow_rays == 0 || s.shadow_rays > MAX_SHADOW_RAYS {
        return Err(Error::input(
            loc("shadow_rays"),
            format!("is {}, must be in 1..={MAX_SHADOW_RAYS}", s.shadow_rays),
        ));
    }
    check_spot_peaks(scene)?;
    for (i, p) in scene.polygons.iter().enumerate() {
        if p.material as usize >= scene.materials.len() {
            return Err(Error::input(
                Location::file(&scene.source).with_key(format!("polygons[{i}].material")),
                "refers to a material that does not exist",
            ));
        }
    }
    Ok(())
}

/// The largest radiosity a spot may put on a surface: samples, patches and pixels are f32
/// (largest 3.4e38), and the reconstruction's slopes, patch coefficients and a pixel's sum of
/// supersamples multiply a value by at most a few tens, so 1e30 keeps every stage finite with
/// eight orders of magnitude to spare.
pub(crate) const MAX_SPOT_RADIOSITY: f64 = 1e30;

/// Refuses a spot that would light a surface beyond [`MAX_SPOT_RADIOSITY`], with an input
/// error naming the spot, the polygon and the distance. Emitters cannot get there (emission is
/// at most 1e9 and reflectance below 1, so radiosity stays below 1e9 / (1 - rho) < 1e26); a
/// spot gives rho I cos(theta_s) / r^2 = rho I h / r^3 at height h above a polygon's plane,
/// at most rho I h / d^3 with d >= h its distance from the polygon (cone and falloff left
/// out: the bound is conservative). A spot within the solver's plane tolerance of the plane
/// lights nothing on it ([`transfer`]), so it is not refused. Without this check a sample
/// beyond the f32 range would be zeroed by [`sanitize`], and a spot 1e-15 above a 1e-7 square
/// would draw a black image with exit 0.
fn check_spot_peaks(scene: &Scene) -> Result<()> {
    let eps = transfer::plane_tolerance(scene);
    for (k, spot) in scene.spots.iter().enumerate() {
        let i_max = spot.intensity.max_element();
        if i_max <= 0.0 {
            continue;
        }
        for (pi, poly) in scene.polygons.iter().enumerate() {
            let rho = scene.materials[poly.material as usize]
                .reflectance
                .max_element();
            let h = poly.normal.dot(spot.position - poly.corners[0]);
            if rho <= 0.0 || h <= eps {
                continue;
            }
            let d = distance_to_polygon(spot.position, poly);
            let peak = rho * i_max * h / (d * d * d);
            if peak.is_nan() || peak > MAX_SPOT_RADIOSITY {
                let name = scene
                    .objects
                    .get(poly.object as usize)
                    .map_or(format!("polygons[{pi}]"), |n| format!("`{n}`"));
                return Err(Error::input(
                    scene.spot_location(k),
                    format!(
                        "is {d:e} from polygon {name}: its radiosity there could reach \
                         rho I h / d^3 = {peak:e}, beyond {MAX_SPOT_RADIOSITY:e}, the most a \
                         solution holds (f32 samples); move the spot away or lower its \
                         intensity"
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Distance from `x` to the (planar, convex) polygon `p`.
fn distance_to_polygon(x: DVec3, p: &scene::Polygon) -> f64 {
    let vs = p.vertices();
    let h = p.normal.dot(x - vs[0]);
    let foot = x - h * p.normal;
    let inside = (0..vs.len()).all(|i| {
        let (a, b) = (vs[i], vs[(i + 1) % vs.len()]);
        (b - a).cross(foot - a).dot(p.normal) >= 0.0
    });
    if inside {
        return h.abs();
    }
    (0..vs.len())
        .map(|i| {
            let (a, b) = (vs[i], vs[(i + 1) % vs.len()]);
            let ab = b - a;
            let t = ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
            (x - (a + t * ab)).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Maps a non-finite or negative channel to 0 (documented clamp; never expected to trigger).
#[inline]
pub fn sanitize(c: DVec3) -> Vec3 {
    let f = |x: f64| {
        let y = x as f32;
        if y.is_finite() && y > 0.0 {
            y
        } else {
            0.0
        }
    };
    Vec3::new(f(c.x), f(c.y), f(c.z))
}

/// Radiosity E + rho * G of material `m` under irradiance G (the one formula of both the solve
/// and the oracle).
#[inline]
pub(crate) fn radiosity_from_g(m: &scene::Material, g: DVec3) -> Vec3 {
    if m.reflectance.max_element() <= 0.0 {
        return sanitize(m.emission);
    }
    sanitize(m.emission + m.reflectance * g)
}

/// Solves `scene` in the caller's rayon pool.
///
/// Cost: direct shots x the vertices they reach, indirect shots x the coarse receiver points
/// they reach (repeated shots reuse cached transfers), and one full gather per round (every
/// vertex x the shooters that reach it), each transfer casting `shadow_rays` shadow rays for an
/// emitter, `shadow_rays / 4` for a reflecting patch, only for pairs an occluder may cut; plus
/// finding each shooter's receivers once (all polygons, or its probe rays' hits); see `shoot`
/// and `transfer`.
///
/// Reports to `opts.observer`: progress of stage `STAGE` (after the settings are checked),
/// `finished` once the shooting is done, trace lines if the observer wants them.
pub fn solve(scene: &Scene, opts: &SolveOptions<'_>) -> Result<Solution> {
    check_settings(scene)?;
    let start = Instant::now();
    let mut stage = Stage::start(opts.observer, STAGE);
    let mut tr = Transfer::new(scene);
    let snapshot = opts
        .snapshots
        .map(|send| move |out: shoot::Outcome| send(solution_of(scene, out, start)));
    let out = shoot::run(
        scene,
        &mut tr,
        &mut stage,
        opts.memory_limit,
        snapshot.as_ref().map(|f| f as &dyn Fn(shoot::Outcome)),
    )?;
    drop(stage);
    Ok(solution_of(scene, out, start))
}

/// The solution of `scene` a solve started at `start` holds in its outcome `out`.
fn solution_of(scene: &Scene, out: shoot::Outcome, start: Instant) -> Solution {
    // Every vertex's G was gathered from the history by the oracle's own function, so
    // E + rho * G here is the oracle's answer at that vertex, bit for bit.
    let mut polygons = Vec::with_capacity(out.trees.len());
    for (r, (tree, keys, g)) in out.trees.into_iter().enumerate() {
        let m = scene.material_of(r);
        let values: Vec<Vec3> = g.iter().map(|g| radiosity_from_g(m, *g)).collect();
        polygons.push(SampledQuadtree {
            tree: tree.canonical(),
            keys,
            values,
        });
    }
    let mut stats = SolveStats {
        shots: out.shots,
        rays_cast: out.rays,
        refined_after: out.refined_after,
        guard_stops: out.guard_stops,
        emitted_power: out.emitted,
        unshot_fraction: out.unshot,
        unshot_history: out.history,
        energy: out.energy,
        ..SolveStats::default()
    };
    fill_tree_stats(&mut stats, &polygons);
    stats.solve_ms = start.elapsed().as_secs_f64() * 1e3;
    let shooters = out
        .kinds
        .iter()
        .zip(&out.totals)
        .zip(out.shapes)
        .map(|((k, t), shape)| Shooter {
            kind: *k,
            total: *t,
            shape,
        })
        .collect();
    Solution {
        polygons,
        shooters,
        stats,
        scene_hash: scene_hash(scene),
    }
}

/// Fills elements, vertices, T-vertices and the depth histogram from the trees.
pub(crate) fn fill_tree_stats(stats: &mut SolveStats, polygons: &[SampledQuadtree]) {
    stats.elements = 0;
    stats.vertices = 0;
    stats.t_vertices = 0;
    stats.depth_histogram.clear();
    for p in polygons {
        stats.elements += p.tree.leaf_count() as u64;
        stats.vertices += p.keys.len() as u64;
        stats.t_vertices += count_t_vertices(&p.tree) as u64;
        let h = p.tree.depth_histogram();
        if stats.depth_histogram.len() < h.len() {
            stats.depth_histogram.resize(h.len(), 0);
        }
        for (d, n) in h.into_iter().enumerate() {
            stats.depth_histogram[d] += n as u64;
        }
    }
}

/// T-vertices of a tree in O(n log n): an interior lattice point that is a corner of exactly two
/// leaves lies inside the edge of a third (a regular interior vertex is a corner of four leaves,
/// and no T-vertex can lie on the domain boundary).
pub(crate) fn count_t_vertices(tree: &base::quadtree::Quadtree) -> usize {
    use base::quadtree::LATTICE;
    let mut corners: Vec<_> = tree
        .nodes()
        .iter()
        .filter(|n| n.is_leaf())
        .flat_map(|n| n.cell.corners())
        .collect();
    corners.sort_unstable();
    let mut count = 0;
    let mut i = 0;
    while i < corners.len() {
        let k = corners[i];
        let mut j = i;
        while j < corners.len() && corners[j] == k {
            j += 1;
        }
        let interior = k.i > 0 && k.i < LATTICE && k.j > 0 && k.j < LATTICE;
        if interior && j - i == 2 {
            count += 1;
        }
        i = j;
    }
    count
}

/// The radiosity oracle: the radiosity at any point of any polygon from a solution's history.
///
/// Build it once (BVH, shooter geometry, pair classes) and query many points; each query costs
/// O(shooters x `shadow_rays`) (rays only for pairs that can be occluded).
pub struct Oracle<'a> {
    tr: Transfer<'a>,
    totals: Vec<DVec3>,
}

impl<'a> Oracle<'a> {
    /// Prepares the oracle of `sol` on `scene` (which must be the scene `sol` solves).
    ///
    /// A solution of another scene (its scene hash differs), or one whose shooters are not the
    /// scene's, is [`Error::Inconsistent`]: no solve of `scene` produces it (the caller decides
    /// whether that is a corrupt file or a bug).
    pub fn new(sol: &Solution, scene: &'a Scene) -> Result<Oracle<'a>> {
        if sol.scene_hash != scene_hash(scene) {
            return Err(Error::inconsistent(
                "the solution was computed for another scene",
            ));
        }
        let mut tr = Transfer::new(scene);
        if tr.shooters.len() != sol.shooters.len() {
            return Err(Error::inconsistent(format!(
                "the solution has {} shooters, the scene {}",
                sol.shooters.len(),
                tr.shooters.len()
            )));
        }
        let totals: Vec<DVec3> = sol.shooters.iter().map(|s| s.total).collect();
        for (s, t) in totals.iter().enumerate() {
            if *t != DVec3::ZERO {
                tr.ensure_pairs(s);
            }
            tr.set_shape(s, sol.shooters[s].shape.clone());
        }
        tr.index_receivers();
        Ok(Oracle { tr, totals })
    }

    /// Radiosity (linear RGB, emission included) of polygon `polygon` at (u, v) in [0, 1]^2
    /// (clamped). Out-of-range polygon indices give black.
    pub fn radiosity(&self, polygon: usize, u: f64, v: f64) -> Vec3 {
        let scene = self.tr.scene;
        if polygon >= scene.polygons.len() {
            return Vec3::ZERO;
        }
        let m = scene.material_of(polygon);
        let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, 1.0) };
        let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
        if m.reflectance.max_element() <= 0.0 {
            return radiosity_from_g(m, DVec3::ZERO);
        }
        let g = self.tr.gather(&self.totals, polygon, u, v);
        radiosity_from_g(m, g)
    }

    /// Irradiance G of polygon `polygon` at (u, v) (radiosity is E + rho G), which must be a
    /// valid index.
    pub(crate) fn irradiance(&self, polygon: usize, u: f64, v: f64) -> DVec3 {
        self.tr.gather(&self.totals, polygon, u, v)
    }
}

impl Solution {
    /// Radiosity at (u, v) of polygon `polygon` from the history. Builds an [`Oracle`] per call
    /// (a BVH and the pair classes: O(shooters x polygons)); for many queries build the oracle
    /// once with [`Oracle::new`]. Per query cost O(shooters x `shadow_rays`). Returns black if the
    /// solution is not for `scene`.
    pub fn radiosity(&self, scene: &Scene, polygon: usize, u: f64, v: f64) -> Vec3 {
        match Oracle::new(self, scene) {
            Ok(o) => o.radiosity(polygon, u, v),
            Err(_) => Vec3::ZERO,
        }
    }
}

/// FNV-1a 64 over bytes.
#[derive(Debug, Clone, Copy)]
pub struct Fnv(pub u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// Feeds bytes.
    pub fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 ^= x as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    /// Feeds a u64, little-endian.
    pub fn u64(&mut self, x: u64) {
        self.bytes(&x.to_le_bytes());
    }
    /// Feeds an f64 by its bits (so -0.0 and 0.0 differ; scenes are compared exactly).
    pub fn f64(&mut self, x: f64) {
        self.u64(x.to_bits());
    }
    /// Feeds a vector.
    pub fn vec3(&mut self, v: DVec3) {
        self.f64(v.x);
        self.f64(v.y);
        self.f64(v.z);
    }
}

/// A stable hash (FNV-1a 64, little-endian field encoding) of everything in `scene` that the
/// solution depends on: polygon corners, shapes and materials, reflectance and emission, spot
/// lights and radiosity settings. Not names, camera, render or display settings.
pub fn scene_hash(scene: &Scene) -> u64 {
    let mut h = Fnv::default();
    h.bytes(b"pixelflow-sim scene v1");
    h.u64(scene.polygons.len() as u64);
    for p in &scene.polygons {
        for c in p.corners {
            h.vec3(c);
        }
        h.u64(p.shape.corner_count() as u64);
        h.u64(p.material as u64);
    }
    h.u64(scene.materials.len() as u64);
    for m in &scene.materials {
        h.vec3(m.reflectance);
        h.vec3(m.emission);
    }
    h.u64(scene.spots.len() as u64);
    for s in &scene.spots {
        h.vec3(s.position);
        h.vec3(s.direction);
        h.vec3(s.intensity);
        h.f64(s.half_angle);
        h.f64(s.falloff);
    }
    let r = &scene.radiosity;
    h.f64(r.tolerance);
    h.u64(r.min_depth as u64);
    h.u64(r.max_depth as u64);
    h.f64(r.convergence);
    h.u64(r.shadow_rays as u64);
    h.u64(r.seed);
    // Hashed only when set, so that solutions of scenes that leave it at `auto` keep their
    // hash (what `auto` picks is a function of the scene).
    match r.visibility {
        scene::Visibility::Auto => {}
        scene::Visibility::Exact => h.bytes(b"visibility exact"),
        scene::Visibility::Sampled => h.bytes(b"visibility sampled"),
    }
    h.0
}

#[cfg(test)]
mod tests;
