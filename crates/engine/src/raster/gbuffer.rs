//! G-buffer: what one screen region holds between rasterization and shading, laid out the way
//! PixelFlow's pixel memories would hold it. Per sample: depth, polygon id, (u, v), and a slot into
//! a region-local patch table holding the bicubic coefficients of every radiosity patch visible in
//! the region. The shading pass reads only this (never the scene), so the rasterizer must resolve,
//! per visible sample, which patch covers it ([`PatchSource::locate`]) and copy that patch's
//! coefficients into the table.
//!
//! Layout: structure of arrays, one plane of `stride * height` entries per sample position, with
//! `stride` the region's width rounded up to whole blocks of 8 (padding lanes stay empty). Empty
//! samples have polygon [`NO_POLYGON`] and infinite depth.
//!
//! Determinism: the table lists patches in the order of their first sample in memory order
//! (sample plane, row, column), so it depends only on the region's pixels, never on the order in
//! which renderers or threads produced them; the patch of a sample is a pure function of
//! (polygon, u, v).

// Lane loops index several fixed-width arrays with one lane index on purpose.
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;

use reconstruction::{PatchCache, PatchCoeffs, PatchSource};

/// Polygon id of a sample that sees nothing.
pub const NO_POLYGON: u32 = u32::MAX;

/// Bytes of one pixel record crossing the composition network: depth, polygon, u, v, slot.
pub const PIXEL_RECORD_BYTES: u64 = 20;

/// Bytes of one patch-table entry.
pub(crate) const TABLE_ENTRY_BYTES: u64 = std::mem::size_of::<PatchCoeffs>() as u64;

/// The G-buffer of one region. `Default` is an empty buffer of no region, to be
/// `RegionGBuffer::reset` before use.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RegionGBuffer {
    /// Index of the region in the frame's region grid.
    pub region: u32,
    /// Left pixel column of the region.
    pub x0: u32,
    /// Top pixel row of the region.
    pub y0: u32,
    /// Width in pixels (the last column of regions may be narrower).
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Entries per row (width rounded up to a multiple of 8).
    pub stride: u32,
    /// Samples per pixel (planes).
    pub samples: u32,
    /// View depth w per sample (infinite when empty).
    pub depth: Vec<f32>,
    /// Scene polygon id per sample, or [`NO_POLYGON`].
    pub polygon: Vec<u32>,
    /// Parameter u per sample, in [0, 1].
    pub u: Vec<f32>,
    /// Parameter v per sample, in [0, 1].
    pub v: Vec<f32>,
    /// Slot into `table` per sample (0 for empty samples).
    pub slot: Vec<u32>,
    /// Coefficients of the patches visible in the region.
    pub table: Vec<PatchCoeffs>,
    /// Global patch id of each table entry.
    pub table_ids: Vec<u32>,
}

impl RegionGBuffer {
    /// An empty G-buffer for a region.
    pub fn new(region: u32, x0: u32, y0: u32, width: u32, height: u32, samples: u32) -> Self {
        let stride = width.div_ceil(8) * 8;
        let n = (stride * height * samples) as usize;
        RegionGBuffer {
            region,
            x0,
            y0,
            width,
            height,
            stride,
            samples,
            depth: vec![f32::INFINITY; n],
            polygon: vec![NO_POLYGON; n],
            u: vec![0.0; n],
            v: vec![0.0; n],
            slot: vec![0; n],
            table: Vec::new(),
            table_ids: Vec::new(),
        }
    }

    /// Makes this buffer the empty G-buffer of another region (or of the same one, next frame),
    /// keeping its allocations: the planes are resized to the region, then only `depth` and
    /// `polygon` are cleared (every reader looks at `u`, `v` and `slot` only where `polygon` is
    /// not [`NO_POLYGON`], so their stale values are never read; they are finite values a
    /// rasterizer wrote, or zeros). The patch table is emptied.
    pub(crate) fn reset(
        &mut self,
        region: u32,
        x0: u32,
        y0: u32,
        width: u32,
        height: u32,
        samples: u32,
    ) {
        let stride = width.div_ceil(8) * 8;
        let n = (stride * height * samples) as usize;
        (self.region, self.x0, self.y0) = (region, x0, y0);
        (self.width, self.height, self.stride, self.samples) = (width, height, stride, samples);
        self.depth.clear();
        self.depth.resize(n, f32::INFINITY);
        self.polygon.clear();
        self.polygon.resize(n, NO_POLYGON);
        self.u.resize(n, 0.0);
        self.v.resize(n, 0.0);
        self.slot.resize(n, 0);
        self.table.clear();
        self.table_ids.clear();
    }

