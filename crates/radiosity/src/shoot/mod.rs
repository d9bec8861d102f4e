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
//!    level (floored at [`REFINE_FLOOR`] of the brightest sample), or when a shadow boundary of a
//!    light crosses it (the light's visible fraction differs across its points), while its depth
//!    is below `max_depth` and its world-space size above [`min_element_size`] (see `refine`);
//!    new vertices gather from the whole history; T-vertices stay, the tree is never balanced;
//! 4. indirect pass: reflecting patches shoot their unshot radiosity (largest unshot power
//!    first, each channel relative to that channel's emitted power; ties by id) until, in every
//!    channel, the unshot power falls below `convergence` times the emitted power. These
//!    shots go to a fixed coarse set of receiver points per polygon (the vertices of its uniform
//!    grid one level below its patch depth), not to every vertex: during shooting the receivers
//!    only serve to estimate the patches' unshot power, which is smooth indirect light, and a
//!    shot then costs O(coarse points) instead of O(vertices). Shooting goes on until the coarse
//!    estimate is below [`SHOOT_MARGIN`] times the threshold (it runs low, and a round that ends
//!    above the threshold costs another full gather). A patch's coarse transfers are computed
//!    on its first shot and cached ([`CoarseCache`]), because patches shoot several times;
//! 5. every vertex gathers G from the whole history (the oracle's computation), the trees are
//!    refined again against it, and the unshot power is re-estimated from all vertices; if that
//!    estimate is still above the threshold, shooting resumes (at most [`MAX_ROUNDS`] rounds);
//! 6. a stored sample is therefore E + rho * G with G gathered from the final history, exactly
//!    the oracle's answer, bit for bit, whatever order the shots came in.
//!
//! Unshot radiosity of a patch = rho * (integral of G over the patch) / area - total shot, with the
//! integral taken by the trapezoid rule over the patch's leaves (direct light, fine vertices) plus
//! over its coarse cells (indirect light shot since the last full gather). It is clamped at zero
//! per channel: a finer estimate can fall below what was already shot, and shooting negative
//! light would create negative radiosity.
//!
//! Progress and diagnostics go to the caller's [`Observer`] through the solve's [`Stage`]: after
//! every shot the distance to convergence on a log scale, and, only when the observer is
//! [`tracing`](Observer::tracing), one trace line per phase with its time, shots, vertices and
//! unshot fraction (used to measure the solver). Neither changes what is computed.
//!
//! Scale: after a shot only the polygons it reached have new integrals and only their patches a
//! new unshot power; the unshot powers live in a tournament tree (`UnshotQueue`) that gives
//! the next shooter and the total in O(log shooters), so a shot costs what the shooter
//! reaches. The total is summed in the tree's fixed shape.
//!
//! Parallelism: rayon over receiver points (`par_iter` + `collect` in order); every float sum is
//! done serially in a fixed order, so the result is the same for any number of threads.

mod eta;
mod queue;
mod refine;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::transfer::{
    build_shooters, spot_power, spot_power3, sub_area, PairClass, ShooterKind, Transfer,
};
use base::error::{Error, Result};
use base::progress::{Observer, Stage};
use base::quadtree::{Quadtree, VertexKey};
use eta::Eta;
use queue::UnshotQueue;
use refine::refine;
pub use refine::{depth_bound, min_element_size, REFINE_FLOOR};
use scene::Scene;

/// Most indirect-shooting rounds (each ends with a full gather and a refinement pass).
pub const MAX_ROUNDS: u32 = 4;

/// Indirect shooting continues until the coarse unshot estimate falls below this fraction of
/// `convergence`. The coarse estimate runs low (light shot to a few coarse points misses what the
/// full gather then finds, typically by a factor of about 2 in the test scenes), and a round that
/// ends above `convergence` costs a whole extra gather at every vertex, while the extra shots
/// are cheap (coarse receivers, see the module doc).
pub const SHOOT_MARGIN: f64 = 0.5;

