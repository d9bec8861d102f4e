//! Binning in chunks: the frame's polygons are set up in chunks of [`chunk_size`] records, each
//! chunk binning its own non-empty records per region as it goes (while they are in cache), and
//! `join` concatenates the chunks' lists in chunk order into the per-renderer, per-region
//! lists the region tasks read.
//!
//! Invariant: the joined lists are exactly those of a sequential round-robin pass
//! ([`super::bin_round_robin_into`]): the k-th non-empty record overall goes to renderer
//! k mod R, and every list is in increasing record order. A chunk cannot know k (the records
//! before it are set up concurrently), so it files each record under its rank within the chunk
//! modulo R (its phase) and the join maps phase p of a chunk whose first non-empty record is
//! the b-th overall to renderer (b + p) mod R. The chunk size depends on the polygon count, not
//! on the thread count, and the joined lists do not depend on it anyway: they are the same for
//! any number of threads.

use rayon::prelude::*;

use super::region::RegionGrid;
use super::setup::Prim;

/// Most records per chunk: large enough that the per-chunk lists cost little, small enough
/// that a chunk's records are still in cache when it bins them.
pub const CHUNK: usize = 2048;

/// Records per chunk for a frame of `n` polygons: [`CHUNK`], or fewer for small scenes, so
/// that a scene of a thousand polygons still makes enough chunks for every thread (at least 64
/// records each). A function of `n` alone, and the bins do not depend on it anyway.
pub fn chunk_size(n: usize) -> usize {
    (n / 16).clamp(64, CHUNK)
}

/// One chunk's bins: `lists[phase][region]` (record indices, increasing) and its count of
/// non-empty records.
#[derive(Debug, Default)]
pub struct ChunkBins {
    lists: Vec<Vec<Vec<u32>>>,
    binned: usize,
    /// The view bounds of the chunk's polygons (see [`super::build_and_bin_into`]).
    pub(crate) bounds: super::ViewBounds,
}

impl ChunkBins {
    /// Empties the lists (keeping their capacity) for `grid` and `renderers` phases.
    pub(crate) fn reset(&mut self, grid: &RegionGrid, renderers: usize) {
        self.lists.resize_with(renderers, Vec::new);
        self.lists.truncate(renderers);
        for phase in &mut self.lists {
            phase.resize_with(grid.count(), Vec::new);
            phase.truncate(grid.count());
            for list in phase.iter_mut() {
                list.clear();
            }
        }
        self.binned = 0;
    }

    /// Bins the chunk's next non-empty record `p` (index `i`) under its phase.
    #[inline]
    pub(crate) fn push(&mut self, grid: &RegionGrid, i: u32, p: &Prim) {
        let phase = self.binned % self.lists.len();
        grid.bin_one(i, p, &mut self.lists[phase]);
        self.binned += 1;
    }
}

/// Joins the chunks' lists into `bins[renderer][region]` (capacity kept across frames), in
/// parallel over the lists. Returns the number of records binned.
pub(crate) fn join(
    grid: &RegionGrid,
    chunks: &[ChunkBins],
    renderers: usize,
    bins: &mut Vec<Vec<Vec<u32>>>,
) -> u32 {
    bins.resize_with(renderers, Vec::new);
    bins.truncate(renderers);
    for b in bins.iter_mut() {
        b.resize_with(grid.count(), Vec::new);
        b.truncate(grid.count());
    }
    bins.par_iter_mut().enumerate().for_each(|(r, lists)| {
        lists.par_iter_mut().enumerate().for_each(|(region, list)| {
            list.clear();
            // `base`: the overall rank of the chunk's first non-empty record.
            let mut base = 0;
            for chunk in chunks {
                let phase = (r + renderers - base % renderers) % renderers;
                list.extend_from_slice(&chunk.lists[phase][region]);
                base += chunk.binned;
            }
        });
    });
    chunks.iter().map(|c| c.binned).sum::<usize>() as u32
}
