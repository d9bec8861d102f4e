//! The walkthrough summary: what a frame-rate meter (the paper's Performer statistics) would
//! show after flying the scene's camera path: frames rendered, frames per second min / median /
//! max, total time, and the median frame's stages and work.
//!
//! Everything comes from the frames' [`FrameStats`]: frame rates are `1000 / frame_ms` of each
//! frame's wall-clock time (see [`fps`]), so writing the PNGs is not part of them. Medians use
//! [`median`], the bench command's too, so the two report the same statistic.
//!
//! [`walk`] flies the path (one warm-up frame, then every frame in one frame context, as
//! `render --walkthrough` draws it); the study times the same flight in separate processes.

use serde::Serialize;

use crate::frames::render_frame_in;
use crate::prepare::Prepared;
use crate::rates::fps;
use crate::rates::{median, min_max};
use base::error::Result;
use base::method::Method;
use engine::frame::{FrameOptions, FrameStats};
use scene::CameraPath;

/// Every frame of `path` drawn by `method` after one warm-up frame (which also builds the
/// textures or the mesh), all in one frame context; each frame's statistics.
pub fn walk(
    p: &Prepared,
    method: Method,
    path: &CameraPath,
    opts: &FrameOptions,
) -> Result<Vec<FrameStats>> {
    let cameras: Vec<_> = (0..path.frames)
        .map(|k| path.camera(p.scene.camera.projection, k))
        .collect();
    let mut ctx = engine::frame::FrameContext::new();
    if let Some(first) = cameras.first() {
        render_frame_in(&mut ctx, p, method, first, opts)?;
    }
    cameras
        .iter()
        .map(|c| render_frame_in(&mut ctx, p, method, c, opts))
        .collect()
}

/// `count` frame indices spread evenly over `frames` (all of them when there are fewer).
pub fn spread_frames(frames: u32, count: u32) -> Vec<u32> {
    if frames <= count {
        return (0..frames).collect();
    }
    if count < 2 {
        return (0..count).collect();
    }
    let last = (frames - 1) as u64;
    (0..count as u64)
        .map(|i| ((i * last + (count as u64 - 1) / 2) / (count as u64 - 1)) as u32)
        .collect()
}

/// Frame rates and per-stage medians over a walkthrough's frames (`--stats` JSON `summary`).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct WalkthroughSummary {
    /// Frames rendered.
    pub frames: usize,
    /// Lowest frame rate (the slowest frame's `1000 / frame_ms`).
    pub fps_min: f64,
    /// Median of the frames' frame rates.
    pub fps_median: f64,
    /// Highest frame rate (the fastest frame's).
    pub fps_max: f64,
    /// Sum of the frames' wall-clock frame times, ms (file writes not included).
    pub total_ms: f64,
    /// Median wall-clock frame time, ms.
    pub median_frame_ms: f64,
    /// Median geometry time, ms.
    pub median_geometry_ms: f64,
    /// Median raster time, ms.
    pub median_raster_ms: f64,
    /// Median composition time (merge busy time per worker), ms.
    pub median_composition_ms: f64,
    /// Median deferred-shading time, ms.
    pub median_shading_ms: f64,
    /// Median sum of the four stage times, ms.
    pub median_stage_sum_ms: f64,
    /// Median samples shaded per frame.
    pub median_pixels_shaded: f64,
    /// Median 8-sample blocks evaluated with one broadcast patch.
    pub median_uniform_blocks: f64,
    /// Median 8-sample blocks evaluated lane by lane.
    pub median_mixed_blocks: f64,
}

impl WalkthroughSummary {
    /// The summary of `frames` (all zeros when there are none).
    pub fn new(frames: &[FrameStats]) -> WalkthroughSummary {
        if frames.is_empty() {
            return WalkthroughSummary::default();
        }
        let med = |f: fn(&FrameStats) -> f64| median(frames.iter().map(f).collect());
        let rates: Vec<f64> = frames.iter().map(|s| fps(s.frame_ms)).collect();
        let [fps_min, fps_max] = min_max(&rates);
        WalkthroughSummary {
            frames: frames.len(),
            fps_min,
            fps_max,
            fps_median: median(rates),
            total_ms: frames.iter().map(|s| s.frame_ms).sum(),
            median_frame_ms: med(|s| s.frame_ms),
            median_geometry_ms: med(|s| s.geometry_ms),
            median_raster_ms: med(|s| s.raster_ms),
            median_composition_ms: med(|s| s.composition_ms),
            median_shading_ms: med(|s| s.shading_ms),
            median_stage_sum_ms: med(|s| s.stage_sum_ms),
            median_pixels_shaded: med(|s| s.pixels_shaded as f64),
            median_uniform_blocks: med(|s| s.uniform_blocks as f64),
            median_mixed_blocks: med(|s| s.mixed_blocks as f64),
        }
    }