/// Luminance of linear RGB (Rec. 709 weights).
#[inline]
pub fn lum(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// One leaf (or coarse cell), with what the unshot estimate needs.
#[derive(Debug, Clone, Copy)]
struct Leaf {
    corners: [u32; 4],
    area: f64,
    patch: u32,
}

/// Per-polygon solve state.
struct Poly {
    tree: Quadtree,
    keys: Vec<VertexKey>,
    g: Vec<DVec3>,
    leaves: Vec<Leaf>,
    /// Coarse receiver points of the indirect pass, their G since the last full gather, cells.
    ckeys: Vec<VertexKey>,
    cg: Vec<DVec3>,
    cleaves: Vec<Leaf>,
    rho: DVec3,
}

/// What the solver hands back to `solve`.
pub struct Outcome {
    /// Per polygon: tree, keys, and G at every key gathered from the final history (zero for a
    /// polygon that does not reflect).
    pub trees: Vec<(Quadtree, Vec<VertexKey>, Vec<DVec3>)>,
    /// Per shooter: total radiosity shot.
    pub totals: Vec<DVec3>,
    /// Shooter kinds in id order.
    pub kinds: Vec<ShooterKind>,
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
}

fn uniform_tree(depth: u32) -> Quadtree {
    let mut tree = Quadtree::new();
    let mut frontier = vec![0u32];
    for _ in 0..depth {
        let mut next = Vec::new();
        for id in frontier {
            let f = tree.split(id);
            next.extend(f..f + 4);
        }
        frontier = next;
    }
    tree
}

/// Runs the whole solve and returns trees and the shooting history. `tr` must be built on `scene`.
/// Reports progress (and trace lines, if wanted) to `stage`; the caller ends the stage.
///
/// `memory_limit` bounds the bytes of the solve's state ([`state_bytes`] plus the pair tables
/// built so far): a refinement pass that would pass it stops the solve with
/// [`Error::Memory`] before it allocates.
pub fn run(
    scene: &Scene,
    tr: &mut Transfer<'_>,
    stage: &mut Stage<'_>,
    memory_limit: u64,
) -> Result<Outcome> {
    run_with_cache(scene, tr, stage, COARSE_CACHE_ENTRIES, memory_limit)
}

/// Bytes the solve holds per quadtree node: the node and one leaf record (a leaf is counted
/// with every node, an upper bound: a tree has about 3/4 as many leaves as nodes).
pub const NODE_BYTES: u64 =
    (std::mem::size_of::<base::quadtree::Node>() + std::mem::size_of::<Leaf>()) as u64;

/// Bytes the solve holds per sample (vertex): its key, its gathered G (f64 RGB) and the RGB
/// `f32` radiosity of the solution it becomes.
pub const VERTEX_BYTES: u64 =
    (std::mem::size_of::<VertexKey>() + std::mem::size_of::<DVec3>() + 12) as u64;

/// The solve stopped by its memory guard.
fn memory_error(scene: &Scene, need: u64, limit: u64, detail: String) -> Error {
    Error::Memory {
        what: format!("the solve of {}", scene.source.display()),
        estimate: need,
        limit,
        detail,
        hint: "raise radiosity.tolerance, lower radiosity.max_depth, or raise --memory-limit"
            .into(),
    }
}

/// Bytes of the solve's state for `nodes` quadtree nodes and `vertices` samples, all polygons.
pub fn state_bytes(nodes: u64, vertices: u64) -> u64 {
    nodes
        .saturating_mul(NODE_BYTES)
        .saturating_add(vertices.saturating_mul(VERTEX_BYTES))
}

/// [`run`] with at most `cache_entries` cached coarse transfers (the result does not depend on
/// it; tests compare 0 with the default).
pub(crate) fn run_with_cache(
    scene: &Scene,
    tr: &mut Transfer<'_>,
    stage: &mut Stage<'_>,
    cache_entries: usize,
    memory_limit: u64,
) -> Result<Outcome> {
    let st = &scene.radiosity;
    let (_, patch_base, patch_depth) = build_shooters(scene);
    let ns = tr.shooters.len();
    let mut totals = vec![DVec3::ZERO; ns];
    let mut unshot = vec![DVec3::ZERO; ns];
    let mut polys: Vec<Poly> = scene
        .polygons
        .iter()
        .enumerate()
        .map(|(i, _)| {
            let tree = uniform_tree(st.min_depth.max(patch_depth[i]).min(st.max_depth));
            let keys = tree.vertex_keys();
            let coarse = uniform_tree((patch_depth[i] + 1).min(st.max_depth.max(patch_depth[i])));
            let ckeys = coarse.vertex_keys();
            let cleaves = leaves_of(scene, i, &coarse, &ckeys, &patch_base, &patch_depth);
            let mut p = Poly {
                g: vec![DVec3::ZERO; keys.len()],
                leaves: Vec::new(),
                tree,
                keys,
                cg: vec![DVec3::ZERO; ckeys.len()],
                ckeys,
                cleaves,
                rho: scene.material_of(i).reflectance,
            };
            p.leaves = leaves_of(scene, i, &p.tree, &p.keys, &patch_base, &patch_depth);
            p
        })
        .collect();

    // Emitted power and the initial unshot of spots and emitters.
    let mut emitted = 0.0;
    for (s, sg) in tr.shooters.iter().enumerate() {
        match sg.kind {
            ShooterKind::Spot { spot } => {
                emitted += spot_power(&scene.spots[spot as usize]);
                unshot[s] = DVec3::ONE;
            }
            ShooterKind::Emitter { polygon } => {
                let e = scene.material_of(polygon as usize).emission;
                emitted += sg.area * (e.x + e.y + e.z);
                unshot[s] = e;
            }
            ShooterKind::Patch { .. } => {}
        }
    }
    // Unshot power per channel (W): a spot's is its power in each channel until it has shot.
    let power3 = |tr: &Transfer<'_>, s: usize, u: DVec3| -> DVec3 {
        match tr.shooters[s].kind {
            ShooterKind::Spot { spot } => {
                if u == DVec3::ZERO {
                    DVec3::ZERO
                } else {
                    spot_power3(&scene.spots[spot as usize])
                }
            }
            _ => tr.shooters[s].area * u,
        }
    };
    let power = |tr: &Transfer<'_>, s: usize, u: DVec3| -> f64 {
        let p = power3(tr, s, u);
        p.x + p.y + p.z
    };
    // Emitted power per channel; a channel nothing emits in needs no shooting.
    let emitted3: DVec3 = (0..ns)
        .filter(|&s| !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }))
        .map(|s| power3(tr, s, unshot[s]))
        .sum();
    let inv_emitted = emitted3
        .to_array()
        .map(|e| if e > 0.0 { 1.0 / e } else { 0.0 });
    // Unshot power of each channel as a fraction of that channel's emitted power.
    let fractions = |p: DVec3| -> DVec3 {
        DVec3::new(
            p.x * inv_emitted[0],
            p.y * inv_emitted[1],
            p.z * inv_emitted[2],
        )
    };
    // Convergence is judged per channel: the solve's unshot fraction is the largest channel's.
    // The queue keeps every shooter's unshot power, their sum and the largest, updated per
    // shooter in O(log shooters), so a shot costs what it reaches, not the scene's size.
    let mut queue = UnshotQueue::new(ns);
    let set_q = |q: &mut UnshotQueue, tr: &Transfer<'_>, s: usize, u: DVec3| {
        let p = power3(tr, s, u);
        let f = fractions(p);
        q.set(s, p, f.x + f.y + f.z);
    };
    let frac_of = |q: &UnshotQueue| -> f64 {
        if emitted <= 0.0 {
            return 0.0;
        }
        fractions(q.total()).max_element()
    };
    // Patch shooter ids of every polygon (empty for one that does not reflect).
    let patches_of = |r: usize| -> std::ops::Range<usize> {
        if patch_base[r] == u32::MAX {
            0..0
        } else {
            let b = patch_base[r] as usize;
            b..b + (1usize << (2 * patch_depth[r]))
        }
    };
    // After a shot: the unshot power of the patches of the polygons it reached (their
    // integrals already updated), in `unshot` and in the queue.
    let refresh = |q: &mut UnshotQueue,
                   unshot: &mut [DVec3],
                   tr: &Transfer<'_>,
                   polys: &[Poly],
                   (totals, base, coarse): (&[DVec3], &[DVec3], &[DVec3]),
                   touched: &[u32]| {
        for &r in touched {
            for p in patches_of(r as usize) {
                unshot[p] = patch_unshot(tr, polys, totals, base, coarse, p);
                set_q(q, tr, p, unshot[p]);
            }
        }
    };
    // After a refinement pass: every patch's unshot power, the queue, and the unshot fraction.
    let refresh_all =
        |q: &mut UnshotQueue,
         unshot: &mut [DVec3],
         tr: &Transfer<'_>,
         polys: &[Poly],
         (totals, base, coarse): (&[DVec3], &[DVec3], &[DVec3])| {
            set_unshot(tr, polys, totals, base, coarse, unshot);
            for (s, u) in unshot.iter().enumerate() {
                set_q(q, tr, s, *u);
            }
            frac_of(q)
        };
    let mut history = Vec::new();
    let mut shots = 0u64;
    let max_shots = 100 * ns as u64 + 100;
    let conv = st.convergence;
    let log_target = -(conv.max(1e-12)).ln();
    // The unshot fraction may rise after a refinement pass; the stage keeps the reported
    // fraction non-decreasing.
    let observer: &dyn Observer = stage.observer();
    let report = |stage: &mut Stage<'_>, frac: f64| {
        let done = if frac <= 0.0 {
            1.0
        } else {
            (-frac.ln() / log_target).clamp(0.0, 1.0)
        };
        stage.advance(done);
    };
    let trace = observer.tracing();
    let t0 = Instant::now();
    let nverts = |polys: &[Poly]| polys.iter().map(|p| p.keys.len()).sum::<usize>();
    // Patch integrals of G from the fine vertices (`base`) and from the coarse points (`coarse`).
    let mut base = vec![DVec3::ZERO; ns];
    let mut coarse = vec![DVec3::ZERO; ns];

    // Direct pass: spots in id order, then emitters by power (ties by id), to every vertex.
    let mut direct: Vec<usize> = (0..ns)
        .filter(|&s| !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }))
        .collect();
    direct.sort_by(|&a, &b| {
        let spot_a = matches!(tr.shooters[a].kind, ShooterKind::Spot { .. });
        let spot_b = matches!(tr.shooters[b].kind, ShooterKind::Spot { .. });
        spot_b
            .cmp(&spot_a)
            .then_with(|| {
                if spot_a && spot_b {
                    std::cmp::Ordering::Equal
                } else {
                    power(tr, b, unshot[b]).total_cmp(&power(tr, a, unshot[a]))
                }
            })
            .then(a.cmp(&b))
    });
    for (s, u) in unshot.iter().enumerate() {
        set_q(&mut queue, tr, s, *u);
    }
    for s in direct {
        if power(tr, s, unshot[s]) <= 0.0 {
            continue;
        }
        let db = unshot[s];
        let (touched, _) = shoot(tr, &mut polys, s, db, None);
        totals[s] += db;
        unshot[s] = DVec3::ZERO;
        set_q(&mut queue, tr, s, unshot[s]);
        shots += 1;
        integrate(&polys, &patch_base, Some(&touched), false, &mut base);
        let sums = (&totals[..], &base[..], &coarse[..]);
        refresh(&mut queue, &mut unshot, tr, &polys, sums, &touched);
        let frac = frac_of(&queue);
        history.push(frac);
        report(stage, frac);
    }
    let mut refined_after = Vec::new();
    let mut frac = 0.0;
    if emitted > 0.0 {
        refined_after.push(shots);
        tr.index_receivers();
        refine(
            scene,
            tr,
            &mut polys,
            &totals,
            (&patch_base, &patch_depth),
            memory_limit,
        )?;
        integrate(&polys, &patch_base, None, false, &mut base);
        let sums = (&totals[..], &base[..], &coarse[..]);
        frac = refresh_all(&mut queue, &mut unshot, tr, &polys, sums);
        if trace {
            observer.trace(&format!(
                "direct + refine {:.0} ms, shots {shots}, vertices {}, unshot {frac:.4}",
                elapsed_ms(t0),
                nverts(&polys)
            ));
        }
    }

    let (mut t_pairs, mut t_shoot) = (0.0, 0.0);
    let mut eta = Eta::new();
    let mut cache = CoarseCache::new(ns, cache_entries);
    let mut round = 0;
    while emitted > 0.0 && round < MAX_ROUNDS {
        round += 1;
        while frac >= SHOOT_MARGIN * conv && shots < max_shots {
            // Largest unshot power, each channel relative to its emitted power (so the channel
            // furthest from convergence is served), ties by the smaller id.
            let Some(s) = queue.best() else { break };
            let db = unshot[s];
            if trace && shots.is_multiple_of(100) {
                observer.trace(&format!(
                    "  shot {shots}: {:.0} ms, unshot {frac:.4}, rays {}",
                    elapsed_ms(t0),
                    tr.rays.load(std::sync::atomic::Ordering::Relaxed)
                ));
            }
            let tp = Instant::now();
            let shot_start = tp;
            let first_shot = tr.pairs[s].is_none();
            if first_shot {
                tr.ensure_pairs(s);
                // A new pair table: the memory guard again (trees do not grow while shooting).
                let nodes: u64 = polys.iter().map(|p| p.tree.nodes().len() as u64).sum();
                let need =
                    state_bytes(nodes, nverts(&polys) as u64).saturating_add(tr.pair_bytes());
                if need > memory_limit {
                    return Err(memory_error(
                        scene,
                        need,
                        memory_limit,
                        format!(
                            "{nodes} quadtree nodes, {} samples, pair tables {} after {shots} shots",
                            nverts(&polys),
                            base::error::human_bytes(tr.pair_bytes())
                        ),
                    ));
                }
            }
            t_pairs += tp.elapsed().as_secs_f64();
            let tp = Instant::now();
            // Whether this shot computes its transfers (a cached one only adds them): only
            // computed ones tell what a gather's transfer costs.
            let computes = cache.per[s].is_none();
            let (touched, points) = shoot(tr, &mut polys, s, db, Some(&mut cache));
            let dt = tp.elapsed().as_secs_f64();
            t_shoot += dt;
            if computes {
                eta.transfers(points, dt);
            }
            totals[s] += db;
            unshot[s] = DVec3::ZERO;
            set_q(&mut queue, tr, s, unshot[s]);
            shots += 1;
            integrate(&polys, &patch_base, Some(&touched), true, &mut coarse);
            let sums = (&totals[..], &base[..], &coarse[..]);
            refresh(&mut queue, &mut unshot, tr, &polys, sums, &touched);
            frac = frac_of(&queue);
            history.push(frac);
            report(stage, frac);
            eta.shot_took(first_shot, shot_start.elapsed().as_secs_f64());
            eta.shot(stage, tr, &polys, &unshot, frac, SHOOT_MARGIN * conv, round);
        }
        // Full gather from the whole history at every vertex, then refine against it.
        if trace {
            let (mut open, mut occ, mut cands) = (0usize, 0usize, 0usize);
            for p in tr.pairs.iter().flatten() {
                for (r, c) in p.receivers() {
                    match c {
                        PairClass::Open => open += 1,
                        PairClass::Occluded => {
                            occ += 1;
                            cands += p.cands_len(r);
                        }
                        PairClass::Culled => {}
                    }
                }
            }
            observer.trace(&format!(
                "  shooting done {:.0} ms (pairs {:.0} ms, shots {:.0} ms), shots {shots}, pairs open {open} occluded {occ} (mean cands {:.1}), shooters with total {}",
                elapsed_ms(t0),
                t_pairs * 1e3,
                t_shoot * 1e3,
                cands as f64 / occ.max(1) as f64,
                totals.iter().filter(|t| **t != DVec3::ZERO).count()
            ));
        }
        tr.index_receivers();
        gather_all(tr, &mut polys, &totals, stage, round);
        eta.phase_start();
        if trace {
            observer.trace(&format!("  gather done {:.0} ms", elapsed_ms(t0)));
        }
        refined_after.push(shots);
        let splits = refine(
            scene,
            tr,
            &mut polys,
            &totals,
            (&patch_base, &patch_depth),
            memory_limit,
        )?;
        integrate(&polys, &patch_base, None, false, &mut base);
        for p in polys.iter_mut() {
            p.cg.iter_mut().for_each(|g| *g = DVec3::ZERO);
        }
        coarse.iter_mut().for_each(|c| *c = DVec3::ZERO);
        let sums = (&totals[..], &base[..], &coarse[..]);
        frac = refresh_all(&mut queue, &mut unshot, tr, &polys, sums);
        if trace {
            observer.trace(&format!(
                "round {round}: {:.0} ms, shots {shots}, splits {splits}, vertices {}, unshot {frac:.4}, rays {}",
                elapsed_ms(t0),
                nverts(&polys),
                tr.rays.load(std::sync::atomic::Ordering::Relaxed)
            ));
        }
        if frac < conv || shots >= max_shots {
            break;
        }
    }
    if emitted > 0.0 && round == 0 {
        tr.index_receivers();
        gather_all(tr, &mut polys, &totals, stage, 0);
    }
    report(stage, 1.0);
    Ok(Outcome {
        trees: polys.into_iter().map(|p| (p.tree, p.keys, p.g)).collect(),
        totals,
        kinds: tr.shooters.iter().map(|s| s.kind).collect(),
        shots,
        history,
        unshot: frac,
        emitted,
        refined_after,
    })
}

