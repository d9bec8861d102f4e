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

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::transfer::{
    build_shooters, spot_power, spot_power3, sub_area, PairClass, ShooterKind, Transfer,
};
use crate::error::{Error, Result};
use crate::progress::{Observer, Stage};
use crate::quadtree::{Cell, Quadtree, VertexKey};
use crate::scene::Scene;

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
    (std::mem::size_of::<crate::quadtree::Node>() + std::mem::size_of::<Leaf>()) as u64;

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
        for &r in &touched {
            for p in patches_of(r as usize) {
                unshot[p] = patch_unshot(tr, &polys, &totals, &base, &coarse, p);
                set_q(&mut queue, tr, p, unshot[p]);
            }
        }
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
        set_unshot(tr, &polys, &totals, &base, &coarse, &mut unshot);
        for (s, u) in unshot.iter().enumerate() {
            set_q(&mut queue, tr, s, *u);
        }
        frac = frac_of(&queue);
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
                            crate::error::human_bytes(tr.pair_bytes())
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
            for &r in &touched {
                for p in patches_of(r as usize) {
                    unshot[p] = patch_unshot(tr, &polys, &totals, &base, &coarse, p);
                    set_q(&mut queue, tr, p, unshot[p]);
                }
            }
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
        set_unshot(tr, &polys, &totals, &base, &coarse, &mut unshot);
        for (s, u) in unshot.iter().enumerate() {
            set_q(&mut queue, tr, s, *u);
        }
        frac = frac_of(&queue);
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

/// The solve's remaining-time estimate while it shoots. The shots left to the round's target
/// are extrapolated from the number of shots per unit of ln(unshot fraction) over the last
/// [`ETA_WINDOW`] reports (the fraction falls about geometrically in shots); of those, as many
/// as there are patches with unshot light that have not shot yet are priced at the measured
/// cost of a first shot (which finds the shooter's receivers and computes its transfers), the
/// rest at the measured cost of a repeated one (cached transfers): pricing all shots alike
/// overestimated by 2-3 times, the first shots being the slow ones. Then the round's gather:
/// its transfers (every vertex times the shooters that reach it) at the time per transfer
/// that the shots which computed theirs measured. It covers the current round; refinement and
/// a further round, which the solve cannot know it will need, are not in it (the gather
/// reports its own remaining time when it runs).
struct Eta {
    /// (shots this round, ln unshot fraction) at recent reports.
    recent: std::collections::VecDeque<(u64, f64)>,
    last: Option<Instant>,
    /// Shots this round, and the time and count of first and of repeated shots (all rounds).
    shots: u64,
    first: (f64, u64),
    repeat: (f64, u64),
    transfer_secs: f64,
    transfers: u64,
}

/// Reports whose rate the shooting estimate extrapolates (5 s at [`ETA_INTERVAL`]).
const ETA_WINDOW: usize = 10;

/// Seconds between two remaining-time reports.
const ETA_INTERVAL: f64 = 0.5;

impl Eta {
    fn new() -> Eta {
        Eta {
            recent: std::collections::VecDeque::new(),
            last: None,
            shots: 0,
            first: (0.0, 0),
            repeat: (0.0, 0),
            transfer_secs: 0.0,
            transfers: 0,
        }
    }

    /// A new shooting phase starts (after a gather).
    fn phase_start(&mut self) {
        self.recent.clear();
        self.last = None;
        self.shots = 0;
    }

    fn transfers(&mut self, n: usize, secs: f64) {
        self.transfers += n as u64;
        self.transfer_secs += secs;
    }

    fn shot_took(&mut self, first: bool, secs: f64) {
        self.shots += 1;
        let c = if first {
            &mut self.first
        } else {
            &mut self.repeat
        };
        c.0 += secs;
        c.1 += 1;
    }

