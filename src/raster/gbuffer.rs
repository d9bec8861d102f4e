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

use std::collections::HashMap;

use crate::shading::{PatchCoeffs, PatchSource};

/// Polygon id of a sample that sees nothing.
pub const NO_POLYGON: u32 = u32::MAX;

/// Bytes of one pixel record crossing the composition network: depth, polygon, u, v, slot.
pub const PIXEL_RECORD_BYTES: u64 = 20;

/// Bytes of one patch-table entry.
pub const TABLE_ENTRY_BYTES: u64 = std::mem::size_of::<PatchCoeffs>() as u64;

/// Margin (in patch-local units) inside which a sample reuses the previous sample's patch without
/// asking [`PatchSource::locate`]; samples nearer a patch side always ask, so the cache never
/// changes which patch a sample gets.
const CACHE_MARGIN: f32 = 1e-3;

/// The G-buffer of one region.
#[derive(Clone, Debug, PartialEq)]
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
    /// `source.locate(polygon, u, v)`, deduplicated in memory order. Samples strictly inside the
    /// previously located patch (whole blocks of 8 at once) reuse it without asking the source.
    pub fn assign_patches(&mut self, source: &dyn PatchSource) {
        self.table.clear();
        self.table_ids.clear();
        let mut index: HashMap<u32, u32> = HashMap::new();
        // Cache of the last located patch: (polygon, slot).
        let mut last: Option<(u32, u32)> = None;
        for b0 in (0..self.polygon.len()).step_by(8) {
            // Whole block of 8 on the cached patch: one vector test, one fill.
            if let Some((lp, ls)) = last {
                let p = &self.table[ls as usize];
                let polys: &[u32; 8] = self.polygon[b0..b0 + 8].try_into().unwrap();
                let us: &[f32; 8] = self.u[b0..b0 + 8].try_into().unwrap();
                let vs: &[f32; 8] = self.v[b0..b0 + 8].try_into().unwrap();
                // Same test as `contains_strictly`, lane by lane without short-circuits.
                let (lo, hi) = (CACHE_MARGIN, 1.0 - CACHE_MARGIN);
                let mut inside = [false; 8];
                for l in 0..8 {
                    let s = (us[l] - p.u0) * p.inv_w;
                    let t = (vs[l] - p.v0) * p.inv_w;
                    inside[l] = (polys[l] == lp) & (s > lo) & (s < hi) & (t > lo) & (t < hi);
                }
                let all = inside.iter().fold(true, |a, &b| a & b);
                if all {
                    self.slot[b0..b0 + 8].fill(ls);
                    continue;
                }
            }
            for i in b0..b0 + 8 {
                let p = self.polygon[i];
                if p == NO_POLYGON {
                    continue;
                }
                let (u, v) = (self.u[i], self.v[i]);
                if let Some((lp, ls)) = last {
                    if lp == p && self.table[ls as usize].contains_strictly(u, v, CACHE_MARGIN) {
                        self.slot[i] = ls;
                        continue;
                    }
                }
                let id = source.locate(p, u, v);
                let slot = *index.entry(id).or_insert_with(|| {
                    self.table.push(*source.patch(id));
                    self.table_ids.push(id);
                    (self.table.len() - 1) as u32
                });
                self.slot[i] = slot;
                last = Some((p, slot));
            }
        }
    }
}
