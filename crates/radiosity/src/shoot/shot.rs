//! One shot: a shooter's radiosity carried to the receiver points of the polygons it reaches
//! (every vertex in the direct pass, the coarse receivers in the indirect one), and the cache of
//! the patches' coarse transfers.

use glam::DVec3;
use rayon::prelude::*;

use super::poly::Poly;
use crate::transfer::{ShooterKind, Transfer};

/// Transfers of indirect shots to the coarse receiver points, kept per shooter (see `shoot`).
pub(crate) struct CoarseCache {
    /// Per shooter: its transfer to every coarse point of every non-culled reflecting polygon, in
    /// work order (polygon order, then coarse key order), rounded to `f32`.
    per: Vec<Option<Vec<f32>>>,
    /// Entries stored so far, and the most that may be stored.
    used: usize,
    budget: usize,
}

/// Most cached coarse transfers (4 bytes each: 512 MiB at most). Entries grow with the pairs
/// (about 9 per pair of a small polygon): 25 M for 10,000 polygons of rooms, 116 M for 40,000.
/// A patch whose transfers do not fit recomputes them at every shot, which dominates the
/// shooting time of a large scene.
pub const COARSE_CACHE_ENTRIES: usize = 128 << 20;

impl CoarseCache {
    /// An empty cache for `shooters` shooters, holding at most `budget` entries.
    pub(super) fn new(shooters: usize, budget: usize) -> Self {
        CoarseCache {
            per: vec![None; shooters],
            used: 0,
            budget,
        }
    }

    /// Bytes the cached transfers hold.
    pub(super) fn bytes(&self) -> u64 {
        4 * self.used as u64
    }

    /// Whether shooter `s`'s transfers are cached (a shot of it then computes none).
    pub(super) fn holds(&self, s: usize) -> bool {
        self.per[s].is_some()
    }

    /// Forgets shooter `s`'s transfers (its light changed shape: the next shot computes them
    /// again).
    pub(super) fn forget(&mut self, s: usize) {
        if let Some(t) = self.per[s].take() {
            self.used -= t.len();
        }
    }

    /// Keeps `t` as shooter `s`'s transfers if there is room; gives it back if not.
    fn store(&mut self, s: usize, t: Vec<f32>) -> Result<(), Vec<f32>> {
        if self.used + t.len() > self.budget {
            return Err(t);
        }
        self.used += t.len();
        self.per[s] = Some(t);
        Ok(())
    }
}

/// The receiver points of one shot, in work order (polygon order, then key order).
struct Points {
    /// Per point: its polygon and the index of its key (coarse key if `coarse`).
    at: Vec<(u32, u32)>,
    /// Per point: the pair's entry in the shooter's table.
    entry: Vec<u32>,
    coarse: bool,
}

impl Points {
    /// Every vertex (or coarse receiver, if `coarse`) of every reflecting polygon that shooter
    /// `s`'s pairs reach and `keep` keeps.
    fn of(
        tr: &Transfer<'_>,
        polys: &[Poly],
        s: usize,
        coarse: bool,
        keep: impl Fn(usize) -> bool,
    ) -> Points {
        let pairs = tr.pairs[s].as_ref().expect("pairs computed above");
        let keys = |p: &Poly| if coarse { p.ckeys.len() } else { p.keys.len() };
        let (at, entry) = pairs
            .receivers()
            .enumerate()
            .filter(|&(_, (r, _))| keep(r))
            .map(|(i, (r, _))| (i, r, &polys[r]))
            .filter(|(_, _, p)| p.reflects())
            .flat_map(|(i, r, p)| (0..keys(p) as u32).map(move |k| ((r as u32, k), i as u32)))
            .unzip();
        Points { at, entry, coarse }
    }