/// Every vertex of every reflecting polygon gathers G from the history `totals`, in
/// [`GATHER_CHUNKS`] chunks (each in parallel), reporting the time left after each from the
/// rate so far. Chunking changes no value: each vertex's gather is the same computation.
fn gather_all(
    tr: &Transfer<'_>,
    polys: &mut [Poly],
    totals: &[DVec3],
    stage: &Stage<'_>,
    round: u32,
) {
    let work: Vec<(u32, u32)> = polys
        .iter()
        .enumerate()
        .filter(|(_, p)| p.rho.max_element() > 0.0)
        .flat_map(|(r, p)| (0..p.keys.len() as u32).map(move |k| (r as u32, k)))
        .collect();
    let polys_ro = &*polys;
    let start = Instant::now();
    let chunk = work.len().div_ceil(GATHER_CHUNKS).max(1);
    let mut g: Vec<DVec3> = Vec::with_capacity(work.len());
    let phase = format!("round {round} gather");
    for part in work.chunks(chunk) {
        g.par_extend(part.par_iter().map(|&(r, k)| {
            let key = polys_ro[r as usize].keys[k as usize];
            tr.gather(totals, r as usize, key.u(), key.v())
        }));
        let done = g.len() as f64 / work.len() as f64;
        let t = start.elapsed().as_secs_f64();
        stage.remaining(&phase, t / done - t);
    }
    for (&(r, k), g) in work.iter().zip(g) {
        polys[r as usize].g[k as usize] = g;
    }
}

