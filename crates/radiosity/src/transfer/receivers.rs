//! The receivers of each shooter: which polygons it can light, found once per shooter and
//! kept as a sparse pair table ([`Pairs`]), and the two ways of finding them. `exact` tests
//! every polygon, so its cost is shooters x polygons; `sampled` casts probe rays from the
//! shooter until the light on polygons they have not hit is estimated below a bound, and keeps
//! what they (and, for a patch, the patches around it) hit, their corner neighbours and the
//! polygons near the shooter, so its cost grows with what the shooter sees
//! ([`Transfer::probe`]); a light whose rays cannot bound what they miss takes every polygon.
//! Which one a scene uses
//! is [`sampled_visibility`]; the memory either may take before it runs is
//! [`pair_table_bound`].
//!
//! Invariants: a table lists receivers ascending, culled pairs left out; the probe set
//! depends only on the scene (streams seeded by scene seed, shooter id and round; a patch's
//! neighbourhood is fixed by its cell, its neighbours' hits are kept once probed), never on
//! threads or the order in which shooters ask for it.

use glam::DVec3;

use super::{PairClass, ShooterGeom, ShooterKind, Transfer};
use base::rng::{seed_of, Rng};
use scene::bvh::Aabb;
use scene::{Scene, Visibility};

/// Bytes of one shooter-receiver entry of a pair table (receiver id, candidate range), without
/// its candidate list. Culled pairs have no entry.
pub const PAIR_BYTES: u64 = 12;

/// The receivers of one shooter: every polygon it may light (culled pairs are left out), each
/// with its class and the polygons that may occlude it. Sparse, so that its size grows with
/// what the shooter reaches, not with the scene.
#[derive(Debug, Clone, Default)]
pub(crate) struct Pairs {
    /// Receiver polygons, ascending.
    pub(super) recv: Vec<u32>,
    /// Per entry of `recv`, the range of its candidates in `cands` (none: the pair is open).
    pub(super) range: Vec<(u32, u32)>,
    /// Occluder candidates, concatenated.
    pub(super) cands: Vec<u32>,
}

impl Pairs {
    pub(super) fn find(&self, r: usize) -> Option<usize> {
        self.recv.binary_search(&(r as u32)).ok()
    }
    /// Class of receiver polygon `r`.
    pub(crate) fn class(&self, r: usize) -> PairClass {
        match self.find(r) {
            None => PairClass::Culled,
            Some(i) if self.range[i].1 == 0 => PairClass::Open,
            Some(_) => PairClass::Occluded,
        }
    }
    /// Number of occluder candidates of receiver polygon `r`.
    pub(crate) fn cands_len(&self, r: usize) -> usize {
        self.find(r).map_or(0, |i| self.range[i].1 as usize)
    }
    /// Every receiver that is not culled, ascending, with its class.
    pub(crate) fn receivers(&self) -> impl Iterator<Item = (usize, PairClass)> + '_ {
        self.recv.iter().zip(&self.range).map(|(&r, &(_, n))| {
            let c = if n == 0 {
                PairClass::Open
            } else {
                PairClass::Occluded
            };
            (r as usize, c)
        })
    }
    pub(super) fn at(&self, i: usize) -> (PairClass, &[u32]) {
        let (a, n) = self.range[i];
        let c = if n == 0 {
            PairClass::Open
        } else {
            PairClass::Occluded
        };
        (c, &self.cands[a as usize..(a + n) as usize])
    }
    pub(super) fn bytes(&self) -> u64 {
        self.recv.len() as u64 * PAIR_BYTES + 4 * self.cands.len() as u64
    }
}

/// Scenes with at most this many (shooter, polygon) pairs classify every pair
/// ([`Visibility::Auto`] picks `exact`); larger ones find each shooter's receivers with probe
/// rays. 1 M pairs is about 1,000 polygons: the gallery (912,000 pairs) and the Cornell box
/// stay exact; a building of 3 x 3 rooms (1,233 polygons, 1.5 M pairs) solves in 14.5 s exact
/// and about 6 s sampled.
pub(crate) const EXACT_PAIRS_LIMIT: u64 = 1 << 20;

