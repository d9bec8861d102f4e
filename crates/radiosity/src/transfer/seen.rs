//! What a gather learns at a receiver point from the geometry alone, kept for the next gather
//! at the same point. Per shooter that reaches the point: its uniform transfer there, its
//! unoccluded form factor and what the point sees of it. A solve gathers at the same points
//! again and again: every round gathers every vertex, every refinement pass gathers the test
//! points of the leaves it judges, and a test point becomes a vertex when its leaf splits.
//! Between those gathers only the light changes (the shooters' totals and the patches'
//! shapes), so a kept point pays only for that part: the shaped corrections, and the region a
//! partly hidden patch is seen through where a correction needs it.
//!
//! Invariants and why:
//! - an entry holds exactly the values the gather computes from (shooter, receiver point), and
//!   those depend on nothing that changes during a solve (the scene, the pair tables, built
//!   once per shooter). A gather from the cache therefore returns the bits a gather without it
//!   returns: the cache changes the time a solve takes, never its solution;
//! - an entry is the uniform transfer of an emitter or a patch, with or without a shape (the
//!   transfer [`Transfer::transfer_at`] computes too, in the same operations): a patch's
//!   entry from a round before it had a shape serves the rounds after;
//! - spot lights are not kept: their transfer is one shadow ray, cheaper than keeping it;
//! - an entry takes 4 bytes for its shooter and what the point sees of it, and only the
//!   values that kind needs: none for a shooter that sends nothing, the form factor for one
//!   seen whole, the transfer and the form factor for one seen in part (the gallery kept
//!   half the bytes a fixed record took);
//! - the cache holds at most its byte budget, and what does not fit is computed again. Points
//!   are kept between parallel phases in the order of the points, so what it holds (and the
//!   rays and exact queries counted) does not depend on the thread count.
//!
//! [`Transfer::transfer_at`]: super::Transfer::transfer_at

use std::collections::HashMap;

use super::visibility::Look;
use crate::visible::Sight;
use base::quadtree::VertexKey;

/// What the point sees of a shooter, as kept: the low [`HOW_BITS`] bits of an entry's id.
/// Most kinds imply part of the values: a shooter seen whole has its form factor as its
/// transfer, one that sends nothing has no value at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
enum How {
    /// The transfer is 0 (the shooter faces away, is hidden, or a culled pair): no value.
    Zero,
    /// Seen clear of every occluder, transfer = form factor: one value.
    Clear,
    /// Seen whole past its occluders, by the exact query: one value.
    All,
    /// Partly seen by the exact query (the region is built again where a correction needs
    /// it): the transfer and the form factor.
    Part,
    /// Partly seen through shadow rays: the transfer and the form factor.
    RaysPart,
    /// Seen whole through shadow rays: one value.
    RaysWhole,
}

impl How {
    /// Every kind, indexed by its bits.
    const ALL: [How; 6] = [
        How::Zero,
        How::Clear,
        How::All,
        How::Part,
        How::RaysPart,
        How::RaysWhole,
    ];

    /// How many values an entry of this kind holds.
    fn values(self) -> usize {
        match self {
            How::Zero => 0,
            How::Clear | How::All | How::RaysWhole => 1,
            How::Part | How::RaysPart => 2,
        }
    }
}

/// Bits of an entry's id that hold its [`How`]; the shooter is the rest.
const HOW_BITS: u32 = 3;

/// The entries of one point, ascending by shooter: one id per shooter (shooter and
/// [`How`]), and the values the kinds need, in the same order.
#[derive(Debug, Default, Clone)]
pub(crate) struct Seen {
    ids: Vec<u32>,
    vals: Vec<f64>,
}

