//! What a gather learns at a receiver point from the geometry alone, kept for the next gather
//! at the same point. Per shooter that reaches the point: its uniform transfer there, its
//! unoccluded form factor and what the point sees of it. A solve gathers at the same points
//! again and again: every round gathers every vertex, every refinement pass gathers the test
//! points of the leaves it judges, and a test point becomes a vertex when its leaf splits.
//! Between those gathers only the light changes (the shooters' totals and the patches'
//! shapes), so a kept point pays only for that part: the shaped corrections, and the region a
//! partly hidden patch is seen through where a correction needs it and it was not kept.
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
//! - the region of a patch seen in part is kept once a correction has used it (the pieces of
//!   the smaller of its visible and hidden regions, all a correction reads: about 100 bytes,
//!   against rebuilding it past every occluder, a fifth of the Cornell box's solve), and a
//!   point whose gather built one it had not kept is kept again with it. The pieces are the
//!   built view's own coordinates, so a restored view answers as the built one did, bit for
//!   bit;
//! - the cache holds at most its byte budget, and what does not fit is computed again. Points
//!   are kept between parallel phases in the order of the points, so what it holds (and the
//!   rays and exact queries counted) does not depend on the thread count.
//!
//! [`Transfer::transfer_at`]: super::Transfer::transfer_at

use std::collections::HashMap;

use glam::DVec2;

use super::visibility::Look;
use crate::visible::{Region, Sight};
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
    /// Partly seen by the exact query (the region is kept beside the entries once a
    /// correction has used it, else built again where one needs it): the transfer and the
    /// form factor.
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
    /// The regions kept of shooters seen in part (none at most points: boxed).
    regions: Option<Box<Regions>>,
}

/// The regions of a point's partly seen shooters, ascending by shooter.
#[derive(Debug, Default, Clone)]
struct Regions {
    /// Per region its shooter, its [`Region`] and piece count (`which | count << 1`), and each
    /// piece's vertex count ...
    heads: Vec<u32>,
    /// ... and the pieces' vertices, in the same order.
    coords: Vec<DVec2>,
}

impl Regions {
    fn bytes(&self) -> usize {
        self.heads.len() * 4 + self.coords.len() * 16
    }
}

/// A region kept at a point ([`Walk::region`]): which of the view's two regions it is, and
/// its pieces.
pub(crate) struct KeptRegion<'a> {
    pub(crate) which: Region,
    lens: &'a [u32],
    coords: &'a [DVec2],
}

impl<'a> KeptRegion<'a> {
    /// The pieces' vertices, in the order they were kept.
    pub(crate) fn pieces(&self) -> impl Iterator<Item = &'a [DVec2]> + '_ {
        let mut at = 0;
        self.lens.iter().map(move |&n| {
            let piece = &self.coords[at..at + n as usize];
            at += n as usize;
            piece
        })
    }
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

    /// Keeps shooter `s`'s region `which` of the point's view, its `pieces` (after every
    /// region kept of a shooter below `s`).
    pub(crate) fn push_region<'p>(
        &mut self,
        s: u32,
        which: Region,
        pieces: impl Iterator<Item = &'p [DVec2]>,
    ) {
        let r = self.regions.get_or_insert_with(Box::default);
        let head = r.heads.len();
        r.heads.extend([s, 0]);
        let mut count = 0u32;
        for p in pieces {
            r.heads.push(p.len() as u32);
            r.coords.extend_from_slice(p);
            count += 1;
        }
        r.heads[head + 1] = u32::from(which == Region::Hidden) | count << 1;
    }

    /// Empties it, keeping its capacity.
    pub(crate) fn clear(&mut self) {
        self.ids.clear();
        self.vals.clear();
        if let Some(r) = &mut self.regions {
            r.heads.clear();
            r.coords.clear();
        }
    }

    /// A copy to keep, at its exact size (no box for regions if it holds none).
    pub(crate) fn to_kept(&self) -> Seen {
        Seen {
            ids: self.ids.clone(),
            vals: self.vals.clone(),
            regions: self
                .regions
                .as_ref()
                .filter(|r| !r.heads.is_empty())
                .cloned(),
        }
    }

    /// Bytes of its regions.
    fn region_bytes(&self) -> u64 {
        self.regions.as_ref().map_or(0, |r| r.bytes() as u64)
    }

    /// Bytes it holds once kept.
    fn bytes(&self) -> u64 {
        (self.ids.len() * 4 + self.vals.len() * 8) as u64 + self.region_bytes() + POINT_BYTES
    }

    /// A reader of the entries in shooter order.
    pub(crate) fn walk(&self) -> Walk<'_> {
        Walk {
            ids: &self.ids,
            vals: &self.vals,
            at: 0,
            val: 0,
            regions: self.regions.as_ref().map_or(&[], |r| &r.heads),
            coords: self.regions.as_ref().map_or(&[], |r| &r.coords),
            region_at: 0,
            coord_at: 0,
        }
    }
}