/// Whether a scene with `shooters` shooters finds receivers by probe rays: its
/// `radiosity.visibility`, and for `auto` whether shooters x polygons passes
/// [`EXACT_PAIRS_LIMIT`].
pub(crate) fn sampled_visibility(scene: &Scene, shooters: u64) -> bool {
    match scene.radiosity.visibility {
        Visibility::Exact => false,
        Visibility::Sampled => true,
        Visibility::Auto => {
            shooters.saturating_mul(scene.polygons.len() as u64) > EXACT_PAIRS_LIMIT
        }
    }
}

/// Bytes of the pair tables' entries before any is built, an upper bound: every pair with
/// exact visibility, and with sampled visibility as many receivers per shooter as it casts
/// probe rays (the distinct polygons they hit; the neighbours added to them and the occluder
/// candidates are not known in advance, and the solve's own guard counts them). `lights` of
/// the `shooters` are spots and emitters.
pub fn pair_table_bound(scene: &Scene, shooters: u64, lights: u64) -> u64 {
    let n = scene.polygons.len() as u64;
    let entry = PAIR_BYTES + 8;
    if !sampled_visibility(scene, shooters) {
        return shooters.saturating_mul(n).saturating_mul(entry);
    }
    let patch = n.min(PROBE_RAYS as u64);
    let light = n.min((PROBE_RAYS * LIGHT_PROBE_FACTOR) as u64);
    let patches = shooters.saturating_sub(lights);
    patches
        .saturating_mul(patch)
        .saturating_add(lights.saturating_mul(light))
        .saturating_mul(entry)
}

/// Probe rays per reflecting patch in sampled visibility (spots and emitters cast
/// [`LIGHT_PROBE_FACTOR`] times as many). See [`Transfer::probe`].
pub(crate) const PROBE_RAYS: usize = 2048;

/// A shooter keeps casting rounds of probe rays until it has cast at least this many per
/// distinct polygon hit, and until the light it has not found is bounded ([`MISSED_LIGHT`]).
pub(crate) const PROBES_PER_HIT: usize = 4;

/// Largest share of a light's power (a spot's or an emitter's) its probe rays may leave on
/// polygons they never hit, and of a reflecting patch's ([`MISSED_LIGHT_PATCH`]), estimated
/// by Good and Turing's unseen-species estimate: with N rays, the share of the shooter's light
/// (its cosine-weighted directions, which the rays sample) going to polygons no ray hit is
/// estimated, up to a bias below exp(-1) / N per such polygon, by N1 / N, N1 the polygons hit
/// exactly once (Good 1953). Rounds go on until the estimate is at most this; a light whose
/// rays reach [`MAX_PROBE_RAYS`] first takes every polygon as a candidate receiver (exact
/// visibility for that light alone: lights are few). 1,600 quads 0.4 wide floating under a
/// 40 x 40 area light were each missed with probability 0.55 by one round of rays, which the
/// rule of 4 rays per polygon hit alone accepted (the quads got 44 % of their light).
pub(crate) const MISSED_LIGHT: f64 = 1e-3;

/// [`MISSED_LIGHT`] for a reflecting patch, which falls back to nothing at the cap: patches
/// are many, and every patch of a polygon takes the receivers all its sibling patches found
/// ([`Transfer::probe`]), so a receiver is missed only if every sibling's rays miss it.
pub(crate) const MISSED_LIGHT_PATCH: f64 = 1e-2;

/// Most probe rays per shooter, over all rounds.
pub(crate) const MAX_PROBE_RAYS: usize = 32 * PROBE_RAYS;

/// Good and Turing's estimate of the share of the light leaving a shooter that its `cast`
/// probe rays have not found, from the polygons they hit with their counts (`hits`): the
/// polygons hit exactly once over the rays cast ([`MISSED_LIGHT`]).
pub(crate) fn unseen_share(hits: &[(u32, u32)], cast: usize) -> f64 {
    let once = hits.iter().filter(|&&(_, c)| c == 1).count();
    once as f64 / cast.max(1) as f64
}