    /// Number of sample entries (including padding lanes).
    pub fn len(&self) -> usize {
        self.depth.len()
    }

    /// Whether the buffer has no entries.
    pub fn is_empty(&self) -> bool {
        self.depth.is_empty()
    }

    /// Bytes this region's G-buffer occupies as pixel records (real samples only) and table.
    pub fn bytes(&self) -> u64 {
        (self.width * self.height * self.samples) as u64 * PIXEL_RECORD_BYTES
            + self.table.len() as u64 * TABLE_ENTRY_BYTES
    }

    /// Fills `slot`, `table` and `table_ids` from the visible samples: each sample's patch is
    /// `source.locate(polygon, u, v)`, deduplicated in memory order.
    ///
    /// Samples inside the exact cell ([`PatchSource::cell`]) of the previously used patch, or of
    /// the patch of the sample one row above, reuse that slot without asking the source; a whole
    /// block of 8 inside the previous cell is filled with one vector test. A cell is the set on
    /// which `locate` returns that patch, so the shortcut never changes a sample's patch.
    pub fn assign_patches(&mut self, source: &dyn PatchSource) {
        self.assign_patches_with(source, &mut PatchScratch::default());
    }

    /// [`RegionGBuffer::assign_patches`] with its working memory kept in `scratch` across calls.
    pub fn assign_patches_with(&mut self, source: &dyn PatchSource, scratch: &mut PatchScratch) {
        self.table.clear();
        self.table_ids.clear();
        let PatchScratch {
            index,
            cells,
            cache,
        } = scratch;
        index.clear();
        // cells[slot]: the polygon and cell on which `locate` returns table_ids[slot].
        cells.clear();
        let stride = self.stride as usize;
        let mut last: Option<usize> = None;
        // Row by row, so that whether a row has one above it in its plane is known without a
        // division per block (rows are whole blocks: the stride is a multiple of 8).
        let height = self.height as usize;
        let rows = height * self.samples as usize;
        let blocks = (0..rows).flat_map(|row| {
            let above = row % height != 0;
            (row * stride..(row + 1) * stride)
                .step_by(8)
                .map(move |b0| (b0, above))
        });
        for (b0, above) in blocks {
            let polys: [u32; 8] = self.polygon[b0..b0 + 8].try_into().unwrap();
            // A block that sees nothing (common in a renderer's share of a region): its slots
            // are never read (see `reset`); the block-level tests below need a valid slot above
            // only for samples that see a polygon, so 0 is written for them.
            if polys.iter().fold(true, |a, &p| a & (p == NO_POLYGON)) {
                self.slot[b0..b0 + 8].fill(0);
                continue;
            }
            if let Some(ls) = last {
                if let Some(settled) = self.settle_block(cells, ls, b0, above) {
                    last = Some(settled);
                    continue;
                }
            }
            let us: [f32; 8] = self.u[b0..b0 + 8].try_into().unwrap();
            let vs: [f32; 8] = self.v[b0..b0 + 8].try_into().unwrap();
            for l in 0..8 {
                let i = b0 + l;
                let p = polys[l];
                if p == NO_POLYGON {
                    self.slot[i] = 0;
                    continue;
                }
                let (u, v) = (us[l], vs[l]);
                if let Some(ls) = last {
                    if cells[ls].contains(p, u, v) {
                        self.slot[i] = ls as u32;
                        continue;
                    }
                }
                // The sample above (same plane) was assigned already; its slot is in range
                // whenever the table is not empty (empty samples hold slot 0).
                if above {
                    let a = self.slot[i - stride] as usize;
                    if a < cells.len() && cells[a].contains(p, u, v) {
                        self.slot[i] = a as u32;
                        last = Some(a);
                        continue;
                    }
                }
                let id = source.locate(p, u, v);
                let slot = *index.entry(id).or_insert_with(|| {
                    self.table.push(source.patch_cached(id, cache));
                    self.table_ids.push(id);
                    cells.push(SlotCell::new(p, source.cell(id)));
                    (self.table.len() - 1) as u32
                });
                self.slot[i] = slot;
                last = Some(slot as usize);
            }
        }
    }
}

