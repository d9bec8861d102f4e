//! Progressive refinement (shooting, Cohen et al. 1988) over adaptive, unrestricted quadtrees.
//!
//! State: per polygon an unrestricted [`Quadtree`], its vertex keys and an irradiance G at every
//! vertex (f64); per shooter the total radiosity it has shot so far (the history). Order of work:
//! 1. every polygon starts uniformly subdivided to `max(min_depth, its patch depth)` (patch
//!    depth <= 2, so a shooter patch is always a union of leaves);
//! 2. direct pass: spot lights shoot, each once, then emitters shoot their emission (largest power
//!    first), to every vertex;
//! 3. refine: a leaf splits when the true reflected radiosity at its centre or an edge midpoint
//!    differs from the bilinear prediction of its corners by more than `tolerance` times its own
//!    level (floored at [`REFINE_FLOOR`] of the brightest sample), when a parabola through three
//!    samples on one of its lines peaks beyond its ends (an extremum between samples), when the
//!    point where a light's direct contribution peaks on the polygon (`peaks`) lies in it with
//!    more light than its corners, or when a shadow boundary of a light crosses it (the light's
//!    visible fraction differs across its points), while its depth is below `max_depth` and its
//!    world-space size above [`min_element_size`]; near a small or close light or a spot's cone
//!    edge those guards give way to a depth set by the light's size and distance (see `refine`);
//!    new vertices gather from the whole history; T-vertices stay, the tree is never balanced;
//! 4. indirect pass: reflecting patches shoot their unshot radiosity (largest unshot power
//!    in magnitude first, each channel relative to that channel's emitted power; ties by id)
//!    until, in every channel, the unshot power falls below `convergence` times the emitted
//!    power. These shots go to a fixed coarse set of receiver points per polygon (the vertices of its uniform
//!    grid one level below its patch depth), not to every vertex: during shooting the receivers
//!    only serve to estimate the patches' unshot power, which is smooth indirect light, and a
//!    shot then costs O(coarse points) instead of O(vertices). Shooting goes on until the coarse
//!    estimate is below [`SHOOT_MARGIN`] times the threshold (it runs low, and a round that ends
//!    above the threshold costs another full gather). A patch's coarse transfers are computed
//!    on its first shot and cached ([`CoarseCache`]), because patches shoot several times;
//! 5. the patches' unshot radiosity joins their totals (the full gather then carries it one
//!    bounce on, instead of leaving it missing), every vertex gathers G from the whole history
//!    (the oracle's computation), the trees are refined again against it, and the unshot power
//!    is re-estimated from all vertices; the shape of each patch's light (`transfer::shape`:
//!    how its radiosity varies over it) is measured from the new samples, and if that estimate
//!    is still above the threshold, the shapes moved by more than `shapes::SHAPE_CHANGE`, or a
//!    patch has still to shoot more than `convergence` of its own light (its residual: the
//!    fraction of the emitted power misses a patch whose light is a small share of it), another
//!    round shoots and gathers with the new shapes (at most [`MAX_ROUNDS`] rounds);
//!    once the unshot light is below the threshold, the new shapes are first settled where
//!    they move the light where it falls by more than `tolerance` (`solver::settle`: the
//!    points there gather again with them, a few passes, and are put back);
//! 6. a stored sample is therefore E + rho * G with G gathered from the final history and the
//!    final shapes, exactly the oracle's answer, bit for bit, whatever order the shots came in.
//!
//! Steps 3 and 5 gather at the same points round after round (every vertex, and the test points
//! of every leaf the refinement judges, which become vertices when the leaf splits), and most of
//! a gather is geometry: each shooter's form factor and visible part from the point. The solve
//! keeps that per point (`transfer::seen`, within a byte budget), so a point gathered again
//! pays only for the light: the same G, bit for bit, in less time (the Cornell box's solve
//! runs about a fifth fewer instructions).
//!
//! Unshot radiosity of a patch = rho * (integral of G over the patch) / area - total, with the
//! integral taken over the patch's leaves (Simpson's rule with the refinement's test points,
//! the trapezoid rule on leaves it did not test) from the light at the fine vertices (the
//! direct pass's, or the last full gather's), plus over its coarse cells (indirect light shot
//! since then). It is signed: where a finer estimate falls below what a patch already shot,
//! the patch shoots the difference back (with the estimate clamped at zero, a patch whose
//! coarse estimate ran high kept its excess: a box's bottom 0.3 over a floor came out 9 % too
//! bright). Totals stay >= 0: a negative shot takes a total down to the estimate, never below.
//!
//! An energy account (`energy`) says where the emitted power went: absorbed, unshot, and lost
//! (left an open scene, or the discretization's own error).
//!
//! Progress and diagnostics go to the caller's [`Observer`](base::progress::Observer) through the
//! solve's [`Stage`]: the work done over the whole work and the seconds left, priced from the
//! rates the solve measures (`eta`), and, only when the observer is
//! [`tracing`](base::progress::Observer::tracing), one trace line per phase with its time, shots,
//! vertices and unshot power in per cent of the emitted power (used to measure the solver).
//! Neither changes what is computed.
//!
//! Code: the solve is a `Solver` (`solver`), its state named fields and its phases methods, in
//! the order above. What it holds per polygon (tree, vertices, G, coarse receivers, leaves) and
//! where each polygon's patches are among the shooters is in `poly`; every shooter's unshot
//! light, the next shooter and the unshot fraction in `unshot`; one shot and the coarse
//! transfer cache in `shot`; the refinement passes in `refine`; the patches' shapes in
//! `shapes`; where each light's direct contribution peaks on each polygon in `peaks`; the
//! energy account in `energy`; the progress and remaining-time estimate in `eta`.
//!
//! Scale: after a shot only the polygons it reached have new integrals and only their patches a
//! new unshot power; the unshot powers live in a tournament tree (`UnshotQueue`) that gives
//! the next shooter and the total in O(log shooters), so a shot costs what the shooter
//! reaches. The total is summed in the tree's fixed shape.
//!
//! Parallelism: rayon over receiver points (`par_iter` + `collect` in order); every float sum is
//! done serially in a fixed order, so the result is the same for any number of threads.

