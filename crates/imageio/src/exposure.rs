//! What an image's pixels say about its exposure: the luminance summary `render` prints beside
//! every image it writes, and the automatic exposure of `--auto-exposure`.
//!
//! A render's numbers are linear radiosity; the PNG shows `2^exposure` times them through the
//! sRGB curve, clipped to white at 1. A first render can come out black or washed out without
//! anything being wrong with the solution, so the summary gives the linear luminance (min,
//! median, max) and the shares of pixels the PNG shows black (under half an 8-bit step) and
//! clipped white, and [`exposure_warning`] turns an extreme share into a warning naming the fix.
//!
//! The automatic exposure is Reinhard et al.'s "key" rule (Photographic Tone Reproduction,
//! 2002): the log-average luminance of the lit pixels is mapped to middle grey, 0.18. Pixels of
//! luminance 0 (background, back sides) are left out, or a half-empty frame would be pushed to
//! white. The result is clamped to [-[`MAX_AUTO_STOPS`], +[`MAX_AUTO_STOPS`]] stops.

use super::ImageView;
use base::image::luminance;
use serde::Serialize;

/// Middle grey: the display value the log-average luminance is mapped to.
pub const KEY: f64 = 0.18;

/// Largest automatic exposure, in stops either way.
pub const MAX_AUTO_STOPS: f64 = 20.0;

/// Share of the pixels shown black or clipped from which [`exposure_warning`] warns.
pub const EXTREME_SHARE: f64 = 0.5;

/// The luminance summary of an image (see the module docs).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct LuminanceSummary {
    /// Smallest linear luminance.
    pub min: f64,
    /// Median linear luminance (the lower middle value for an even count).
    pub median: f64,
    /// Largest linear luminance.
    pub max: f64,
    /// The exposure the PNG is shown with, stops.
    pub exposure: f64,
    /// Share of the pixels showing a polygon that the PNG shows black: luminance *
    /// 2^exposure under half an 8-bit step of the sRGB curve (0.5 / 255 / 12.92).
    pub black: f64,
    /// Share of the pixels (samples) that show a polygon rather than the background.
    pub covered: f64,
    /// Share of pixels the PNG shows clipped: some channel * 2^exposure at 1 or more.
    pub clipped: f64,
}