impl RegionGBuffer {
    /// The block shortcuts of [`RegionGBuffer::assign_patches_with`] for the block at `b0`,
    /// `ls` the slot used last and `above` whether the block has a row above it in its plane:
    /// every lane in the cell of `ls` (one lane-wise test, one fill), or every lane in it or in
    /// the cell of the slot above the block's last lane (a block that crosses into the next
    /// patch along the row usually ends in that one: a second lane-wise test and a select).
    /// Returns the slot used last when the block is settled, `None` to go lane by lane.
    #[inline(always)]
    fn settle_block(
        &mut self,
        cells: &[SlotCell],
        ls: usize,
        b0: usize,
        above: bool,
    ) -> Option<usize> {
        let polys: &[u32; 8] = self.polygon[b0..b0 + 8].try_into().unwrap();
        let us: &[f32; 8] = self.u[b0..b0 + 8].try_into().unwrap();
        let vs: &[f32; 8] = self.v[b0..b0 + 8].try_into().unwrap();
        let c = &cells[ls];
        let mut inside = [false; 8];
        for l in 0..8 {
            inside[l] = c.contains(polys[l], us[l], vs[l]);
        }
        if inside.iter().fold(true, |a, &b| a & b) {
            self.slot[b0..b0 + 8].fill(ls as u32);
            return Some(ls);
        }
        if !above {
            return None;
        }
        let a = self.slot[b0 + 7 - self.stride as usize] as usize;
        let c2 = cells.get(a)?;
        let mut either = [false; 8];
        for l in 0..8 {
            either[l] = inside[l] | c2.contains(polys[l], us[l], vs[l]);
        }
        if !either.iter().fold(true, |x, &y| x & y) {
            return None;
        }
        let out: &mut [u32; 8] = (&mut self.slot[b0..b0 + 8]).try_into().unwrap();
        for l in 0..8 {
            out[l] = if inside[l] { ls as u32 } else { a as u32 };
        }
        Some(out[7] as usize)
    }
}

/// Working memory of [`RegionGBuffer::assign_patches_with`], kept by the frame stage across
/// regions and frames so that locating patches allocates nothing once warm: the slot index, the
/// slots' cells and the worker's cache of expanded patches ([`PatchCache`], for sources that
/// expand patches on demand).
#[derive(Debug, Default)]
pub struct PatchScratch {
    index: IdMap,
    cells: Vec<SlotCell>,
    cache: PatchCache,
}

impl PatchScratch {
    /// Fills the patch cache for `source` ahead of a first frame ([`PatchSource::warm`]).
    pub fn warm(&mut self, source: &dyn PatchSource) {
        source.warm(&mut self.cache);
    }

    /// Bytes of the patch cache.
    pub fn cache_bytes(&self) -> usize {
        self.cache.bytes()
    }
}

/// The polygon and half-open (u, v) rectangle on which a table slot's patch is `locate`'s answer.
#[derive(Clone, Copy, Debug)]
struct SlotCell {
    polygon: u32,
    /// `[u_lo, u_hi, v_lo, v_hi]`; an empty range when the source does not know the cell.
    bounds: [f32; 4],
}

impl SlotCell {
    fn new(polygon: u32, cell: Option<[f32; 4]>) -> SlotCell {
        SlotCell {
            polygon,
            // u >= 1 && u < 0 never holds (nor for NaN): an unknown cell matches no sample.
            bounds: cell.unwrap_or([1.0, 0.0, 1.0, 0.0]),
        }
    }

    /// Lane-friendly membership test (no short-circuits).
    #[inline(always)]
    fn contains(&self, polygon: u32, u: f32, v: f32) -> bool {
        let b = &self.bounds;
        (polygon == self.polygon) & (u >= b[0]) & (u < b[1]) & (v >= b[2]) & (v < b[3])
    }
}

/// Hasher for global patch ids (u32 keys): one multiply by the 64-bit golden-ratio constant. The
/// standard SipHash showed up in profiles of the patch-table dedupe; the keys are not adversarial.
#[derive(Default)]
pub(crate) struct IdHasher(u64);