mod energy;
mod eta;
#[cfg(test)]
pub(crate) use energy::gathered_integral;
mod poly;
mod queue;
mod peaks;
mod refine;
mod shapes;
mod shot;
mod solver;
mod unshot;

use std::time::Instant;

use glam::DVec3;

use super::transfer::{ShooterKind, Transfer};
use base::error::{Error, Result};
use base::progress::Stage;
use base::quadtree::{Quadtree, VertexKey};
pub(crate) use refine::LIGHT_DEPTH_FACTOR;
pub use refine::{depth_bound, min_element_size, DIVE_NODES, SHADOW_EDGE_LEVELS};
use scene::Scene;
pub use shot::COARSE_CACHE_ENTRIES;
#[cfg(test)]
pub(crate) use solver::without_settling;
use solver::Solver;

/// Most indirect-shooting rounds (each ends with a full gather and a refinement pass). Scenes
/// whose shapes settle late take five to bring every patch's residual below `convergence`:
/// the furnished room of docs/accuracy.md ended its fourth round with a cabinet's side
/// shooting 3.2 % more than its light and the floor of the nook it faces 2 % bright (1.3 %
/// after a fifth round, for 1.19 times the solve), the studio's dark pieces 14 % (10 %).
pub(crate) const MAX_ROUNDS: u32 = 5;

/// Indirect shooting continues until the coarse unshot estimate falls below this fraction of
/// `convergence`. The coarse estimate runs low (light shot to a few coarse points misses what the
/// full gather then finds, typically by a factor of about 2 in the test scenes), and a round that
/// ends above `convergence` costs a whole extra gather at every vertex, while the extra shots
/// are cheap (coarse receivers, see the module doc).
pub(crate) const SHOOT_MARGIN: f64 = 0.5;

/// Luminance of linear RGB (Rec. 709 weights).
#[inline]
pub(crate) fn lum(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Largest of `values` less the smallest (0 for none).
pub(crate) fn spread(values: impl IntoIterator<Item = f64>) -> f64 {
    let (lo, hi) = values
        .into_iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(x), hi.max(x))
        });
    if hi >= lo {
        hi - lo
    } else {
        0.0
    }
}

/// The centre rule on a leaf of area `area` whose corners' values sum to `corners` and whose
/// centre's value is `centre`: corners 1/12 each, centre 2/3. Exact for a quadratic, so along
/// a ramp that varies in one direction it is Simpson's rule; the trapezoid rule on the corners
/// misses the ramp's curvature.
pub(crate) fn centre_rule(area: f64, corners: DVec3, centre: DVec3) -> DVec3 {
    area * (corners / 12.0 + centre * (2.0 / 3.0))
}

/// What the solver hands back to `solve`.
#[derive(Clone)]
pub(crate) struct Outcome {
    /// Per polygon: tree, keys, and G at every key gathered from the final history (zero for a
    /// polygon that does not reflect).
    pub trees: Vec<(Quadtree, Vec<VertexKey>, Vec<DVec3>)>,
    /// Per shooter: total radiosity shot.
    pub totals: Vec<DVec3>,
    /// Shooter kinds in id order.
    pub kinds: Vec<ShooterKind>,
    /// Where the emitted power went.
    pub energy: crate::EnergyAccount,
    /// Per shooter, the shape of its light the final gather used.
    pub shapes: Vec<Option<crate::transfer::shape::PatchShape>>,
    /// Shots taken.
    pub shots: u64,
    /// Unshot fraction after every shot.
    pub history: Vec<f64>,
    /// Final unshot fraction (estimated from every vertex).
    pub unshot: f64,
    /// Emitted power (sum over channels).
    pub emitted: f64,
    /// Number of shots taken before each refinement pass.
    pub refined_after: Vec<u64>,
    /// Leaves refined to a guard with the error test failing.
    pub guard_stops: crate::GuardStops,
    /// Shadow rays cast.
    pub rays: u64,
}

