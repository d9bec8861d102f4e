//! Progressive refinement (shooting, Cohen et al. 1988) over adaptive, unrestricted quadtrees.
//!
//! State: per polygon an unrestricted [`Quadtree`], its vertex keys and a working irradiance G at
//! every vertex (f64); per shooter the total radiosity it has shot so far. Order of work:
//! 1. every polygon starts uniformly subdivided to `max(min_depth, its patch depth)` (patch
//!    depth <= 2, so a shooter patch is always a union of leaves);
//! 2. spot lights shoot, each once; emitters shoot their emission, in order of power;
//! 3. refine: a leaf splits when the true radiosity at its centre or an edge midpoint differs
//!    from the bilinear prediction of its corners by more than `tolerance * scale` (luminance),
//!    where `scale` is the area-weighted mean reflected radiosity of the reflecting polygons; new
//!    vertices gather from the whole history; T-vertices stay, the tree is never balanced;
//! 4. reflecting patches shoot their unshot radiosity (largest unshot power first, ties by id)
//!    until the unshot power falls below `convergence` times the emitted power;
//! 5. refine again; if that moved the unshot estimate above the threshold, shoot again (at most
//!    [`MAX_ROUNDS`] rounds);
//! 6. every vertex's stored value is recomputed by the oracle's gather over the final history, so a
//!    stored sample and the oracle agree bit for bit, whatever order the shots came in.
//!
//! Unshot radiosity of a patch = rho * (integral of G over the patch) / area - total shot, with the
//! integral taken over the patch's leaves by the trapezoid rule on their corners (T-vertices are
//! ignored there, which only changes the estimate, never a stored sample). It is clamped at zero
//! per channel: refinement can lower the integral below what was already shot, and shooting
//! negative light would create negative radiosity.
//!
//! Parallelism: rayon over receiver vertices (`par_iter` + `collect` in order); every float sum is
//! done serially in a fixed order, so the result is the same for any number of threads.

use std::collections::HashMap;
use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

use super::transfer::{build_shooters, spot_power, sub_area, ShooterKind, Transfer};
use crate::quadtree::{Cell, Quadtree, VertexKey};
use crate::scene::Scene;

/// Most shoot-then-refine rounds after the direct pass.
pub const MAX_ROUNDS: u32 = 3;

/// Luminance of linear RGB (Rec. 709 weights).
#[inline]
pub fn lum(c: DVec3) -> f64 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// One leaf, with what the unshot estimate needs.
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
    rho: DVec3,
}

/// What the solver hands back to `solve`.
pub struct Outcome {
    /// Per polygon: tree, keys, and G per key (final gather).
    pub trees: Vec<(Quadtree, Vec<VertexKey>)>,
    /// Per shooter: total radiosity shot.
    pub totals: Vec<DVec3>,
    /// Shooter kinds in id order.
    pub kinds: Vec<ShooterKind>,
    /// Shots taken.
    pub shots: u64,
    /// Unshot fraction after every shot.
    pub history: Vec<f64>,
    /// Final unshot fraction.
    pub unshot: f64,
    /// Emitted power (sum over channels).
    pub emitted: f64,
    /// Number of shots taken before each refinement pass.
    pub refined_after: Vec<u64>,
}

/// Progress callback: fraction done in [0, 1].
pub type ProgressFn<'p> = &'p (dyn Fn(f64) + Sync);