/// Reads a point's entries in shooter order ([`Walk::find`]).
pub(crate) struct Walk<'a> {
    ids: &'a [u32],
    vals: &'a [f64],
    at: usize,
    val: usize,
    regions: &'a [u32],
    coords: &'a [DVec2],
    region_at: usize,
    coord_at: usize,
}

impl<'a> Walk<'a> {
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

    /// Shooter `s`'s region, if kept; `s` must not be below the shooter of the previous call
    /// (the entries and the regions are read independently).
    pub(crate) fn region(&mut self, s: u32) -> Option<KeptRegion<'a>> {
        while let Some(&shooter) = self.regions.get(self.region_at) {
            if shooter > s {
                return None;
            }
            let head = self.regions[self.region_at + 1];
            let count = (head >> 1) as usize;
            let lens = &self.regions[self.region_at + 2..self.region_at + 2 + count];
            let n: usize = lens.iter().map(|&l| l as usize).sum();
            let coords = &self.coords[self.coord_at..self.coord_at + n];
            self.region_at += 2 + count;
            self.coord_at += n;
            if shooter == s {
                let which = if head & 1 == 1 {
                    Region::Hidden
                } else {
                    Region::Visible
                };
                return Some(KeptRegion {
                    which,
                    lens,
                    coords,
                });
            }
        }
        None
    }
}

/// Bytes one kept point costs besides its entries: its key, its two vectors' headers (24
/// bytes each), the regions' box and the hash table's control byte, rounded up to the slot's
/// alignment.
const POINT_BYTES: u64 = 72;

/// The kept points of a solve, per polygon, within a byte budget.
pub(crate) struct SeenCache {
    points: Vec<HashMap<VertexKey, Seen>>,
    bytes: u64,
    budget: u64,
    /// Bytes of the regions among `bytes`.
    region_bytes: u64,
    /// Whether it keeps regions: until the first point that does not fit. A point's entries
    /// save a whole gather's geometry, a region one rebuild, so once the budget is short the
    /// regions give their room to points (the gallery, whose points alone fill the budget,
    /// solved 9 % slower when regions displaced them).
    regions: bool,
}