/// Runs the whole solve and returns trees and the shooting history. `tr` must be built on `scene`.
/// Reports progress (and trace lines, if wanted) to `stage`; the caller ends the stage.
///
/// `memory_limit` bounds the bytes of the solve's state ([`state_bytes`] plus the pair tables
/// built so far): a refinement pass that would pass it stops the solve with
/// [`Error::Memory`] before it allocates.
///
/// `snapshot`, if given, receives the state of the solve each time every vertex holds G from
/// the history so far: after the direct pass and its refinement, and after every indirect
/// round but the last (whose state is the outcome); its energy account is left empty.
pub(crate) fn run(
    scene: &Scene,
    tr: &mut Transfer<'_>,
    stage: &mut Stage<'_>,
    memory_limit: u64,
    snapshot: Option<&dyn Fn(Outcome)>,
) -> Result<Outcome> {
    Solver::new(scene, tr, stage, COARSE_CACHE_ENTRIES, memory_limit)
        .with_snapshots(snapshot)
        .solve()
}

/// [`run`] with at most `cache_entries` cached coarse transfers and `seen_bytes` of the
/// gathers' kept geometry (the result does not depend on either; tests compare 0 with the
/// default).
#[cfg(test)]
pub(crate) fn run_with_caches(
    scene: &Scene,
    tr: &mut Transfer<'_>,
    stage: &mut Stage<'_>,
    (cache_entries, seen_bytes): (usize, u64),
    memory_limit: u64,
) -> Result<Outcome> {
    Solver::new(scene, tr, stage, cache_entries, memory_limit)
        .with_seen_budget(seen_bytes)
        .solve()
}

/// Bytes the solve holds per quadtree node: the node, one leaf record with G at its five test
/// points (a leaf is counted with every node, an upper bound: a tree has about 3/4 as many
/// leaves as nodes), the node's copy in its patch's shape, twice (node, mean weight and area,
/// centre and size, 2-D cell, dipole, leaf index, leaf weight: a shape is the polygon's tree
/// under the patch; the shapes in use and the newly measured ones are held together while
/// they are compared), and
/// [`AFTER_SOLVE_NODE_BYTES`], so that a solve the guard admits can also be reconstructed and
/// written under the same limit (measured: gallery-fine under a 100 MiB limit peaked at 151 MB
/// when the guard counted neither).
pub(crate) const NODE_BYTES: u64 = (std::mem::size_of::<base::quadtree::Node>()
    + std::mem::size_of::<poly::Leaf>()
    + std::mem::size_of::<(base::quadtree::Cell, [DVec3; 5])>()
    + 2 * SHAPE_NODE_BYTES
    + AFTER_SOLVE_NODE_BYTES) as u64;

/// Bytes per node of what is built from the solution once the solve ends: its leaf's bicubic
/// patch (16 `f32` coefficients per channel, 192 B) while the compact RRPs are made, and its
/// share of the solution file's encoding (held twice: payload and file).
const AFTER_SOLVE_NODE_BYTES: usize = 192 + 128;

/// Bytes a patch's shape holds per node of its tree (see [`NODE_BYTES`]).
const SHAPE_NODE_BYTES: usize = std::mem::size_of::<base::quadtree::Node>()
    + 2 * std::mem::size_of::<(DVec3, f64)>()
    + std::mem::size_of::<[glam::DVec2; 4]>()
    + std::mem::size_of::<usize>()
    + std::mem::size_of::<[glam::Vec3; 3]>()
    + std::mem::size_of::<u32>()
    + 12;

/// Bytes the solve holds per sample (vertex): its key, its gathered G (f64 RGB) and the RGB
/// `f32` radiosity of the solution it becomes.
pub(crate) const VERTEX_BYTES: u64 =
    (std::mem::size_of::<VertexKey>() + std::mem::size_of::<DVec3>() + 12) as u64;

/// Bytes of the solve's state for `nodes` quadtree nodes and `vertices` samples, all polygons.
pub fn state_bytes(nodes: u64, vertices: u64) -> u64 {
    nodes
        .saturating_mul(NODE_BYTES)
        .saturating_add(vertices.saturating_mul(VERTEX_BYTES))
}

/// The solve stopped by its memory guard: `need` bytes over `limit`, `detail` saying of what.
fn memory_error(scene: &Scene, need: u64, limit: u64, detail: String) -> Error {
    Error::Memory {
        what: format!("the solve of {}", scene.source.display()),
        estimate: need,
        limit,
        detail,
        hint: "raise radiosity.tolerance, lower radiosity.max_depth, or raise `memory-limit`"
            .into(),
    }
}

/// Milliseconds since `t`: the one definition of the solver's trace times.
pub(crate) fn elapsed_ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
