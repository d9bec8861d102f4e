//! Equal-error memory: how many bytes of radiosity texture each texture method needs to be as
//! accurate as the direct method, beside the bytes of the RRPs the direct method holds. This is
//! the honest form of the compactness comparison: bytes at equal error, not at equal sampling.
//!
//! The search scales every polygon's quadtree-depth texture side ([`SizePolicy::Scaled`]) by
//! `2^k` for `k` = `MIN_SCALE`, ..., `MAX_SCALE` (halved three times up to doubled four
//! times), at both texel placements, renders each texture method at each scale and measures its
//! **reconstruction error** (perceptual distance to the same solution's exact value at every
//! pixel, the error of the method alone). For each ratio `r` of `EQUAL_ERROR_RATIOS` it reports
//! the smallest tested texture whose error is at most `r` times the direct method's.
//!
//! Each set is measured twice: as the texture methods draw it (mip-mapped, the level of detail
//! from the pixel's footprint) and with its mip chain dropped (level 0 at every pixel). The
//! textures are resampled from the same RRPs the direct method evaluates, so as they grow their
//! image approaches the direct method's; but once a texel is smaller than a pixel, mip-mapping
//! averages over the pixel's footprint (isotropically: over more than the footprint where a
//! surface is seen obliquely), where the direct method and the exact image sample the pixel
//! centre, and that error does not fall with the texture's size. Without the chain the error does
//! converge to the direct method's (and can dip below it where bilinear smoothing happens to undo
//! some of the RRP's own error), at the price of aliasing under minification that a point-sampled
//! error measure does not see. The looser ratio (within 10 %) is reported too, and every tested
//! scale's error, so a reader sees the whole curve.
//!
//! Invariants: deterministic (errors and bytes only, no timing); the scales tried stop early when
//! every method reached the strict ratio, when every side is clamped at the largest texture side,
//! or when a set would hold more than `SEARCH_MEMORY_CAP` bytes of f32 texels in memory.

use serde::Serialize;

use app::frames::frame_image;
use app::frames::render_frame;
use app::prepare::Prepared;
use base::error::Result;
use base::method::{Method, Placement};
use base::progress::{Observer, Stage};
use engine::frame::{self, FrameOptions};
use engine::shading::Shader;
use imageio::LinearImage;
use metric::compare;
use reconstruction::texture::{Extent, SizePolicy, TextureMemory, TextureSet, GUTTER};

/// Error ratios to the direct method's reconstruction error at which the texture memory is
/// reported: equal (1.0) and within 10 % (1.1).
pub(crate) const EQUAL_ERROR_RATIOS: [f64; 2] = [1.0, 1.1];
/// Smallest scale exponent tried: the quadtree-depth sides halved three times.
pub(crate) const MIN_SCALE: i32 = -3;
/// Largest scale exponent tried: the quadtree-depth sides doubled four times.
pub(crate) const MAX_SCALE: i32 = 4;
/// The largest texture set the search builds, in bytes held in memory (f32 RGB texels with mip
/// chains): 1 GiB, a twentieth of the reference machine's memory.
pub(crate) const SEARCH_MEMORY_CAP: u64 = 1 << 30;

/// One tested texture scale of one method and placement.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct ScalePoint {
    /// The exponent `k`: the quadtree-depth sides times `2^k`.
    pub scale: i32,
    /// Level-0 texels of all textures.
    pub texels: u64,
    /// Bytes at 12 bits per channel, with mip chains when the row is mip-mapped (as the sweep
    /// counts textures), of level 0 alone when not.
    pub bytes: u64,
    /// Reconstruction error (perceptual distance to the same solution's exact image).
    pub error: f64,
}

/// One texture method at one texel placement.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EqualErrorRow {
    /// Method name (`texture-bilinear`, ...).
    pub method: String,
    /// Texel placement (`centre` or `corner`).
    pub placement: &'static str,
    /// Drawn with mip-mapping (as the texture methods draw); `false`: level 0 at every pixel.
    pub mip_mapped: bool,
    /// Every scale tried, smallest first.
    pub tested: Vec<ScalePoint>,
    /// For each of `EQUAL_ERROR_RATIOS`: the smallest tested texture whose error is at most that
    /// ratio times the direct method's, if any.
    pub reached: Vec<Option<ScalePoint>>,
}