/// The final gather runs in this many chunks, so that its remaining time can be reported.
const GATHER_CHUNKS: usize = 64;

/// Transfers of indirect shots to the coarse receiver points, kept per shooter (see
/// [`CoarseCache`]).
pub struct CoarseCache {
    /// Per shooter: its transfer to every coarse point of every non-culled reflecting polygon, in
    /// work order (polygon order, then coarse key order), rounded to `f32`.
    per: Vec<Option<Vec<f32>>>,
    /// Entries stored so far, and the most that may be stored.
    used: usize,
    budget: usize,
}

/// Most cached coarse transfers (4 bytes each: 512 MiB at most). Entries grow with the pairs
/// (about 9 per pair of a small polygon): 25 M for 10,000 polygons of rooms, 116 M for 40,000,
/// where a smaller cache made every later shot of a patch recompute its transfers (the 40,000
/// polygon solve spent 79 s shooting with 32 M entries).
pub const COARSE_CACHE_ENTRIES: usize = 128 << 20;

impl CoarseCache {
    fn new(shooters: usize, budget: usize) -> Self {
        CoarseCache {
            per: vec![None; shooters],
            used: 0,
            budget,
        }
    }
}

/// Shooter `s` shoots radiosity `db` (per unit intensity scale for a spot) to every vertex, or
/// to the coarse receiver points if `cache` is given. Returns the polygons that received or own
/// the shooter, ascending, and the number of receiver points.
///
/// Coarse shots go to a fixed set of points (the coarse receivers never change during a solve),
/// and a patch shoots about four times on average in an enclosed scene (the gallery: 4167 shots
/// by 955 patches), so a shooter's coarse transfers are computed once, rounded to `f32` (the
/// rounding is applied on the first shot too, so a cached and a computed shot add the same
/// values) and reused while the cache has room. Coarse shots only estimate unshot power; stored
/// samples come from the full gather, which never uses this cache.
fn shoot(
    tr: &mut Transfer<'_>,
    polys: &mut [Poly],
    s: usize,
    db: DVec3,
    cache: Option<&mut CoarseCache>,
) -> (Vec<u32>, usize) {
    tr.ensure_pairs(s);
    let tr = &*tr;
    let coarse = cache.is_some();
    let pairs = tr.pairs[s].as_ref().expect("pairs computed above");
    let keys = |p: &Poly| if coarse { p.ckeys.len() } else { p.keys.len() };
    // (receiver, key) per point, and the pair's entry in the shooter's table.
    let (work, entry): (Vec<(u32, u32)>, Vec<u32>) = pairs
        .receivers()
        .enumerate()
        .map(|(i, (r, _))| (i, r, &polys[r]))
        .filter(|(_, _, p)| p.rho.max_element() > 0.0)
        .flat_map(|(i, r, p)| (0..keys(p) as u32).map(move |k| ((r as u32, k), i as u32)))
        .unzip();
    let polys_ro = &*polys;
    let compute = || -> Vec<DVec3> {
        work.par_iter()
            .zip(&entry)
            .map(|(&(r, k), &i)| {
                let p = &polys_ro[r as usize];
                let key = if coarse {
                    p.ckeys[k as usize]
                } else {
                    p.keys[k as usize]
                };
                tr.transfer_at(s, r as usize, i as usize, key.u(), key.v())
            })
            .collect()
    };
    match cache {
        None => {
            let t = compute();
            for (&(r, k), t) in work.iter().zip(t) {
                polys[r as usize].g[k as usize] += db * t;
            }
        }
        Some(cache) => {
            let is_patch = matches!(tr.shooters[s].kind, ShooterKind::Patch { .. });
            if !is_patch {
                // Spots and emitters shoot to every vertex in the direct pass; should one ever
                // shoot coarse, its (coloured, for a spot) transfer is added unrounded.
                let t = compute();
                for (&(r, k), t) in work.iter().zip(t) {
                    polys[r as usize].cg[k as usize] += db * t;
                }
            } else if cache.per[s].is_none() {
                // A patch's transfer is the same in every channel (F * V), so one f32 holds it.
                let t: Vec<f32> = compute().into_iter().map(|t| t.x as f32).collect();
                if cache.used + t.len() <= cache.budget {
                    cache.used += t.len();
                    cache.per[s] = Some(t);
                } else {
                    add_coarse(polys, &work, &t, db);
                }
            }
            if let Some(t) = &cache.per[s] {
                add_coarse(polys, &work, t, db);
            }
        }
    }
    let mut touched: Vec<u32> = pairs.receivers().map(|(r, _)| r as u32).collect();
    let own = tr.shooters[s].polygon;
    if (own as usize) < polys.len() {
        if let Err(i) = touched.binary_search(&own) {
            touched.insert(i, own);
        }
    }
    (touched, work.len())
}