    #[allow(clippy::too_many_arguments)]
    fn shot(
        &mut self,
        stage: &Stage<'_>,
        tr: &Transfer<'_>,
        polys: &[Poly],
        unshot: &[DVec3],
        frac: f64,
        target: f64,
        round: u32,
    ) {
        if self
            .last
            .is_some_and(|l| l.elapsed().as_secs_f64() < ETA_INTERVAL)
        {
            return;
        }
        self.last = Some(Instant::now());
        let now = (self.shots, frac.ln());
        if self.recent.len() == ETA_WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back(now);
        let Some(&(s0, l0)) = self.recent.front() else {
            return;
        };
        let fallen = l0 - now.1;
        if fallen.is_nan() || fallen <= 0.0 || self.transfers == 0 {
            return;
        }
        let left = if frac > target {
            (now.0 - s0) as f64 / fallen * (frac / target).ln()
        } else {
            0.0
        };
        let mean = |(t, n): (f64, u64)| if n > 0 { t / n as f64 } else { 0.0 };
        let unpaired = (0..tr.shooters.len())
            .filter(|&s| tr.pairs[s].is_none() && unshot[s] != DVec3::ZERO)
            .count() as f64;
        let firsts = left.min(unpaired);
        let repeat = if self.repeat.1 > 0 {
            mean(self.repeat)
        } else {
            mean(self.first)
        };
        let shooting = firsts * mean(self.first) + (left - firsts) * repeat;
        let gather: f64 = polys
            .iter()
            .enumerate()
            .filter(|(_, p)| p.rho.max_element() > 0.0)
            .map(|(r, p)| (p.keys.len() * tr.shooters_of(r).len()) as f64)
            .sum();
        let per = self.transfer_secs / self.transfers as f64;
        stage.remaining(&format!("round {round} shooting"), shooting + gather * per);
    }
}

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

/// The shooters' unshot power (per channel, W) and the selection key (the sum over channels of
/// unshot power relative to each channel's emitted power) in a tournament tree: the largest key
/// (ties to the smaller id, as a scan in id order would pick) and the total power, each
/// updated in O(log n) when one shooter changes. The total is summed in the tree's fixed
/// shape, so it does not depend on the order of updates.
struct UnshotQueue {
    /// Leaves start at `size`; node k has children 2k and 2k + 1.
    power: Vec<DVec3>,
    best: Vec<(f64, u32)>,
    size: usize,
}

impl UnshotQueue {
    fn new(n: usize) -> Self {
        let size = n.next_power_of_two().max(1);
        UnshotQueue {
            power: vec![DVec3::ZERO; 2 * size],
            best: vec![(0.0, u32::MAX); 2 * size],
            size,
        }
    }

    fn set(&mut self, s: usize, power: DVec3, key: f64) {
        let mut k = self.size + s;
        self.power[k] = power;
        // Only a positive key can be selected (a NaN never is).
        self.best[k] = (if key > 0.0 { key } else { 0.0 }, s as u32);
        while k > 1 {
            k /= 2;
            let (l, r) = (self.best[2 * k], self.best[2 * k + 1]);
            self.best[k] = if r.0 > l.0 { r } else { l };
            self.power[k] = self.power[2 * k] + self.power[2 * k + 1];
        }
    }

    /// The shooter with the largest positive key, ties to the smaller id.
    fn best(&self) -> Option<usize> {
        let (k, s) = self.best[1];
        (k > 0.0).then_some(s as usize)
    }