/// The distinct polygons of the sorted list `all`, each with how often it occurs.
pub(crate) fn counted(all: &[u32]) -> Vec<(u32, u32)> {
    let mut out: Vec<(u32, u32)> = Vec::new();
    for &h in all {
        match out.last_mut() {
            Some((last, c)) if *last == h => *c += 1,
            _ => out.push((h, 1)),
        }
    }
    out
}

/// Spots and emitters light the scene directly and are few: they cast this many times
/// [`PROBE_RAYS`].
pub(crate) const LIGHT_PROBE_FACTOR: usize = 4;

/// Ray parameters (a share of the scene's reach) within which two hits are one point: a
/// polygon and its coincident reversed twin.
const COINCIDENT_T: f64 = 1e-12;

/// The face a ray meets first.
enum Face {
    /// No polygon.
    Miss,
    /// A polygon's front, which absorbs and reflects.
    Front,
    /// A polygon's back, which absorbs everything.
    Back,
}

impl Transfer<'_> {
    /// The candidate receivers of shooter `s`, ascending: the polygons its probe rays hit
    /// first (a reflecting patch: the rays of every patch of its polygon), every polygon
    /// sharing a corner with one of them or with the shooter's own polygon, and every polygon
    /// near the shooter (see below); `None` for a light whose rays could not bound the light
    /// they miss ([`MISSED_LIGHT`]): every polygon is then a candidate.
    ///
    /// Rays: rounds of [`PROBE_RAYS`] ([`LIGHT_PROBE_FACTOR`] times as many for a light),
    /// each from stratified points of the shooter (its cell's domain split into a grid, one
    /// jittered point per stratum) in cosine-distributed directions about its normal,
    /// stratified too and paired through a permutation (Latin hypercube); a spot casts from
    /// its position, uniformly over its cone. Rounds go on while fewer than
    /// [`PROBES_PER_HIT`] rays per distinct polygon hit have been cast or while the light
    /// still unseen is estimated above [`MISSED_LIGHT`] ([`MISSED_LIGHT_PATCH`] for a patch),
    /// at most [`MAX_PROBE_RAYS`]. All from streams seeded by (scene seed, shooter id, round),
    /// so the set depends only on the scene.
    ///
    /// Why this is enough: a polygon that receives a fraction f of the shooter's light (its
    /// cosine-weighted solid angle) is hit on average by f times the rays, and the share of
    /// light on polygons not yet hit is estimated from the rays themselves ([`unseen_share`]).
    /// A patch's siblings see nearly what it sees, so their union multiplies its rays by the
    /// patches of its polygon; and since light a missed polygon would receive is shared with
    /// its neighbours' (a wall cut into pieces), adding the neighbours of every hit recovers
    /// small pieces among visible ones.
    pub(crate) fn probe(&self, s: usize, found: &[(u32, u32)]) -> Option<Vec<u32>> {
        let sg = &self.shooters[s];
        let hits = match sg.kind {
            ShooterKind::Patch { .. } => found.to_vec(),
            _ => self.probe_hits(s)?,
        };
        let mut out: Vec<u32> = hits.iter().map(|&(h, _)| h).collect();
        for &(h, _) in &hits {
            out.extend_from_slice(&self.neighbours[h as usize]);
        }
        if !matches!(sg.kind, ShooterKind::Patch { .. }) {
            // A light's rays hit each of many small receivers (a grid of tiles, foliage) only
            // a few times; one they all missed has its neighbours hit: every polygon within
            // half its own size of a hit joins (a missed tile is lost only if the tiles around
            // it are missed too). Lights are few, so this costs little; a patch has its
            // siblings' rays instead.
            for &(h, _) in &hits {
                let b = Aabb::of(self.scene.polygons[h as usize].vertices());
                let grow = DVec3::splat(0.5 * (b.hi - b.lo).max_element());
                let around = Aabb {
                    lo: b.lo - grow,
                    hi: b.hi + grow,
                };
                self.bvh.for_each_overlapping(&around, |q| out.push(q));
            }
        }
        // Polygons at the shooter: a probe ray ignores hits closer than its blind zone (`T_EPS`
        // of four times the scene core's diagonal), so an emitter a hair in front of a wall would
        // never find the wall it lights most (`scenes/hard/light-touching.toml` lost half its
        // light).
        // Every polygon whose box comes within a tenth of the shooter's size (and at least
        // 1e-6 of the scene's) of the shooter's box is a receiver too.
        let pts: &[DVec3] = match sg.kind {
            ShooterKind::Spot { spot } => {
                std::slice::from_ref(&self.scene.spots[spot as usize].position)
            }
            _ => sg.outline.verts(),
        };
        let b = Aabb::of(pts);
        let grow = 0.1 * (b.hi - b.lo).max_element() + 1e-6 * self.reach / 4.0;
        let near = Aabb {
            lo: b.lo - DVec3::splat(grow),
            hi: b.hi + DVec3::splat(grow),
        };
        self.bvh.for_each_overlapping(&near, |q| out.push(q));
        if let Some(own) = self.neighbours.get(sg.polygon as usize) {
            out.extend_from_slice(own);
        }
        out.sort_unstable();
        out.dedup();
        out.retain(|&r| r != sg.polygon);
        Some(out)
    }

    /// The distinct polygons shooter `s`'s probe rays hit, ascending, after the rounds the
    /// stopping rule asks for (see [`Transfer::probe`]); `None` for a light that reached
    /// [`MAX_PROBE_RAYS`] with the unseen light still above [`MISSED_LIGHT`]. A patch stops at
    /// the cap whatever the estimate.
    pub(crate) fn probe_hits(&self, s: usize) -> Option<Vec<(u32, u32)>> {
        let is_light = !matches!(self.shooters[s].kind, ShooterKind::Patch { .. });
        let (n, bound) = if is_light {
            (PROBE_RAYS * LIGHT_PROBE_FACTOR, MISSED_LIGHT)
        } else {
            (PROBE_RAYS, MISSED_LIGHT_PATCH)
        };
        let mut all: Vec<u32> = Vec::new();
        let mut cast = 0usize;
        let mut round = 0u64;
        loop {
            all.extend(self.probe_round(s, n, round));
            all.sort_unstable();
            cast += n;
            round += 1;
            let hits = counted(&all);
            if cast >= PROBES_PER_HIT * hits.len() && unseen_share(&hits, cast) <= bound {
                return Some(hits);
            }
            if cast + n > MAX_PROBE_RAYS {
                return (!is_light).then_some(hits);
            }
        }
    }

    /// The shares of shooter `s`'s light that leave the scene (hitting no polygon) and that
    /// land on a polygon's back face, which absorbs all of it (a polygon is one-sided; a
    /// two-sided one's reversed twin lies in its plane, so a back face with a front face at
    /// the same distance is that front face): the weighted shares of `n` probe rays
    /// (stratified origins paired with stratified cosine directions, as
    /// [`Transfer::probe_round`] casts them, with a stream of their own), each weighted by
    /// the light it carries (the area element at its origin for a polygon, the intensity in
    /// its direction over the axis's for a spot; for a shaped patch, times its shape's weight
    /// there, so that the dark part of a patch half under a box sends no rays into the box).
    pub(crate) fn escape_share(&self, s: usize, n: usize) -> (f64, f64) {
        let sg = &self.shooters[s];
        // A sealed polygon's light all lands on its covers, which its rays, starting past
        // them, cannot see: on the faces it is sealed with, and on the backs of the others.
        if self.seals().is_sealed(sg.polygon) {
            return (0.0, self.seals().behind(sg.polygon));
        }
        let seed = seed_of(&[self.scene.radiosity.seed, s as u64, 0x6573_6361_7065]);
        let grid = (n as f64).sqrt().ceil() as usize;
        let mut rng = Rng::new(seed);
        let perm = strata_pairing(&mut rng, n);
        let (mut missed, mut behind, mut total) = (0.0, 0.0, 0.0);
        let g = grid as f64;
        for (i, &j) in perm.iter().enumerate() {
            let (o, d, w) = match sg.kind {
                ShooterKind::Spot { spot } => {
                    let (o, d) = self.probe_ray(sg, i, j as usize, grid, &mut rng);
                    let sp = &self.scene.spots[spot as usize];
                    let axis = sp.intensity.max_element();
                    let w = if axis > 0.0 {
                        sp.intensity_towards(d).max_element() / axis
                    } else {
                        0.0
                    };
                    (o, d, w)
                }
                _ => {
                    let p = &self.scene.polygons[sg.polygon as usize];
                    let (u0, v0, u1, v1) = sg.bounds;
                    let su = ((i % grid) as f64 + rng.next_f64()) / g;
                    let sv = (((i / grid) as f64 + rng.next_f64()) / g).min(1.0);
                    let (u, v) = (u0 + (u1 - u0) * su, v0 + (v1 - v0) * sv);
                    let j = j as usize;
                    let a = ((j % grid) as f64 + rng.next_f64()) / g;
                    let phi = 2.0 * std::f64::consts::PI * ((j / grid) as f64 + rng.next_f64()) / g;
                    let (t1, t2) = sg.normal.any_orthonormal_pair();
                    let d =
                        (t1 * phi.cos() + t2 * phi.sin()) * a.sqrt() + sg.normal * (1.0 - a).sqrt();
                    let shape = super::shape::shape_weight(self.shapes[s].as_ref(), su, sv);
                    (p.point(u, v), d, p.area_element(u, v) * shape)
                }
            };
            total += w;
            if w > 0.0 {
                match self.first_face(o, d, sg.polygon) {
                    Face::Miss => missed += w,
                    Face::Back => behind += w,
                    Face::Front => {}
                }
            }
        }
        if total > 0.0 {
            (missed / total, behind / total)
        } else {
            (0.0, 0.0)
        }
    }

    /// Which face the ray from `o` along unit `d` (within the scene's reach, skipping `skip`)
    /// meets first. A back face with a front face at the same parameter (within
    /// [`COINCIDENT_T`]) counts as that front face: the BVH breaks the tie by index, and a
    /// two-sided polygon's twin comes after the face it copies.
    fn first_face(&self, o: DVec3, d: DVec3, skip: u32) -> Face {
        let back = |k: u32| self.scene.polygons[k as usize].normal.dot(d) >= 0.0;
        let (ray, t0) = (d * self.reach, self.ray_t0);
        match self.bvh.first_hit_from(o, ray, t0, [skip, u32::MAX]) {
            None => Face::Miss,
            Some((k, _)) if !back(k) => Face::Front,
            Some((k, t)) => match self.bvh.first_hit_from(o, ray, t0, [skip, k]) {
                Some((k2, t2)) if (t2 - t).abs() <= COINCIDENT_T && !back(k2) => Face::Front,
                _ => Face::Back,
            },
        }
    }

    /// The first polygons hit by round `round` of `n` probe rays of shooter `s` (with
    /// repeats, in ray order).
    fn probe_round(&self, s: usize, n: usize, round: u64) -> Vec<u32> {
        use rayon::prelude::*;
        let sg = &self.shooters[s];
        let (reach, t0) = (self.reach, self.ray_t0);
        let seed = seed_of(&[self.scene.radiosity.seed, s as u64, 0x7072_6f62_6573, round]);
        let grid = (n as f64).sqrt().ceil() as usize;
        let mut rng = Rng::new(seed);
        let perm = strata_pairing(&mut rng, n);
        const CHUNK: usize = 64;
        (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .flat_map_iter(|c| {
                let mut rng = Rng::new(seed_of(&[seed, c as u64]));
                let perm = &perm;
                (c * CHUNK..((c + 1) * CHUNK).min(n)).filter_map(move |i| {
                    let (o, d) = self.probe_ray(sg, i, perm[i] as usize, grid, &mut rng);
                    let skip = [sg.polygon, u32::MAX];
                    self.bvh.first_hit_from(o, d * reach, t0, skip).map(|h| h.0)
                })
            })
            .collect()
    }

    /// Origin and unit direction of probe ray `i` (origin stratum `i`, direction stratum `j`).
    fn probe_ray(
        &self,
        sg: &ShooterGeom,
        i: usize,
        j: usize,
        grid: usize,
        rng: &mut Rng,
    ) -> (DVec3, DVec3) {
        let g = grid as f64;
        let a = ((j % grid) as f64 + rng.next_f64()) / g;
        let b = ((j / grid) as f64 + rng.next_f64()) / g;
        let phi = 2.0 * std::f64::consts::PI * b;
        match sg.kind {
            ShooterKind::Spot { spot } => {
                let sp = &self.scene.spots[spot as usize];
                let ca = sp.half_angle.cos().clamp(-1.0, 1.0);
                let cos = 1.0 - a * (1.0 - ca);
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let (t1, t2) = sp.direction.normalize_or_zero().any_orthonormal_pair();
                let d = sp.direction.normalize_or_zero() * cos
                    + (t1 * phi.cos() + t2 * phi.sin()) * sin;
                (sp.position, d)
            }
            _ => {
                let p = &self.scene.polygons[sg.polygon as usize];
                let (u0, v0, u1, v1) = sg.bounds;
                let su = ((i % grid) as f64 + rng.next_f64()) / g;
                let sv = ((i / grid) as f64 + rng.next_f64()) / g;
                let o = p.point(u0 + (u1 - u0) * su, v0 + (v1 - v0) * sv.min(1.0));
                let (t1, t2) = sg.normal.any_orthonormal_pair();
                let r = a.sqrt();
                let d = (t1 * phi.cos() + t2 * phi.sin()) * r + sg.normal * (1.0 - a).sqrt();
                (o, d)
            }
        }
    }
}