impl Seen {
    /// Appends shooter `s`'s entry: uniform transfer `t`, unoccluded form factor `f`, `look`
    /// (after every shooter below `s`).
    pub(crate) fn push(&mut self, s: u32, t: f64, f: f64, look: Look) {
        let how = if t == 0.0 {
            How::Zero
        } else {
            match look {
                Look::Clear => How::Clear,
                Look::Exact(Sight::Part) => How::Part,
                Look::Exact(_) => How::All,
                Look::Rays(v) if v < 1.0 => How::RaysPart,
                Look::Rays(_) => How::RaysWhole,
            }
        };
        debug_assert!(s < u32::MAX >> HOW_BITS, "shooter ids fit beside the kind");
        self.ids.push(s << HOW_BITS | how as u32);
        match how.values() {
            0 => {}
            1 => {
                debug_assert_eq!(t, f, "a shooter seen whole sends its form factor");
                self.vals.push(f);
            }
            _ => self.vals.extend([t, f]),
        }
    }

    /// Empties it, keeping its capacity.
    pub(crate) fn clear(&mut self) {
        self.ids.clear();
        self.vals.clear();
    }

    /// Bytes it holds once kept.
    fn bytes(&self) -> u64 {
        (self.ids.len() * 4 + self.vals.len() * 8) as u64 + POINT_BYTES
    }

    /// A reader of the entries in shooter order.
    pub(crate) fn walk(&self) -> Walk<'_> {
        Walk {
            ids: &self.ids,
            vals: &self.vals,
            at: 0,
            val: 0,
        }
    }
}

/// Reads a point's entries in shooter order ([`Walk::find`]).
pub(crate) struct Walk<'a> {
    ids: &'a [u32],
    vals: &'a [f64],
    at: usize,
    val: usize,
}

impl Walk<'_> {
    /// Shooter `s`'s uniform transfer, unoccluded form factor and look, if kept; `s` must
    /// not be below the shooter of the previous call. A fraction found by rays comes back as
    /// a share of the same class (part, or whole): past the uniform transfer, which holds the
    /// fraction itself, a gather reads only the class.
    pub(crate) fn find(&mut self, s: u32) -> Option<(f64, f64, Look)> {
        while let Some(&id) = self.ids.get(self.at) {
            let shooter = id >> HOW_BITS;
            if shooter > s {
                return None;
            }
            let how = How::ALL[(id & ((1 << HOW_BITS) - 1)) as usize];
            let take = how.values();
            let vals = &self.vals[self.val..self.val + take];
            self.at += 1;
            self.val += take;
            if shooter < s {
                continue;
            }
            return Some(match how {
                How::Zero => (0.0, 0.0, Look::Clear),
                How::Clear => (vals[0], vals[0], Look::Clear),
                How::All => (vals[0], vals[0], Look::Exact(Sight::All)),
                How::RaysWhole => (vals[0], vals[0], Look::Rays(1.0)),
                How::Part => (vals[0], vals[1], Look::Exact(Sight::Part)),
                How::RaysPart => (vals[0], vals[1], Look::Rays(0.5)),
            });
        }
        None
    }
}

/// Bytes one kept point costs besides its entries: its key, the two boxed slices and the hash
/// table's slot and control byte, rounded up.
const POINT_BYTES: u64 = 48;

/// The kept points of a solve, per polygon, within a byte budget.
pub(crate) struct SeenCache {
    points: Vec<HashMap<VertexKey, Seen>>,
    bytes: u64,
    budget: u64,
}

/// The entries of a point with none kept.
static NONE: Seen = Seen {
    ids: Vec::new(),
    vals: Vec::new(),
};

impl SeenCache {
    /// An empty cache for `polygons` polygons and `shooters` shooters holding at most `budget`
    /// bytes (none if a shooter's id would not fit beside its kind).
    pub(crate) fn new(polygons: usize, shooters: usize, budget: u64) -> SeenCache {
        let fits = shooters <= (u32::MAX >> HOW_BITS) as usize;
        SeenCache {
            points: (0..polygons).map(|_| HashMap::new()).collect(),
            bytes: 0,
            budget: if fits { budget } else { 0 },
        }
    }

    /// The entries kept at point `k` of polygon `r` (none if the point is not kept).
    pub(crate) fn get(&self, r: usize, k: VertexKey) -> &Seen {
        self.points[r].get(&k).unwrap_or(&NONE)
    }