    /// Unshot power of every shooter, per channel.
    fn total(&self) -> DVec3 {
        self.power[1]
    }
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

/// Floor of the refinement criterion, as a fraction of the brightest reflected radiosity
/// (luminance) sampled so far: an element's variation is judged relative to its own level, but
/// never to a level below this fraction of the peak, so that dark regions (where any noise is a
/// large relative change) do not refine to the depth limit.
pub const REFINE_FLOOR: f64 = 0.01;

/// The brightest reflected radiosity rho * G (luminance) at any vertex of a reflecting polygon.
fn peak_reflected(polys: &[Poly]) -> f64 {
    polys
        .iter()
        .filter(|p| lum(p.rho) > 0.0)
        .flat_map(|p| p.g.iter().map(|g| lum(p.rho * *g)))
        .fold(0.0, f64::max)
}

/// Adaptive subdivision against the true radiosity; returns the number of splits.
///
/// A leaf splits (below `max_depth` and above [`min_element_size`]) when either
/// - **variation**: at its centre or an edge midpoint the reflected radiosity rho * G differs
///   from the bilinear prediction of its corners by more than `tolerance * level` (luminance of
///   the per-channel difference), `level` being the larger of the leaf's own level (the mean
///   luminance of rho * G over its corners and test points) and [`REFINE_FLOOR`] times the
///   peak; nothing in this test depends on the polygon's area or shape, so thin and small
///   polygons refine like large ones; or
/// - **visibility**: for a light (spot or emitter) with occluders between it and the polygon,
///   the visible fraction of the light differs across the leaf's corners and test points (a
///   shadow boundary crosses it) and the light's unshadowed contribution times that difference
///   exceeds the same `tolerance * level`: the leaf is split toward the boundary, down to the
///   depth limit, even where the bilinear prediction happens to agree at the test points.
fn refine(
    scene: &Scene,
    tr: &Transfer<'_>,
    polys: &mut [Poly],
    totals: &[DVec3],
    (base, depth): (&[u32], &[u32]),
    memory_limit: u64,
) -> Result<usize> {
    let st = &scene.radiosity;
    let tol = st.tolerance;
    if tol <= 0.0 || !tol.is_finite() {
        return Ok(0);
    }
    // The memory guard: nodes and samples held now, and the pair tables built so far (they do
    // not grow while refining).
    let mut nodes: u64 = polys.iter().map(|p| p.tree.nodes().len() as u64).sum();
    let mut vertices: u64 = polys.iter().map(|p| p.keys.len() as u64).sum();
    let pair_bytes = tr.pair_bytes();
    let mut peak = peak_reflected(polys);
    // The lights that have shot (their shadows drive the visibility test) and, per polygon,
    // those whose pairs with it may be occluded, ascending (from the per-receiver index, so
    // this costs the pairs, not lights x polygons).
    let is_light: Vec<bool> = (0..tr.shooters.len())
        .map(|s| {
            !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }) && totals[s] != DVec3::ZERO
        })
        .collect();
    let shadow_lights: Vec<Vec<usize>> = (0..polys.len())
        .map(|r| {
            tr.shooters_of(r)
                .iter()
                .map(|&(s, _)| s as usize)
                .filter(|&s| {
                    is_light[s]
                        && tr.pairs[s]
                            .as_ref()
                            .is_some_and(|p| p.class(r) == PairClass::Occluded)
                })
                .collect()
        })
        .collect();
    let min_size = min_element_size(scene);
    let mut pending: Vec<(u32, u32)> = Vec::new();
    for (r, p) in polys.iter().enumerate() {
        if p.rho.max_element() <= 0.0 {
            // A non-reflecting polygon's radiosity is its constant emission.
            continue;
        }
        for id in p.tree.leaves() {
            if can_split(scene, r, p.tree.node(id).cell, min_size) {
                pending.push((r as u32, id));
            }
        }
    }
    let mut splits = 0;
    while !pending.is_empty() {
        // Probe keys not yet vertices, per polygon, deduplicated and sorted.
        let mut probes: Vec<(u32, VertexKey)> = Vec::new();
        // Every point (corners and test points) of a pending leaf that some light's shadow
        // may cross.
        let mut shadow_keys: Vec<(u32, VertexKey)> = Vec::new();
        for &(r, id) in &pending {
            let p = &polys[r as usize];
            let cell = p.tree.node(id).cell;
            for k in test_points(cell) {
                if p.keys.binary_search(&k).is_err() {
                    probes.push((r, k));
                }
            }
            if !shadow_lights[r as usize].is_empty() {
                shadow_keys.extend(
                    cell.corners()
                        .iter()
                        .chain(&test_points(cell))
                        .map(|&k| (r, k)),
                );
            }
        }
        probes.sort_unstable();
        probes.dedup();
        shadow_keys.sort_unstable();
        shadow_keys.dedup();
        let vals: Vec<DVec3> = probes
            .par_iter()
            .map(|&(r, k)| tr.gather(totals, r as usize, k.u(), k.v()))
            .collect();
        // Per shadow key and light (in `lights` order; lights without occluders toward the
        // polygon are skipped): the unshadowed reflected luminance and the visible fraction.
        let shadows: Vec<Vec<(f64, f64)>> = shadow_keys
            .par_iter()
            .map(|&(r, k)| {
                let rho = polys[r as usize].rho;
                shadow_lights[r as usize]
                    .iter()
                    .map(|&s| {
                        let (open, vis) = tr.shadowed(s, r as usize, k.u(), k.v());
                        (lum(rho * totals[s] * open), vis)
                    })
                    .collect()
            })
            .collect();
        for (&(r, _), g) in probes.iter().zip(&vals) {
            peak = peak.max(lum(polys[r as usize].rho * *g));
        }
        let floor = REFINE_FLOOR * peak;
        let probe_g = |r: u32, k: VertexKey, polys: &[Poly]| -> DVec3 {
            let p = &polys[r as usize];
            match p.keys.binary_search(&k) {
                Ok(i) => p.g[i],
                Err(_) => {
                    let i = probes
                        .binary_search(&(r, k))
                        .expect("every test point was probed");
                    vals[i]
                }
            }
        };
        let mut split_now: Vec<(u32, u32)> = Vec::new();
        for &(r, id) in &pending {
            let p = &polys[r as usize];
            let cell = p.tree.node(id).cell;
            let c = cell.corners().map(|k| probe_g(r, k, polys));
            let tp = test_points(cell);
            let t = tp.map(|k| probe_g(r, k, polys));
            let level = c.iter().chain(&t).map(|g| lum(p.rho * *g)).sum::<f64>() / 9.0;
            let thresh = tol * level.max(floor);
            let pred = [
                0.25 * (c[0] + c[1] + c[2] + c[3]),
                0.5 * (c[0] + c[1]),
                0.5 * (c[1] + c[2]),
                0.5 * (c[2] + c[3]),
                0.5 * (c[3] + c[0]),
            ];
            let varies = t.iter().zip(pred).any(|(g, pr)| {
                let d = p.rho * (*g - pr);
                lum(d.abs()) > thresh
            });
            let shadowed = !varies && !shadow_lights[r as usize].is_empty() && {
                let at = |k: VertexKey| {
                    let i = shadow_keys
                        .binary_search(&(r, k))
                        .expect("every point of a shadowed leaf was tested");
                    &shadows[i]
                };
                let pts: Vec<&Vec<(f64, f64)>> =
                    cell.corners().iter().chain(&tp).map(|&k| at(k)).collect();
                let n = pts.first().map_or(0, |v| v.len());
                (0..n).any(|j| {
                    let (mut lo, mut hi, mut open) = (f64::INFINITY, f64::NEG_INFINITY, 0f64);
                    for q in &pts {
                        let (a, v) = q[j];
                        lo = lo.min(v);
                        hi = hi.max(v);
                        open = open.max(a);
                    }
                    hi > lo && open * (hi - lo) > thresh
                })
            };
            if varies || shadowed {
                split_now.push((r, id));
            }
        }
        // Each split adds 4 nodes and at most 5 samples (4 edge midpoints and the centre).
        let k = split_now.len() as u64;
        let (n_after, v_after) = (nodes + 4 * k, vertices + 5 * k);
        let need = state_bytes(n_after, v_after).saturating_add(pair_bytes);
        if need > memory_limit {
            return Err(memory_error(
                scene,
                need,
                memory_limit,
                format!(
                    "{n_after} quadtree nodes and up to {v_after} samples in this refinement \
                     pass, pair tables {}",
                    crate::error::human_bytes(pair_bytes)
                ),
            ));
        }
        (nodes, vertices) = (n_after, v_after);
        let mut next = Vec::new();
        let mut touched: Vec<u32> = Vec::new();
        for &(r, id) in &split_now {
            let p = &mut polys[r as usize];
            let f = p.tree.split(id);
            splits += 1;
            for c in f..f + 4 {
                if can_split(scene, r as usize, p.tree.node(c).cell, min_size) {
                    next.push((r, c));
                }
            }
            touched.push(r);
        }
        touched.dedup();
        for &r in &touched {
            let keys = polys[r as usize].tree.vertex_keys();
            let g: Vec<DVec3> = keys.iter().map(|&k| probe_g(r, k, polys)).collect();
            let p = &mut polys[r as usize];
            p.keys = keys;
            p.g = g;
            rebuild_leaves(scene, r as usize, p, base, depth);
        }
        pending = next;
    }
    Ok(splits)
}