impl std::hash::Hasher for IdHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }

    fn write_u32(&mut self, x: u32) {
        self.0 = (self.0 ^ x as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    }
}

/// Map from global patch id to table slot.
pub(crate) type IdMap = HashMap<u32, u32, std::hash::BuildHasherDefault<IdHasher>>;

#[cfg(test)]
mod tests {
    use super::*;

    /// n x n square patches per polygon; `cells` says whether it reports them to the cache.
    struct Grid {
        n: u32,
        cells: bool,
        patches: Vec<PatchCoeffs>,
    }

    impl Grid {
        fn new(polygons: u32, n: u32, cells: bool) -> Grid {
            let mut patches = Vec::new();
            for p in 0..polygons {
                for k in 0..n * n {
                    let mut c = PatchCoeffs::whole([[0.0; 16]; 3]);
                    c.c[0][0] = (p * n * n + k) as f32;
                    c.u0 = (k % n) as f32 / n as f32;
                    c.v0 = (k / n) as f32 / n as f32;
                    c.inv_w = n as f32;
                    patches.push(c);
                }
            }
            Grid { n, cells, patches }
        }
    }

    impl PatchSource for Grid {
        fn locate(&self, polygon: u32, u: f32, v: f32) -> u32 {
            let n = self.n;
            let i = ((u * n as f32) as u32).min(n - 1);
            let j = ((v * n as f32) as u32).min(n - 1);
            polygon * n * n + j * n + i
        }
        fn patch(&self, id: u32) -> PatchCoeffs {
            self.patches[id as usize]
        }
        // With n a power of two, u * n is exact, so the cell is exactly where `locate` answers.
        fn cell(&self, id: u32) -> Option<[f32; 4]> {
            let p = &self.patches[id as usize];
            let w = 1.0 / p.inv_w;
            self.cells.then_some([p.u0, p.u0 + w, p.v0, p.v0 + w])
        }
    }

    /// Two polygons, smooth (u, v) ramps crossing many patch sides inside blocks, rows that
    /// change polygon, scattered empty samples and out-of-ramp samples, in 2 sample planes.
    fn filled(region_w: u32, region_h: u32) -> RegionGBuffer {
        let mut gb = RegionGBuffer::new(0, 0, 0, region_w, region_h, 2);
        let mut seed = 12345u32;
        let stride = gb.stride as usize;
        for i in 0..gb.len() {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let (x, y) = (
                (i % stride) as f32,
                ((i / stride) % region_h as usize) as f32,
            );
            let plane = i / (stride * region_h as usize);
            if (i % stride) as u32 >= region_w || seed >> 28 == 0 {
                continue; // padding lane or a hole
            }
            gb.polygon[i] = if (y as u32 / 5 + plane as u32).is_multiple_of(3) {
                1
            } else {
                0
            };
            gb.depth[i] = 1.0;
            let jitter = if seed >> 27 == 31 { 0.37 } else { 0.0 };
            gb.u[i] = ((x * 0.0137 + jitter) % 1.0).min(1.0);
            gb.v[i] = (y * 0.019 + plane as f32 * 0.1).min(1.0);
        }
        gb
    }

    #[test]
    fn every_sample_gets_the_patch_locate_returns_and_the_table_is_canonical() {
        let (with, without) = (Grid::new(2, 16, true), Grid::new(2, 16, false));
        let mut a = filled(72, 40);
        let mut b = a.clone();
        a.assign_patches(&with);
        b.assign_patches(&without);
        let mut checked = 0;
        for i in 0..a.len() {
            let p = a.polygon[i];
            if p == NO_POLYGON {
                assert_eq!(a.slot[i], 0);
                continue;
            }
            let want = with.locate(p, a.u[i], a.v[i]);
            assert_eq!(a.table_ids[a.slot[i] as usize], want, "sample {i}");
            assert_eq!(a.table[a.slot[i] as usize], with.patch(want));
            checked += 1;
        }
        assert!(checked > 4000, "only {checked} samples checked");
        // The cache only skips work: same slots, same table order as asking for every sample.
        assert_eq!(a.slot, b.slot);
        assert_eq!(a.table_ids, b.table_ids);
        // Sanity: the ramps really cross patches (16 x 16 cells over ~1 x 0.9 of the domain).
        assert!(a.table_ids.len() > 100, "{} patches", a.table_ids.len());
    }
}