    /// Keeps `seen` at point `k` of polygon `r`, in place of what the point held, if the
    /// budget allows.
    pub(crate) fn keep(&mut self, r: usize, k: VertexKey, seen: Seen) {
        let old = self.points[r].get(&k).map_or(0, Seen::bytes);
        let new = seen.bytes();
        if self.bytes - old + new > self.budget {
            return;
        }
        self.bytes = self.bytes - old + new;
        self.points[r].insert(k, seen);
    }

    /// Whether it may keep more (while full, the gathers need not record what they see).
    pub(crate) fn has_room(&self) -> bool {
        self.bytes < self.budget
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Gives every byte back and keeps nothing more if the solve's own state, which the
    /// memory guard admits (`need` bytes under `limit`), could need the room.
    pub(crate) fn yield_to(&mut self, need: u64, limit: u64) {
        if need.saturating_add(self.budget) > limit {
            self.points.iter_mut().for_each(HashMap::clear);
            self.bytes = 0;
            self.budget = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every kind of entry reads back as written (a fraction found by rays by its class), a
    /// walk skips the shooters it is not asked for, and a shooter not kept reads as none.
    #[test]
    fn entries_read_back_as_written() {
        let written = [
            (2, 0.0, 0.7, Look::Exact(Sight::Nothing)),
            (3, 0.25, 0.25, Look::Clear),
            (5, 0.5, 0.5, Look::Exact(Sight::All)),
            (8, 0.125, 0.375, Look::Exact(Sight::Part)),
            (9, 0.2, 0.8, Look::Rays(0.25)),
            (11, 0.3, 0.3, Look::Rays(1.0)),
        ];
        let mut seen = Seen::default();
        for &(s, t, f, look) in &written {
            seen.push(s, t, f, look);
        }
        assert_eq!(seen.ids.len(), 6);
        assert_eq!(
            seen.vals.len(),
            1 + 1 + 2 + 2 + 1,
            "no value for a zero transfer"
        );
        let mut walk = seen.walk();
        assert_eq!(walk.find(1), None);
        assert_eq!(walk.find(3), Some((0.25, 0.25, Look::Clear)));
        assert_eq!(walk.find(4), None);
        assert_eq!(walk.find(8), Some((0.125, 0.375, Look::Exact(Sight::Part))));
        assert_eq!(walk.find(9), Some((0.2, 0.8, Look::Rays(0.5))));
        assert_eq!(walk.find(11), Some((0.3, 0.3, Look::Rays(1.0))));
        assert_eq!(walk.find(12), None);
        let mut walk = seen.walk();
        assert_eq!(walk.find(2).map(|e| e.0), Some(0.0));
        assert_eq!(walk.find(5), Some((0.5, 0.5, Look::Exact(Sight::All))));
    }

    /// The cache keeps no more than its budget, replaces a point's entries in place, and gives
    /// everything back when the solve's state needs the room.
    #[test]
    fn the_cache_holds_its_budget_and_yields() {
        let entry = |n: u32| {
            let mut s = Seen::default();
            for k in 0..n {
                s.push(k, 0.5, 0.5, Look::Clear);
            }
            s
        };
        let one = entry(10).bytes();
        let mut cache = SeenCache::new(2, 100, 2 * one);
        let k = |i| VertexKey::new(i, 0);
        cache.keep(0, k(0), entry(10));
        cache.keep(1, k(0), entry(10));
        assert_eq!(cache.bytes(), 2 * one);
        cache.keep(0, k(1), entry(10));
        assert_eq!(cache.get(0, k(1)).ids.len(), 0, "over the budget: not kept");
        cache.keep(0, k(0), entry(4));
        assert_eq!(cache.get(0, k(0)).ids.len(), 4, "replaced in place");
        assert!(cache.bytes() < 2 * one && cache.has_room());
        // Room for the state and the whole budget: kept.
        cache.yield_to(10 * one, 12 * one);
        assert_eq!(cache.bytes(), 2 * one - one + entry(4).bytes());
        cache.yield_to(10 * one, 12 * one - 1);
        assert_eq!((cache.bytes(), cache.has_room()), (0, false));
        assert_eq!(cache.get(1, k(0)).ids.len(), 0);
        assert_eq!(SeenCache::new(1, 1 << 30, 1 << 20).budget, 0);
    }
}