    /// Shooter `s`'s transfer to every point (in parallel, collected in order): at coarse
    /// receivers and concentrated shots' fine vertices as an indirect shot takes it
    /// ([`Transfer::coarse_transfer`]), at every vertex of a direct shot as the gather does.
    fn transfers(&self, tr: &Transfer<'_>, polys: &[Poly], s: usize, indirect: bool) -> Vec<DVec3> {
        self.at
            .par_iter()
            .zip(&self.entry)
            .map(|(&(r, k), &i)| {
                let p = &polys[r as usize];
                let key = if self.coarse {
                    p.ckeys[k as usize]
                } else {
                    p.keys[k as usize]
                };
                if indirect {
                    tr.coarse_transfer(s, r as usize, i as usize, key.u(), key.v())
                } else {
                    tr.transfer_at(s, r as usize, i as usize, key.u(), key.v())
                }
            })
            .collect()
    }
}

/// What one shot reached.
pub(super) struct Shot {
    /// The polygons that received it or own the shooter, ascending.
    pub touched: Vec<u32>,
    /// The polygons whose fine vertices received an indirect shot concentrated on them,
    /// ascending (see [`shoot`]).
    pub concentrated: Vec<u32>,
    /// Receiver points.
    pub points: usize,
}

/// The receiver points of an indirect shot of one shooter: the coarse receivers of the
/// polygons it reaches, and the fine vertices of those it concentrates its light on.
pub(super) struct Plan {
    shot: Shot,
    coarse: Points,
    fine: Points,
}

/// A shooter's transfers to a [`Plan`]'s coarse points and to its fine ones.
pub(super) type PlanTransfers = (Vec<DVec3>, Vec<DVec3>);

impl Plan {
    /// Where shooter `s` (whose pair table exists) shoots in the indirect pass.
    pub(super) fn of(tr: &Transfer<'_>, polys: &[Poly], s: usize) -> Plan {
        let touched = touched_polygons(tr, polys.len(), s);
        let concentrated: Vec<u32> = touched
            .iter()
            .copied()
            .filter(|&r| {
                let p = &polys[r as usize];
                p.reflects() && tr.concentrated(s, r as usize, p.coarse_spacing)
            })
            .collect();
        let is_concentrated = |r: usize| concentrated.binary_search(&(r as u32)).is_ok();
        let coarse = Points::of(tr, polys, s, true, |r| !is_concentrated(r));
        let fine = Points::of(tr, polys, s, false, is_concentrated);
        Plan {
            shot: Shot {
                points: coarse.at.len() + fine.at.len(),
                touched,
                concentrated,
            },
            coarse,
            fine,
        }
    }

    /// Shooter `s`'s transfers to the coarse points and to the fine ones, as they are now.
    pub(super) fn transfers(&self, tr: &Transfer<'_>, polys: &[Poly], s: usize) -> PlanTransfers {
        (
            self.coarse.transfers(tr, polys, s, true),
            self.fine.transfers(tr, polys, s, true),
        )
    }

    /// Adds `db` times `new - old` (pairs of [`Plan::transfers`]) to the points' light: the
    /// change of what a shooter's total delivers when its transfers change (its shape did).
    /// What it reached.
    pub(super) fn add_change(
        self,
        polys: &mut [Poly],
        db: DVec3,
        old: PlanTransfers,
        new: PlanTransfers,
    ) -> Shot {
        for ((&(r, k), o), n) in self.coarse.at.iter().zip(old.0).zip(new.0) {
            polys[r as usize].cg[k as usize] += db * (n - o);
        }
        for ((&(r, k), o), n) in self.fine.at.iter().zip(old.1).zip(new.1) {
            polys[r as usize].ng[k as usize] += db * (n - o);
        }
        self.shot
    }
}