/// Smallest element edge worth splitting: the scene's bounding diagonal / 2^max_depth. Depth
/// limits are per polygon, so without this a small polygon (a 1 m floor tile in a 15 m hall)
/// would be refined to elements far smaller than a large one's at the same depth; with it,
/// `max_depth` means "the scene resolved to 1 / 2^max_depth of its size" everywhere.
pub fn min_element_size(scene: &Scene) -> f64 {
    let (lo, hi) = scene.bounds();
    (hi - lo).length() / (1u64 << scene.radiosity.max_depth.min(63)) as f64
}

/// Whether a leaf may split: below max_depth, and its longer world-space edge (at the cell's
/// centre) is longer than `min_size`.
///
/// Both tangents of a polygon are at most its longest edge long everywhere (for a quad a convex
/// combination of two opposite edges, for a triangle at most an edge), which bounds the depth
/// any of its leaves can reach: [`depth_bound`].
fn can_split(scene: &Scene, r: usize, cell: Cell, min_size: f64) -> bool {
    if cell.level >= scene.radiosity.max_depth {
        return false;
    }
    let (u0, v0, u1, v1) = cell.bounds();
    let (du, dv) = scene.polygons[r].tangents(0.5 * (u0 + u1), 0.5 * (v0 + v1));
    let w = u1 - u0;
    (du.length() * w).max(dv.length() * w) > min_size
}