/// The summary of `image` shown with `exposure` stops, of which the share `covered` shows
/// polygons; `background` is the luminance of the other pixels (counted out of the black
/// share when it is black itself).
pub fn summarize(
    image: ImageView<'_>,
    exposure: f64,
    covered: f64,
    background: f64,
) -> LuminanceSummary {
    let gain = exposure.exp2();
    // One f32 per pixel (the memory estimate counts 4 B): the median is selected, not sorted.
    let mut lum: Vec<f32> = image.pixels.iter().map(|p| luminance(*p) as f32).collect();
    let n = lum.len().max(1) as f64;
    let dark = 0.5 / 255.0 / 12.92;
    let covered = covered.clamp(0.0, 1.0);
    let mut black = lum.iter().filter(|&&l| l as f64 * gain < dark).count() as f64 / n;
    if background * gain < dark {
        black -= 1.0 - covered;
    }
    let black = if covered > 0.0 {
        (black / covered).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let clipped = image
        .pixels
        .iter()
        .filter(|p| p.max_element() as f64 * gain >= 1.0)
        .count() as f64
        / n;
    let min = lum.iter().copied().fold(f32::INFINITY, f32::min);
    let max = lum.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let median = if lum.is_empty() {
        0.0
    } else {
        let mid = (lum.len() - 1) / 2;
        *lum.select_nth_unstable_by(mid, f32::total_cmp).1
    };
    let finite = |x: f32| if x.is_finite() { x as f64 } else { 0.0 };
    LuminanceSummary {
        min: finite(min),
        median: finite(median),
        max: finite(max),
        exposure,
        black,
        covered,
        clipped,
    }
}

/// The exposure in stops that maps the log-average luminance of the pixels of non-zero
/// luminance to [`KEY`]; 0 if there are none.
pub fn auto_exposure(image: ImageView<'_>) -> f64 {
    let (mut sum, mut count) = (0.0, 0usize);
    for p in image.pixels {
        let l = luminance(*p);
        if l > 0.0 && l.is_finite() {
            sum += l.ln();
            count += 1;
        }
    }
    if count == 0 {
        return 0.0;
    }
    let log_average = (sum / count as f64).exp();
    (KEY / log_average)
        .log2()
        .clamp(-MAX_AUTO_STOPS, MAX_AUTO_STOPS)
}

impl LuminanceSummary {
    /// One line: `luminance min / median / max ...; exposure ...: x % black, y % clipped`.
    pub fn line(&self) -> String {
        format!(
            "luminance min {:.4} / median {:.4} / max {:.4} (linear); exposure {:+.2} stops: \
             {:.1} % of the model black, {:.1} % of the image clipped; {:.1} % background",
            self.min,
            self.median,
            self.max,
            self.exposure,
            100.0 * self.black,
            100.0 * self.clipped,
            100.0 * (1.0 - self.covered)
        )
    }
}

/// A warning when most of the image is clipped or most of the model black at its exposure,
/// naming the fix (`auto`: the exposure was chosen automatically, so the fix is not to).
pub fn exposure_warning(s: &LuminanceSummary, auto: bool) -> Option<String> {
    let fix = if auto {
        "the light is very uneven; set an exposure (display.exposure)"
    } else {
        "set another exposure (display.exposure), or choose it automatically (auto-exposure)"
    };
    if s.clipped >= EXTREME_SHARE {
        Some(format!(
            "{:.0} % of the image is clipped to white at exposure {:+.2}: it is washed out; {fix}",
            100.0 * s.clipped,
            s.exposure
        ))
    } else if s.black >= EXTREME_SHARE && s.max > 0.0 {
        Some(format!(
            "{:.0} % of the model in view is black at exposure {:+.2} (the brightest pixel has \
             luminance {:.3e}): unlit, seen from behind, or under-exposed; {fix}",
            100.0 * s.black,
            s.exposure,
            s.max
        ))
    } else if s.max == 0.0 && s.covered > 0.0 {
        Some("every pixel is black: no light reaches what the camera sees".to_string())
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn view(p: &[Vec3]) -> ImageView<'_> {
        ImageView {
            width: p.len() as u32,
            height: 1,
            pixels: p,
        }
    }

    #[test]
    fn auto_exposure_maps_the_log_average_to_middle_grey() {
        // Luminances 0.01 and 1 (grey pixels): log-average 0.1, so 0.18 / 0.1 = 1.8 = 2^0.848.
        // The black pixel is left out.
        let p = [Vec3::splat(0.01), Vec3::splat(1.0), Vec3::ZERO];
        let e = auto_exposure(view(&p));
        assert!((e - 1.8f64.log2()).abs() < 1e-6, "{e}");
        assert_eq!(auto_exposure(view(&[Vec3::ZERO])), 0.0);
    }

    #[test]
    fn summary_counts_black_and_clipped_pixels() {
        let p = [
            Vec3::ZERO,
            Vec3::splat(0.25),
            Vec3::splat(0.5),
            Vec3::splat(2.0),
        ];
        let s = summarize(view(&p), 1.0, 1.0, 0.0);
        assert_eq!(s.min, 0.0);
        assert!((s.median - 0.25).abs() < 1e-6);
        assert!((s.max - 2.0).abs() < 1e-6);
        // 0.5 and 2.0 reach 1 at +1 stop; 0 is black.
        assert_eq!(s.clipped, 0.5);
        assert_eq!(s.black, 0.25);
        assert!(exposure_warning(&s, false).is_some());
        let s = summarize(view(&p), -2.0, 1.0, 0.0);
        assert_eq!(s.clipped, 0.0);
        assert!(exposure_warning(&s, false).is_none());
        // Half the pixels are background (the black one and one more): the black share is of
        // the covered pixels only.
        let s = summarize(view(&p), 1.0, 0.75, 0.0);
        assert_eq!(s.black, 0.0);
    }
}