impl EqualErrorRow {
    /// The tested point with the lowest error (the first of equals).
    pub fn best(&self) -> Option<ScalePoint> {
        self.tested
            .iter()
            .copied()
            .fold(None, |b: Option<ScalePoint>, p| match b {
                Some(b) if b.error <= p.error => Some(b),
                _ => Some(p),
            })
    }
}

/// The equal-error comparison of one solution.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct EqualError {
    /// The sweep's density level it was measured at.
    pub density: usize,
    /// The direct method's reconstruction error.
    pub direct_error: f64,
    /// Bytes the direct method's RRPs are stored in (the trees and samples they are built from;
    /// [`app::memory::rrp_stored_bytes`]): what the textures' bytes are compared with.
    pub rrp_bytes: u64,
    /// Bytes of the same RRPs as the direct method holds them (compact: locate trees, leaf
    /// records, Hermite data as f32).
    pub rrp_held_bytes: u64,
    /// The ratios of [`EqualErrorRow::reached`].
    pub ratios: Vec<f64>,
    /// Why the search stopped growing the textures.
    pub stopped: String,
    /// One row per texture method and placement.
    pub rows: Vec<EqualErrorRow>,
}

/// Bytes a set of these sides holds in memory: f32 RGB texels with mip chains.
pub(crate) fn held_bytes(memory: &TextureMemory) -> u64 {
    memory.texels_with_chain.saturating_mul(12)
}

/// Runs the search on prepared solution `p` for the texture methods among `methods`, against
/// `exact` (the same solution's exact image at `opts`' size). `None` if `methods` has no texture
/// method.
pub fn equal_error(
    p: &Prepared,
    density: usize,
    methods: &[Method],
    exact: &LinearImage,
    opts: &FrameOptions,
    ppd: f64,
    observer: &dyn Observer,
) -> Result<Option<EqualError>> {
    let filters: Vec<Method> = methods
        .iter()
        .copied()
        .filter(|m| matches!(m, Method::Texture(_)))
        .collect();
    if filters.is_empty() {
        return Ok(None);
    }
    let mut stage = Stage::start(observer, "equal-error search");
    let direct = frame_image(render_frame(p, Method::Direct, &p.scene.camera, opts)?)?;
    let direct_error = compare(&direct, exact, ppd)?.perceptual_distance;
    let mut rows = empty_rows(&filters);
    let search = Search {
        p,
        filters: &filters,
        exact,
        opts,
        ppd,
        direct_error,
    };
    let stopped = search.run(&mut rows, &mut stage)?;
    Ok(Some(EqualError {
        density,
        direct_error,
        rrp_bytes: app::memory::rrp_stored_bytes(p),
        rrp_held_bytes: app::memory::rrp_bytes(&p.compact),
        ratios: EQUAL_ERROR_RATIOS.to_vec(),
        stopped,
        rows,
    }))
}

/// The texel placements every scale is tried at, in row order.
const PLACEMENTS: [Placement; 2] = [Placement::Centre, Placement::Corner];

/// One empty row per texture method, placement and mip-mapping: mip-mapped first, then
/// placement, then method.
fn empty_rows(filters: &[Method]) -> Vec<EqualErrorRow> {
    let mut rows = Vec::new();
    for mip_mapped in [true, false] {
        for pl in PLACEMENTS {
            for m in filters {
                rows.push(EqualErrorRow {
                    method: m.name().to_string(),
                    placement: pl.name(),
                    mip_mapped,
                    tested: Vec::new(),
                    reached: vec![None; EQUAL_ERROR_RATIOS.len()],
                });
            }
        }
    }
    rows
}

/// What the search draws each texture from and measures it against.
struct Search<'a> {
    p: &'a Prepared,
    /// The texture methods searched.
    filters: &'a [Method],
    /// The same solution's exact image.
    exact: &'a LinearImage,
    opts: &'a FrameOptions,
    ppd: f64,
    /// The direct method's reconstruction error, the target.
    direct_error: f64,
}