/// Runs the whole solve and returns trees and the shooting history. `tr` must be built on `scene`.
pub fn run(scene: &Scene, tr: &mut Transfer<'_>, progress: ProgressFn<'_>) -> Outcome {
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
            let depth = st.min_depth.max(patch_depth[i]).min(st.max_depth);
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
            let keys = tree.vertex_keys();
            Poly {
                g: vec![DVec3::ZERO; keys.len()],
                tree,
                keys,
                leaves: Vec::new(),
                rho: scene.material_of(i).reflectance,
            }
        })
        .collect();
    for (i, p) in polys.iter_mut().enumerate() {
        rebuild_leaves(scene, i, p, &patch_base, &patch_depth);
    }

    // Emitted power and the initial unshot of spots and emitters.
    let mut emitted = 0.0;
    for (s, sg) in tr.shooters.iter().enumerate() {
        match sg.kind {
            ShooterKind::Spot { spot } => {
                let p = spot_power(&scene.spots[spot as usize]);
                emitted += p;
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
    let power = |tr: &Transfer<'_>, s: usize, u: DVec3| -> f64 {
        match tr.shooters[s].kind {
            ShooterKind::Spot { spot } => {
                if u == DVec3::ZERO {
                    0.0
                } else {
                    spot_power(&scene.spots[spot as usize])
                }
            }
            _ => tr.shooters[s].area * (u.x + u.y + u.z),
        }
    };
    let mut history = Vec::new();
    let mut shots = 0u64;
    let max_shots = 100 * ns as u64 + 100;
    let conv = st.convergence;
    let log_target = -(conv.max(1e-12)).ln();
    let report = |frac: f64| {
        let done = if frac <= 0.0 {
            1.0
        } else {
            (-frac.ln() / log_target).clamp(0.0, 1.0)
        };
        progress(done);
    };

    // Direct pass: spots in order, then emitters by power (ties by id).
    if emitted > 0.0 {
        let direct: Vec<usize> = (0..ns)
            .filter(|&s| !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }))
            .collect();
        let mut order = direct.clone();
        order.sort_by(|&a, &b| {
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
        for s in order {
            if power(tr, s, unshot[s]) <= 0.0 {
                continue;
            }
            shoot(scene, tr, &mut polys, s, unshot[s]);
            totals[s] += unshot[s];
            unshot[s] = DVec3::ZERO;
            shots += 1;
            update_unshot(&polys, &totals, &mut unshot, tr);
            let frac = unshot_fraction(tr, &unshot, emitted, &power);
            history.push(frac);
            report(frac);
        }
    }

    let trace = std::env::var_os("PFS_TRACE").is_some();
    let t0 = Instant::now();
    if trace {
        eprintln!(
            "direct done: shots {shots} rays {}",
            tr.rays.load(std::sync::atomic::Ordering::Relaxed)
        );
    }
    let mut refined_after = Vec::new();
    if emitted > 0.0 {
        refine(scene, tr, &mut polys, &totals, &patch_base, &patch_depth);
        refined_after.push(shots);
    }
    update_unshot(&polys, &totals, &mut unshot, tr);
    let mut frac = unshot_fraction(tr, &unshot, emitted, &power);
    if trace {
        eprintln!(
            "refine1 {:.0} ms verts {} rays {}",
            elapsed_ms(t0),
            polys.iter().map(|p| p.keys.len()).sum::<usize>(),
            tr.rays.load(std::sync::atomic::Ordering::Relaxed)
        );
    }

    let mut round = 0;
    while emitted > 0.0 && round < MAX_ROUNDS {
        round += 1;
        while frac >= conv && shots < max_shots {
            // Largest unshot power, ties by the smaller id.
            let mut best = None;
            let mut best_p = 0.0;
            for s in 0..ns {
                let p = power(tr, s, unshot[s]);
                if p > best_p {
                    best_p = p;
                    best = Some(s);
                }
            }
            let Some(s) = best else { break };
            let db = unshot[s];
            shoot(scene, tr, &mut polys, s, db);
            totals[s] += db;
            unshot[s] = DVec3::ZERO;
            shots += 1;
            update_unshot(&polys, &totals, &mut unshot, tr);
            frac = unshot_fraction(tr, &unshot, emitted, &power);
            history.push(frac);
            report(frac);
        }
        if trace {
            eprintln!(
                "shot {:.0} ms shots {shots} rays {}",
                elapsed_ms(t0),
                tr.rays.load(std::sync::atomic::Ordering::Relaxed)
            );
        }
        let splits = refine(scene, tr, &mut polys, &totals, &patch_base, &patch_depth);
        refined_after.push(shots);
        if trace {
            eprintln!(
                "refine {:.0} ms splits {splits} verts {} rays {}",
                elapsed_ms(t0),
                polys.iter().map(|p| p.keys.len()).sum::<usize>(),
                tr.rays.load(std::sync::atomic::Ordering::Relaxed)
            );
        }
        update_unshot(&polys, &totals, &mut unshot, tr);
        frac = unshot_fraction(tr, &unshot, emitted, &power);
        if splits == 0 || frac < conv || shots >= max_shots {
            break;
        }
    }
    report(1.0);
    Outcome {
        trees: polys.into_iter().map(|p| (p.tree, p.keys)).collect(),
        totals,
        kinds: tr.shooters.iter().map(|s| s.kind).collect(),
        shots,
        history,
        unshot: if emitted > 0.0 { frac } else { 0.0 },
        emitted,
        refined_after,
    }
}

fn unshot_fraction(
    tr: &Transfer<'_>,
    unshot: &[DVec3],
    emitted: f64,
    power: &impl Fn(&Transfer<'_>, usize, DVec3) -> f64,
) -> f64 {
    if emitted <= 0.0 {
        return 0.0;
    }
    let total: f64 = (0..unshot.len()).map(|s| power(tr, s, unshot[s])).sum();
    total / emitted
}

/// Shooter `s` shoots radiosity `db` (per-unit intensity scale for a spot) to every vertex.
fn shoot(scene: &Scene, tr: &mut Transfer<'_>, polys: &mut [Poly], s: usize, db: DVec3) {
    tr.ensure_pairs(s);
    let tr = &*tr;
    let classes = &tr.pairs[s].as_ref().expect("pairs computed above").class;
    let work: Vec<(u32, u32)> = polys
        .iter()
        .enumerate()
        .filter(|(r, p)| {
            classes[*r] != super::transfer::PairClass::Culled && p.rho.max_element() > 0.0
        })
        .flat_map(|(r, p)| (0..p.keys.len() as u32).map(move |k| (r as u32, k)))
        .collect();
    let _ = scene;
    let t: Vec<DVec3> = work
        .par_iter()
        .map(|&(r, k)| {
            let key = polys[r as usize].keys[k as usize];
            tr.transfer(s, r as usize, key.u(), key.v())
        })
        .collect();
    for (&(r, k), t) in work.iter().zip(t) {
        polys[r as usize].g[k as usize] += db * t;
    }
}

/// Recomputes the unshot radiosity of every reflecting patch from the vertices' G.
fn update_unshot(polys: &[Poly], totals: &[DVec3], unshot: &mut [DVec3], tr: &Transfer<'_>) {
    let mut integ: HashMap<u32, DVec3> = HashMap::new();
    for p in polys {
        if p.rho.max_element() <= 0.0 {
            continue;
        }
        for l in &p.leaves {
            let avg = 0.25 * l.corners.iter().map(|&c| p.g[c as usize]).sum::<DVec3>();
            *integ.entry(l.patch).or_insert(DVec3::ZERO) += l.area * avg;
        }
    }
    for (s, sg) in tr.shooters.iter().enumerate() {
        if let ShooterKind::Patch { polygon, .. } = sg.kind {
            let rho = polys[polygon as usize].rho;
            let i = integ.get(&(s as u32)).copied().unwrap_or(DVec3::ZERO);
            let b = if sg.area > 0.0 {
                rho * i / sg.area
            } else {
                DVec3::ZERO
            };
            // Clamp at zero per channel (see the module doc).
            unshot[s] = (b - totals[s]).max(DVec3::ZERO);
        }
    }
}

fn rebuild_leaves(scene: &Scene, i: usize, p: &mut Poly, base: &[u32], depth: &[u32]) {
    let poly = &scene.polygons[i];
    let idx = |k: VertexKey, keys: &[VertexKey]| keys.binary_search(&k).map_or(0, |x| x as u32);
    p.leaves = p
        .tree
        .leaves()
        .into_iter()
        .map(|id| {
            let cell = p.tree.node(id).cell;
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
                corners: [
                    idx(c[0], &p.keys),
                    idx(c[1], &p.keys),
                    idx(c[2], &p.keys),
                    idx(c[3], &p.keys),
                ],
                area: sub_area(poly, cell),
                patch,
            }
        })
        .collect();
}

/// Brightness scale for the subdivision test: the larger of
/// - the area-weighted mean luminance of the reflected radiosity rho * G over the reflecting
///   polygons, measured at the vertices, and
/// - the mean reflected radiosity the emitted luminous power would give if it fell evenly on the
///   reflecting area (first bounce only): `emitted_lum * mean_rho_lum / area`.
///
/// The second term keeps the scale meaningful when the initial vertices all miss the light (a
/// narrow spot falling between them): the measured mean is then 0 and would stop refinement.
fn brightness_scale(polys: &[Poly], emitted_lum: f64) -> f64 {
    let (mut num, mut den, mut rho_a) = (0.0, 0.0, 0.0);
    for p in polys {
        if lum(p.rho) <= 0.0 {
            continue;
        }
        for l in &p.leaves {
            let avg = 0.25 * l.corners.iter().map(|&c| p.g[c as usize]).sum::<DVec3>();
            num += l.area * lum(p.rho * avg);
            den += l.area;
            rho_a += l.area * lum(p.rho);
        }
    }
    if den > 0.0 && (num / den).is_finite() {
        let even = emitted_lum * (rho_a / den) / den;
        let even = if even.is_finite() { even } else { 0.0 };
        (num / den).max(even)
    } else {
        0.0
    }
}

/// Adaptive subdivision against the true radiosity; returns the number of splits.
fn refine(
    scene: &Scene,
    tr: &Transfer<'_>,
    polys: &mut [Poly],
    totals: &[DVec3],
    base: &[u32],
    depth: &[u32],
) -> usize {
    let st = &scene.radiosity;
    let thresh = st.tolerance * brightness_scale(polys, emitted_lum(scene, tr));
    if thresh <= 0.0 || !thresh.is_finite() {
        return 0;
    }
    let mut pending: Vec<(u32, u32)> = Vec::new();
    for (r, p) in polys.iter().enumerate() {
        if p.rho.max_element() <= 0.0 {
            // A non-reflecting polygon's radiosity is its constant emission.
            continue;
        }
        for id in p.tree.leaves() {
            if p.tree.node(id).cell.level < st.max_depth {
                pending.push((r as u32, id));
            }
        }
    }
    let mut splits = 0;
    while !pending.is_empty() {
        // Probe keys not yet vertices, per polygon, deduplicated and sorted.
        let mut probes: Vec<(u32, VertexKey)> = Vec::new();
        for &(r, id) in &pending {
            let p = &polys[r as usize];
            for k in test_points(p.tree.node(id).cell) {
                if p.keys.binary_search(&k).is_err() {
                    probes.push((r, k));
                }
            }
        }
        probes.sort_unstable();
        probes.dedup();
        let vals: Vec<DVec3> = probes
            .par_iter()
            .map(|&(r, k)| tr.gather(totals, r as usize, k.u(), k.v()))
            .collect();
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
            let pred = [
                0.25 * (c[0] + c[1] + c[2] + c[3]),
                0.5 * (c[0] + c[1]),
                0.5 * (c[1] + c[2]),
                0.5 * (c[2] + c[3]),
                0.5 * (c[3] + c[0]),
            ];
            let bad = tp.iter().zip(pred).any(|(&k, pr)| {
                let d = p.rho * (probe_g(r, k, polys) - pr);
                lum(d.abs()) > thresh
            });
            if bad {
                split_now.push((r, id));
            }
        }
        let mut next = Vec::new();
        let mut touched: Vec<u32> = Vec::new();
        for &(r, id) in &split_now {
            let p = &mut polys[r as usize];
            let f = p.tree.split(id);
            splits += 1;
            for c in f..f + 4 {
                if p.tree.node(c).cell.level < st.max_depth {
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
    splits
}

/// Emitted power in luminance (spots and emissive polygons).
fn emitted_lum(scene: &Scene, tr: &Transfer<'_>) -> f64 {
    let mut e = 0.0;
    for sg in &tr.shooters {
        match sg.kind {
            ShooterKind::Spot { spot } => {
                let s = &scene.spots[spot as usize];
                let sum = s.intensity.x + s.intensity.y + s.intensity.z;
                if sum > 0.0 {
                    e += spot_power(s) * lum(s.intensity) / sum;
                }
            }
            ShooterKind::Emitter { polygon } => {
                e += sg.area * lum(scene.material_of(polygon as usize).emission);
            }
            ShooterKind::Patch { .. } => {}
        }
    }
    e
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