fn add_coarse(polys: &mut [Poly], work: &[(u32, u32)], t: &[f32], db: DVec3) {
    for (&(r, k), &t) in work.iter().zip(t) {
        polys[r as usize].cg[k as usize] += db * t as f64;
    }
}

/// Recomputes the patch integrals of G (fine leaves, or coarse cells if `coarse`) of the
/// polygons listed in `only` (all if `None`) into `out`, indexed by shooter id.
fn integrate(polys: &[Poly], base: &[u32], only: Option<&[u32]>, coarse: bool, out: &mut [DVec3]) {
    let all: Vec<u32>;
    let list = match only {
        Some(l) => l,
        None => {
            all = (0..polys.len() as u32).collect();
            &all
        }
    };
    for &r in list {
        let (r, p) = (r as usize, &polys[r as usize]);
        if base[r] == u32::MAX {
            continue;
        }
        let (leaves, g) = if coarse {
            (&p.cleaves, &p.cg)
        } else {
            (&p.leaves, &p.g)
        };
        let first = base[r] as usize;
        let last = leaves
            .iter()
            .map(|l| l.patch as usize)
            .max()
            .unwrap_or(first);
        out[first..=last].iter_mut().for_each(|x| *x = DVec3::ZERO);
        for l in leaves {
            let avg = 0.25 * l.corners.iter().map(|&c| g[c as usize]).sum::<DVec3>();
            out[l.patch as usize] += l.area * avg;
        }
    }
}