/// The entries of a point with none kept.
static NONE: Seen = Seen {
    ids: Vec::new(),
    vals: Vec::new(),
    regions: None,
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
            region_bytes: 0,
            regions: true,
        }
    }

    /// The entries kept at point `k` of polygon `r` (none if the point is not kept).
    pub(crate) fn get(&self, r: usize, k: VertexKey) -> &Seen {
        self.points[r].get(&k).unwrap_or(&NONE)
    }

    /// Keeps `seen` at point `k` of polygon `r`, in place of what the point held, if the
    /// budget allows; the first point that does not fit drops every region kept, and no
    /// region is kept after (see [`SeenCache::keeps_regions`]).
    pub(crate) fn keep(&mut self, r: usize, k: VertexKey, mut seen: Seen) {
        if !self.regions {
            seen.regions = None;
        }
        let held = self.points[r].get(&k);
        let (old, old_regions) = held.map_or((0, 0), |h| (h.bytes(), h.region_bytes()));
        let new = seen.bytes();
        if self.bytes - old + new > self.budget {
            if !self.regions {
                return;
            }
            self.drop_regions();
            return self.keep(r, k, seen);
        }
        self.bytes = self.bytes - old + new;
        self.region_bytes = self.region_bytes - old_regions + seen.region_bytes();
        self.points[r].insert(k, seen);
    }

    /// Drops every kept region and keeps none after.
    fn drop_regions(&mut self) {
        for seen in self.points.iter_mut().flat_map(HashMap::values_mut) {
            seen.regions = None;
        }
        self.bytes -= self.region_bytes;
        self.region_bytes = 0;
        self.regions = false;
    }

    /// Whether the gathers should record the regions they use: the cache still keeps them.
    pub(crate) fn keeps_regions(&self) -> bool {
        self.regions
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
            self.region_bytes = 0;
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

    /// Regions read back as kept, in shooter order, each with its pieces, independently of
    /// the entries; a shooter without one reads as none, and the bytes count them.
    #[test]
    fn regions_read_back_as_written() {
        let a = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(0.0, 1.0),
        ];
        let b = [
            DVec2::new(2.0, 2.0),
            DVec2::new(3.0, 2.0),
            DVec2::new(3.0, 3.0),
            DVec2::new(2.0, 3.0),
        ];
        let mut seen = Seen::default();
        seen.push(4, 0.25, 0.5, Look::Exact(Sight::Part));
        seen.push(7, 0.125, 0.5, Look::Exact(Sight::Part));
        let before = seen.bytes();
        seen.push_region(4, Region::Hidden, [&a[..], &b[..]].into_iter());
        seen.push_region(7, Region::Visible, [&b[..]].into_iter());
        assert_eq!(
            seen.bytes() - before,
            (2 + 2 + 2 + 1) * 4 + (3 + 4 + 4) * 16
        );
        let mut walk = seen.walk();
        assert!(walk.region(3).is_none());
        let r = walk.region(4).expect("kept");
        assert_eq!(r.which, Region::Hidden);
        assert_eq!(r.pieces().collect::<Vec<_>>(), vec![&a[..], &b[..]]);
        assert_eq!(walk.find(7).map(|e| e.2), Some(Look::Exact(Sight::Part)));
        assert!(walk.region(5).is_none());
        let r = walk.region(7).expect("kept");
        assert_eq!(r.which, Region::Visible);
        assert_eq!(r.pieces().collect::<Vec<_>>(), vec![&b[..]]);
        assert!(walk.region(9).is_none());
    }

    /// Points keep their regions while everything fits; the first point that does not fit
    /// drops every region (their bytes given back) and is kept in their room, and regions
    /// offered after are not kept.
    #[test]
    fn regions_give_their_room_to_points() {
        let tri = [DVec2::ZERO, DVec2::X, DVec2::Y];
        let entry = |regions: bool| {
            let mut s = Seen::default();
            for k in 0..10 {
                s.push(k, 0.5, 0.75, Look::Exact(Sight::Part));
                if regions {
                    s.push_region(k, Region::Visible, [&tri[..]].into_iter());
                }
            }
            s.to_kept()
        };
        let (with, without) = (entry(true).bytes(), entry(false).bytes());
        assert_eq!(with - without, 10 * (3 * 4 + 3 * 16));
        let mut cache = SeenCache::new(1, 100, 2 * with);
        let k = |i| VertexKey::new(i, 0);
        cache.keep(0, k(0), entry(true));
        cache.keep(0, k(1), entry(true));
        assert!(cache.keeps_regions() && cache.bytes() == 2 * with);
        assert!(cache.get(0, k(0)).walk().region(3).is_some());
        cache.keep(0, k(2), entry(true));
        assert!(!cache.keeps_regions());
        assert_eq!(cache.bytes(), 3 * without, "three points, no region");
        assert!(cache.get(0, k(0)).walk().region(3).is_none());
        assert!(cache.get(0, k(2)).walk().region(3).is_none());
        assert_eq!(cache.get(0, k(2)).ids.len(), 10);
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