    /// One line for a terminal: `walkthrough: 48 frames, fps min 61.2 / median 80.4 / max 92.0;
    /// median ms: geometry 0.4 raster 5.1 composition 0.3 shading 5.6`.
    pub fn line(&self) -> String {
        format!(
            "walkthrough: {} frames, fps min {:.1} / median {:.1} / max {:.1}; \
             median ms: geometry {:.1} raster {:.1} composition {:.1} shading {:.1}",
            self.frames,
            self.fps_min,
            self.fps_median,
            self.fps_max,
            self.median_geometry_ms,
            self.median_raster_ms,
            self.median_composition_ms,
            self.median_shading_ms
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame with the given wall-clock time, stage times, and counters derived from `k`.
    fn frame(frame_ms: f64, stages: [f64; 4], k: u64) -> FrameStats {
        FrameStats {
            frame_ms,
            geometry_ms: stages[0],
            raster_ms: stages[1],
            composition_ms: stages[2],
            shading_ms: stages[3],
            stage_sum_ms: stages.iter().sum(),
            pixels_shaded: 100 * k,
            uniform_blocks: 10 * k,
            mixed_blocks: k,
            ..FrameStats::default()
        }
    }

    #[test]
    fn odd_count_takes_the_middle_frame() {
        // Frame times 10, 20, 40 ms: 100, 50, 25 fps; given out of order.
        let s = WalkthroughSummary::new(&[
            frame(20.0, [1.0, 8.0, 2.0, 9.0], 2),
            frame(40.0, [3.0, 16.0, 4.0, 17.0], 7),
            frame(10.0, [0.5, 4.0, 1.0, 4.5], 1),
        ]);
        assert_eq!(s.frames, 3);
        assert_eq!(s.fps_min, 25.0);
        assert_eq!(s.fps_median, 50.0);
        assert_eq!(s.fps_max, 100.0);
        assert_eq!(s.total_ms, 70.0);
        assert_eq!(s.median_frame_ms, 20.0);
        assert_eq!(s.median_geometry_ms, 1.0);
        assert_eq!(s.median_raster_ms, 8.0);
        assert_eq!(s.median_composition_ms, 2.0);
        assert_eq!(s.median_shading_ms, 9.0);
        assert_eq!(s.median_stage_sum_ms, 20.0);
        assert_eq!(s.median_pixels_shaded, 200.0);
        assert_eq!(s.median_uniform_blocks, 20.0);
        assert_eq!(s.median_mixed_blocks, 2.0);
    }

    #[test]
    fn even_count_averages_the_middle_two() {
        // 8, 10, 20, 40 ms: 125, 100, 50, 25 fps; the median rate is (100 + 50) / 2, not the
        // rate of the median time (1000 / 15).
        let s = WalkthroughSummary::new(&[
            frame(40.0, [4.0, 20.0, 4.0, 12.0], 4),
            frame(8.0, [1.0, 3.0, 1.0, 3.0], 1),
            frame(20.0, [2.0, 10.0, 2.0, 6.0], 3),
            frame(10.0, [1.0, 5.0, 1.0, 3.0], 2),
        ]);
        assert_eq!(s.frames, 4);
        assert_eq!(s.fps_min, 25.0);
        assert_eq!(s.fps_median, 75.0);
        assert_eq!(s.fps_max, 125.0);
        assert_eq!(s.total_ms, 78.0);
        assert_eq!(s.median_frame_ms, 15.0);
        assert_eq!(s.median_geometry_ms, 1.5);
        assert_eq!(s.median_raster_ms, 7.5);
        assert_eq!(s.median_composition_ms, 1.5);
        assert_eq!(s.median_shading_ms, 4.5);
        assert_eq!(s.median_stage_sum_ms, 15.0);
        assert_eq!(s.median_pixels_shaded, 250.0);
        assert_eq!(s.median_uniform_blocks, 25.0);
        assert_eq!(s.median_mixed_blocks, 2.5);
    }

    #[test]
    fn one_frame_is_its_own_min_median_and_max() {
        let s = WalkthroughSummary::new(&[frame(4.0, [0.5, 1.5, 0.5, 1.5], 3)]);
        assert_eq!(s.frames, 1);
        assert_eq!((s.fps_min, s.fps_median, s.fps_max), (250.0, 250.0, 250.0));
        assert_eq!(s.total_ms, 4.0);
        assert_eq!(s.median_frame_ms, 4.0);
        assert_eq!(s.median_stage_sum_ms, 4.0);
        assert_eq!(s.median_pixels_shaded, 300.0);
        assert_eq!(s.median_mixed_blocks, 3.0);
    }

    #[test]
    fn no_frames_is_all_zeros() {
        assert_eq!(WalkthroughSummary::new(&[]), WalkthroughSummary::default());
    }

    #[test]
    fn line_names_frames_rates_and_stage_medians() {
        let s = WalkthroughSummary::new(&[
            frame(20.0, [1.0, 8.0, 2.0, 9.0], 2),
            frame(40.0, [3.0, 16.0, 4.0, 17.0], 7),
            frame(10.0, [0.5, 4.0, 1.0, 4.5], 1),
        ]);
        assert_eq!(
            s.line(),
            "walkthrough: 3 frames, fps min 25.0 / median 50.0 / max 100.0; \
             median ms: geometry 1.0 raster 8.0 composition 2.0 shading 9.0"
        );
    }

    #[test]
    fn frames_spread_over_the_path_with_both_ends() {
        assert_eq!(spread_frames(48, 12)[0], 0);
        assert_eq!(*spread_frames(48, 12).last().unwrap(), 47);
        assert_eq!(spread_frames(48, 12).len(), 12);
        assert_eq!(spread_frames(5, 3), [0, 2, 4]);
        assert_eq!(spread_frames(3, 12), [0, 1, 2]);
        assert_eq!(spread_frames(1, 12), [0]);
        assert_eq!(spread_frames(0, 12), Vec::<u32>::new());
        let s = spread_frames(1000, 12);
        assert!(s.windows(2).all(|w| w[0] < w[1]), "{s:?}");
    }
}