/// Unshot radiosity of reflecting patch `s`: rho * (fine + coarse integral) / area - total,
/// clamped at zero per channel (see the module doc). [`set_unshot`] for one patch.
fn patch_unshot(
    tr: &Transfer<'_>,
    polys: &[Poly],
    totals: &[DVec3],
    base: &[DVec3],
    coarse: &[DVec3],
    s: usize,
) -> DVec3 {
    let sg = &tr.shooters[s];
    let ShooterKind::Patch { polygon, .. } = sg.kind else {
        return DVec3::ZERO;
    };
    let rho = polys[polygon as usize].rho;
    let b = if sg.area > 0.0 {
        rho * (base[s] + coarse[s]) / sg.area
    } else {
        DVec3::ZERO
    };
    (b - totals[s]).max(DVec3::ZERO)
}

/// Unshot radiosity of every reflecting patch: rho * (fine + coarse integral) / area - total,
/// clamped at zero per channel (see the module doc).
fn set_unshot(
    tr: &Transfer<'_>,
    polys: &[Poly],
    totals: &[DVec3],
    base: &[DVec3],
    coarse: &[DVec3],
    unshot: &mut [DVec3],
) {
    for (s, sg) in tr.shooters.iter().enumerate() {
        if let ShooterKind::Patch { polygon, .. } = sg.kind {
            let rho = polys[polygon as usize].rho;
            let b = if sg.area > 0.0 {
                rho * (base[s] + coarse[s]) / sg.area
            } else {
                DVec3::ZERO
            };
            unshot[s] = (b - totals[s]).max(DVec3::ZERO);
        }
    }
}

fn leaves_of(
    scene: &Scene,
    i: usize,
    tree: &Quadtree,
    keys: &[VertexKey],
    base: &[u32],
    depth: &[u32],
) -> Vec<Leaf> {
    let poly = &scene.polygons[i];
    let idx = |k: VertexKey| keys.binary_search(&k).map_or(0, |x| x as u32);
    tree.leaves()
        .into_iter()
        .map(|id| {
            let cell = tree.node(id).cell;
            let c = cell.corners();
            let patch = if base[i] == u32::MAX {
                u32::MAX
            } else {
                let d = depth[i];
                let sh = cell.level.saturating_sub(d);
                let n = 1u32 << d;
                base[i] + (cell.y >> sh) * n + (cell.x >> sh)
            };
            Leaf {
                corners: c.map(idx),
                area: sub_area(poly, cell),
                patch,
            }
        })
        .collect()
}

fn rebuild_leaves(scene: &Scene, i: usize, p: &mut Poly, base: &[u32], depth: &[u32]) {
    p.leaves = leaves_of(scene, i, &p.tree, &p.keys, base, depth);
}

/// Wall-clock helper kept here so the solver's timing has one definition.
pub fn elapsed_ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