impl Search<'_> {
    /// The row (of [`empty_rows`]) of mip-mapping `mip`, placement `pi` and method `mi`.
    fn row_index(&self, mip: bool, pi: usize, mi: usize) -> usize {
        (usize::from(!mip) * PLACEMENTS.len() + pi) * self.filters.len() + mi
    }

    /// Tries the scales from [`MIN_SCALE`] up until one of the stops, filling `rows`; returns
    /// why it stopped.
    fn run(&self, rows: &mut [EqualErrorRow], stage: &mut Stage<'_>) -> Result<String> {
        let extents = self.p.texture_extents()?;
        let mut previous: Option<Vec<(u32, u32)>> = None;
        for k in MIN_SCALE..=MAX_SCALE {
            let sides = TextureSet::sizes(&extents, SizePolicy::Scaled(k))?;
            if previous.as_ref() == Some(&sides) {
                return Ok(format!(
                    "every side reached the largest texture side at 2^{}",
                    k - 1
                ));
            }
            let memory = TextureMemory::of_sizes(&sides, GUTTER);
            if held_bytes(&memory) > SEARCH_MEMORY_CAP {
                return Ok(format!(
                    "the textures at 2^{k} would hold {:.0} MB in memory, above the search's cap \
                     of {:.0} MB",
                    held_bytes(&memory) as f64 / 1e6,
                    SEARCH_MEMORY_CAP as f64 / 1e6
                ));
            }
            previous = Some(sides);
            stage.advance((k - MIN_SCALE) as f64 / (MAX_SCALE - MIN_SCALE + 1) as f64);
            for (pi, &placement) in PLACEMENTS.iter().enumerate() {
                self.measure_set(rows, k, &extents, pi, placement)?;
            }
            if rows.iter().all(|r| r.reached.iter().all(Option::is_some)) {
                return Ok(format!(
                    "every method reached the direct method's error by 2^{k}"
                ));
            }
        }
        Ok(format!("every scale up to 2^{MAX_SCALE} was tried"))
    }

    /// The set at scale `k` and placement `pi`, each texture method drawn with it mip-mapped,
    /// then with its mip chains dropped.
    fn measure_set(
        &self,
        rows: &mut [EqualErrorRow],
        k: i32,
        extents: &[Extent],
        pi: usize,
        placement: Placement,
    ) -> Result<()> {
        let p = self.p;
        let mut set =
            TextureSet::build(p.expanded()?.0, extents, SizePolicy::Scaled(k), placement)?;
        for mip in [true, false] {
            if !mip {
                set.drop_mip_chains();
            }
            let bytes = if mip {
                app::memory::texture_bytes(&set.memory)
            } else {
                set.memory.bytes[1]
            };
            for (mi, &m) in self.filters.iter().enumerate() {
                let Method::Texture(filter) = m else {
                    continue;
                };
                let img = frame_image(frame::render(
                    &p.scene,
                    &p.scene.camera,
                    &Shader::Texture {
                        set: &set,
                        filter,
                        anisotropy: 1,
                    },
                    m,
                    self.opts,
                )?)?;
                let point = ScalePoint {
                    scale: k,
                    texels: set.memory.texels,
                    bytes,
                    error: compare(&img, self.exact, self.ppd)?.perceptual_distance,
                };
                record(
                    &mut rows[self.row_index(mip, pi, mi)],
                    point,
                    self.direct_error,
                );
            }
        }
        Ok(())
    }
}

/// Adds `point` to `row`'s tested scales, and as the answer of each ratio of the direct
/// method's error it is the first to reach.
fn record(row: &mut EqualErrorRow, point: ScalePoint, direct_error: f64) {
    row.tested.push(point);
    for (slot, r) in row.reached.iter_mut().zip(EQUAL_ERROR_RATIOS) {
        if slot.is_none() && point.error <= r * direct_error {
            *slot = Some(point);
        }
    }
}

/// The comparison as a fixed-width table.
pub fn table(e: &EqualError) -> String {
    let mut s = format!(
        "equal-error memory (density {}): direct reconstruction error {:.4}, RRPs {} bytes; {}\n\
         method            placement  mip  bytes to <= direct  bytes to <= 1.1 x  best error / direct (bytes)\n",
        e.density, e.direct_error, e.rrp_bytes, e.stopped
    );
    let cell = |p: Option<ScalePoint>| p.map_or("not reached".to_string(), |p| p.bytes.to_string());
    for r in &e.rows {
        let best = r.best().map_or("-".to_string(), |b| {
            format!("{:.3} ({})", b.error / e.direct_error.max(1e-300), b.bytes)
        });
        s += &format!(
            "{:<17} {:<9} {:<4} {:>19} {:>18}  {}\n",
            r.method,
            r.placement,
            if r.mip_mapped { "yes" } else { "no" },
            cell(r.reached.first().copied().flatten()),
            cell(r.reached.get(1).copied().flatten()),
            best
        );
    }
    s
}