/// The deepest level polygon `r`'s leaves can reach by refinement: `max_depth`, or less where
/// the polygon's longest edge `L` halved `d` times is already within the smallest element size
/// (`can_split` refuses a cell whose edges are all at most that). The starting depth may
/// exceed it (min_depth and shooter patches are imposed, not refined).
pub fn depth_bound(scene: &Scene, r: usize, min_size: f64) -> u32 {
    let vs = scene.polygons[r].vertices();
    let longest = (0..vs.len())
        .map(|i| (vs[(i + 1) % vs.len()] - vs[i]).length())
        .fold(0.0f64, f64::max);
    let max = scene.radiosity.max_depth;
    let mut d = 0;
    let mut edge = longest;
    while d < max && edge > min_size {
        edge *= 0.5;
        d += 1;
    }
    d
}

/// Centre and the four edge midpoints (bottom, right, top, left) of a cell.
fn test_points(cell: Cell) -> [VertexKey; 5] {
    let o = cell.origin();
    let s = cell.size();
    let h = s / 2;
    [
        VertexKey::new(o.i + h, o.j + h),
        VertexKey::new(o.i + h, o.j),
        VertexKey::new(o.i + s, o.j + h),
        VertexKey::new(o.i + h, o.j + s),
        VertexKey::new(o.i, o.j + h),
    ]
}

/// Wall-clock helper kept here so the solver's timing has one definition.
pub fn elapsed_ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

#[cfg(test)]
mod queue_tests {
    use super::*;
    use crate::radiosity::rng::Rng;

    /// The queue picks what a scan in id order picks (the largest positive key, ties to the
    /// smaller id, none when every key is 0) through random updates, with repeated keys so
    /// ties happen, and its total is the channel sums to rounding.
    #[test]
    fn queue_agrees_with_a_scan() {
        let n = 37;
        let mut q = UnshotQueue::new(n);
        let mut keys = vec![0.0f64; n];
        let mut pw = vec![DVec3::ZERO; n];
        let mut rng = Rng::new(3);
        for step in 0..2000 {
            let s = rng.below(n as u32) as usize;
            let k = if rng.below(4) == 0 {
                0.0
            } else {
                f64::from(rng.below(6))
            };
            let p = DVec3::new(k, 2.0 * k, rng.next_f64());
            keys[s] = k;
            pw[s] = p;
            q.set(s, p, k);
            let mut best = None;
            let mut best_k = 0.0;
            for (i, &x) in keys.iter().enumerate() {
                if x > best_k {
                    best_k = x;
                    best = Some(i);
                }
            }
            assert_eq!(q.best(), best, "step {step}");
            let sum: DVec3 = pw.iter().copied().sum();
            assert!(
                (q.total() - sum).abs().max_element() <= 1e-12 * (1.0 + sum.abs().max_element())
            );
        }
    }
}