/// Shooter `s` shoots radiosity `db` (per unit intensity scale for a spot) to every vertex, or,
/// if `cache` is given (an indirect shot), to the coarse receiver points, except on the
/// polygons where its light is concentrated on a few coarse cells
/// ([`Transfer::concentrated`]: a panel 2 cm under a ceiling lights a spot of the ceiling
/// smaller than the ceiling's coarse cells, whose trapezoid rule would count that spot's light
/// over a whole cell), whose fine vertices receive it instead (`Poly::ng`, not cached: the
/// fine vertices change with every refinement).
///
/// Coarse shots go to a fixed set of points (the coarse receivers never change during a solve),
/// and a patch shoots several times in an enclosed scene (about 4.7 times on average in the
/// gallery: 4440 indirect shots by 946 patches), so a shooter's coarse transfers are computed
/// once, rounded to `f32` (the rounding is applied on the first shot too, so a cached and a
/// computed shot add the same values) and reused while the cache has room. Coarse shots only estimate unshot power; stored
/// samples come from the full gather, which never uses this cache.
pub(super) fn shoot(
    tr: &mut Transfer<'_>,
    polys: &mut [Poly],
    s: usize,
    db: DVec3,
    cache: Option<&mut CoarseCache>,
) -> Shot {
    tr.ensure_pairs(s);
    let tr = &*tr;
    let Some(cache) = cache else {
        let points = Points::of(tr, polys, s, false, |_| true);
        let t = points.transfers(tr, polys, s, false);
        for (&(r, k), t) in points.at.iter().zip(t) {
            polys[r as usize].g[k as usize] += db * t;
        }
        return Shot {
            touched: touched_polygons(tr, polys.len(), s),
            concentrated: Vec::new(),
            points: points.at.len(),
        };
    };
    let plan = Plan::of(tr, polys, s);
    shoot_coarse(tr, polys, s, db, &plan.coarse, cache);
    if !plan.fine.at.is_empty() {
        let t = plan.fine.transfers(tr, polys, s, true);
        for (&(r, k), t) in plan.fine.at.iter().zip(t) {
            polys[r as usize].ng[k as usize] += db * t;
        }
    }
    plan.shot
}

/// The coarse half of [`shoot`]: a patch's transfers come from the cache (computed and stored
/// on its first shot, while there is room).
fn shoot_coarse(
    tr: &Transfer<'_>,
    polys: &mut [Poly],
    s: usize,
    db: DVec3,
    points: &Points,
    cache: &mut CoarseCache,
) {
    if !matches!(tr.shooters[s].kind, ShooterKind::Patch { .. }) {
        // Spots and emitters shoot to every vertex in the direct pass; should one ever shoot
        // coarse, its (coloured, for a spot) transfer is added unrounded.
        let t = points.transfers(tr, polys, s, true);
        for (&(r, k), t) in points.at.iter().zip(t) {
            polys[r as usize].cg[k as usize] += db * t;
        }
        return;
    }
    if !cache.holds(s) {
        // A patch's transfer is the same in every channel (F * V), so one f32 holds it.
        let t: Vec<f32> = points
            .transfers(tr, polys, s, true)
            .into_iter()
            .map(|t| t.x as f32)
            .collect();
        if let Err(t) = cache.store(s, t) {
            add_coarse(polys, &points.at, &t, db);
            return;
        }
    }
    if let Some(t) = &cache.per[s] {
        add_coarse(polys, &points.at, t, db);
    }
}

/// Adds `db` times the rounded transfers `t` to the coarse receivers `at`.
fn add_coarse(polys: &mut [Poly], at: &[(u32, u32)], t: &[f32], db: DVec3) {
    for (&(r, k), &t) in at.iter().zip(t) {
        polys[r as usize].cg[k as usize] += db * t as f64;
    }
}

/// The polygons shooter `s` reaches, and its own (of `polygons`), ascending.
fn touched_polygons(tr: &Transfer<'_>, polygons: usize, s: usize) -> Vec<u32> {
    let pairs = tr.pairs[s].as_ref().expect("pairs computed above");
    let mut touched: Vec<u32> = pairs.receivers().map(|(r, _)| r as u32).collect();
    let own = tr.shooters[s].polygon;
    if (own as usize) < polygons {
        if let Err(i) = touched.binary_search(&own) {
            touched.insert(i, own);
        }
    }
    touched
}