/// Most polygons sharing one corner for which [`corner_neighbours`] records them.
const MAX_SHARING: usize = 32;

/// Per polygon, the other polygons that share a corner with it (exact coordinates), ascending.
pub(super) fn corner_neighbours(scene: &Scene) -> Vec<Vec<u32>> {
    let key = |p: &DVec3| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
    let mut at: Vec<([u64; 3], u32)> = scene
        .polygons
        .iter()
        .enumerate()
        .flat_map(|(i, p)| p.vertices().iter().map(move |c| (key(c), i as u32)))
        .collect();
    at.sort_unstable();
    at.dedup();
    let mut out = vec![Vec::new(); scene.polygons.len()];
    let mut i = 0;
    while i < at.len() {
        let mut j = i;
        while j < at.len() && at[j].0 == at[i].0 {
            j += 1;
        }
        // A corner shared by more than MAX_SHARING polygons (the centre of a large fan) adds no
        // neighbours: the pass would cost its square, and such fans are rare in models.
        if j - i > MAX_SHARING {
            i = j;
            continue;
        }
        for a in &at[i..j] {
            for b in &at[i..j] {
                if a.1 != b.1 {
                    out[a.1 as usize].push(b.1);
                }
            }
        }
        i = j;
    }
    for l in &mut out {
        l.sort_unstable();
        l.dedup();
    }
    out
}

/// A random permutation of `0..n` (Fisher-Yates): probe ray `i` takes origin stratum `i` and
/// direction stratum `perm[i]`, so origins and directions are each stratified and paired at
/// random.
fn strata_pairing(rng: &mut Rng, n: usize) -> Vec<u32> {
    let mut perm: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        let j = rng.below(i as u32 + 1) as usize;
        perm.swap(i, j);
    }
    perm
}
