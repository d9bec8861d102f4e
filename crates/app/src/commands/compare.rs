//! Comparing image files, for the `compare` command: [`run_compare`] reads two images (any
//! format [`imageio::read`] decodes) once, runs the pixel-by-pixel check
//! ([`metric::pixels::diff`]) and the perceptual measures ([`metric::compare`]) as asked, and
//! returns one [`CompareReport`] holding every number and every check with its limit, so a CI
//! job reads one JSON document and one verdict.
//!
//! Invariants: every option and both headers are checked before any pixel is decoded (a bad
//! threshold, images of different sizes or encodings, or a decompression bomb cost
//! milliseconds); a PNG (sRGB code values after the render's exposure and clamping) is compared
//! with a linear float image only when asked (`convert`), since their values differ by more
//! than any regression tolerance; `passed` is true exactly when every check passed. Thresholds
//! are meant to hold across image sizes: the pixel check fails on a percentage of pixels and the
//! perceptual check can bound the distance per pixel.

use std::path::{Path, PathBuf};

use serde::Serialize;

use base::error::{Error, Location, Result};
use base::image::LinearImage;
use metric::pixels::PixelDiff;
use metric::{compare, Comparison};

/// Bytes a pixel of the two images costs the perceptual comparison at its peak, the program's
/// own few MB aside (measured: 103 at 2048 x 2048 from EXR or PNG, 106 at 1024 x 1024 from
/// PFM, whose file is read whole before decoding): both linear images (12 each), the decoder's
/// buffer and its conversion (up to 28 for the image being decoded), the luminances and the
/// lightness images (8 each per image) and the two spectra (16 each per image).
pub const PERCEPTUAL_PIXEL_BYTES: u64 = 120;

/// Bytes a pixel costs the pixel-by-pixel check (measured at 2048 x 2048: 60 from EXR, 37 from
/// PNG): both linear images, the decoder's buffer, the difference image.
pub const PIXELS_PIXEL_BYTES: [u64; 2] = [40, 64];

/// What `pixelflow-sim compare` was asked to do.
#[derive(Debug, Clone)]
pub struct CompareRequest {
    /// The image under test.
    pub a: PathBuf,
    /// The reference.
    pub b: PathBuf,
    /// Pixels per degree of visual angle of the perceptual distance.
    pub ppd: f64,
    /// The visual angle the image's width spans, degrees: the perceptual distance then uses
    /// `ppd = width / view_degrees` (instead of `ppd`), so any resolution of one picture is
    /// seen alike.
    pub view_degrees: Option<f64>,
    /// The pixel-by-pixel check's relative tolerance (`None`: no pixel check).
    pub tolerance: Option<f32>,
    /// The pixel check's floor (see [`metric::pixels::diff`]).
    pub floor: f32,
    /// The pixel check fails when more than this percentage of the pixels differ.
    pub fail_percent: f64,
    /// Largest perceptual distance that passes.
    pub max_distance: Option<f64>,
    /// Largest perceptual distance per pixel that passes.
    pub max_distance_per_pixel: Option<f64>,
    /// Compare a PNG with a linear float image, decoding the PNG from sRGB to linear.
    pub convert: bool,
    /// A mask image of the same size (`truth --shadow-mask`): the luminance error is also split
    /// at the pixels whose mask luminance is above one half.
    pub mask: Option<PathBuf>,
    /// A second, independent estimate of the reference (a path tracer's image at another
    /// seed): the masked split then also estimates the error free of the references' noise
    /// ([`metric::edges::cross_split_at`]). Needs `mask`.
    pub second_reference: Option<PathBuf>,
}

impl CompareRequest {
    /// Whether the perceptual measures run: without a pixel check, or when one of their
    /// thresholds is given.
    pub fn perceptual(&self) -> bool {
        self.tolerance.is_none()
            || self.max_distance.is_some()
            || self.max_distance_per_pixel.is_some()
    }
}

/// One pass-or-fail test of a comparison: `value` against the largest passing `limit`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    /// The option that set the limit (`fail-percent`, `max-distance`, `max-distance-per-pixel`).
    pub name: &'static str,
    /// The largest value that passes.
    pub limit: f64,
    /// The measured value.
    pub value: f64,
    /// `value <= limit`.
    pub passed: bool,
}

impl Check {
    fn new(name: &'static str, limit: f64, value: f64) -> Check {
        Check {
            name,
            limit,
            value,
            passed: value <= limit,
        }
    }

    /// `4.5000 % of the pixels differ beyond the tolerance, over --fail-percent 1`: the check
    /// in words.
    fn describe(&self) -> String {
        let rel = if self.passed { "within" } else { "over" };
        let what = match self.name {
            "fail-percent" => {
                return format!(
                    "{:.4} % of the pixels differ beyond the tolerance, {rel} --fail-percent {}",
                    self.value, self.limit
                )
            }
            "max-distance" => "perceptual distance",
            _ => "perceptual distance per pixel",
        };
        format!(
            "{what} {:.6e} {rel} --{} {}",
            self.value, self.name, self.limit
        )
    }
}

/// Everything one `compare` run found: the perceptual measures (at the top level, under the
/// names [`Comparison`] gives them), the pixel check, the checks and the verdict.
#[derive(Debug, Clone, Serialize)]
pub struct CompareReport {
    /// The image under test.
    pub a: String,
    /// The reference.
    pub b: String,
    /// What was converted to compare the two (a PNG decoded from sRGB to linear beside a float
    /// image), `None` when both have one encoding.
    pub converted: Option<String>,
    /// The perceptual and error measures, when they ran.
    #[serde(flatten)]
    pub metrics: Option<Comparison>,
    /// The pixel-by-pixel check, when asked (`--tolerance`).
    pub pixels: Option<PixelDiff>,
    /// The luminance error split at the mask's pixels, when asked (`--mask`).
    pub masked: Option<MaskedSplit>,
    /// The checks, in the order pixels, distance, distance per pixel.
    pub checks: Vec<Check>,
    /// Every check passed (true when there are none).
    pub passed: bool,
}

/// The luminance error of `a` against `b` inside a mask and outside it.
#[derive(Debug, Clone, Serialize)]
pub struct MaskedSplit {
    /// The mask file.
    pub mask: String,
    /// The split: `near_*` inside the mask, `rmse_far` outside it.
    #[serde(flatten)]
    pub split: metric::edges::EdgeSplit,
    /// RMSE inside over RMSE outside (`None` when the outside's is 0).
    pub ratio: Option<f64>,
    /// With a second reference: the split of the error free of the references' noise.
    pub cross: Option<metric::edges::CrossSplit>,
    /// Its RMSE inside over outside (`None` when the outside's is 0).
    pub cross_ratio: Option<f64>,
}

impl MaskedSplit {
    /// One line for the terminal.
    pub fn line(&self) -> String {
        let e = &self.split;
        let show = |r: Option<f64>| r.map_or("-".to_string(), |r| format!("{r:.3}"));
        let mut s = format!(
            "in mask {}: {:.1} % of squared error on {} px (rmse {:.6e} in, {:.6e} out, ratio {})\n",
            self.mask,
            100.0 * e.near_share,
            e.near_pixels,
            e.rmse_near,
            e.rmse_far,
            show(self.ratio)
        );
        if let Some(c) = &self.cross {
            s += &format!(
                "  noise taken out (two references): rmse {:.6e} in, {:.6e} out, ratio {} \
                 (squared errors {:.3e} +- {:.1e} in, {:.3e} +- {:.1e} out)\n",
                c.rmse_near,
                c.rmse_far,
                show(self.cross_ratio),
                c.rmse_near * c.rmse_near,
                c.squared_se_near,
                c.rmse_far * c.rmse_far,
                c.squared_se_far
            );
        }
        s
    }
}

impl CompareReport {
    /// The failed checks, for the error message (empty when all passed).
    pub fn failures(&self) -> Vec<String> {
        self.checks
            .iter()
            .filter(|c| !c.passed)
            .map(|c| c.describe())
            .collect()
    }

    /// The report for the terminal: the conversion, the pixel check's summary, the table of
    /// measures and one line per check.
    pub fn text(&self) -> String {
        let mut s = String::new();
        if let Some(c) = &self.converted {
            s += &format!("note: {c}\n");
        }
        if let Some(p) = &self.pixels {
            s += &(p.summary() + "\n");
        }
        if let Some(m) = &self.metrics {
            s += &m.table();
        }
        if let Some(m) = &self.masked {
            s += &m.line();
        }
        for c in &self.checks {
            let verdict = if c.passed { "passed" } else { "FAILED" };
            s += &format!("check {verdict}: {}\n", c.describe());
        }
        s
    }
}

/// A threshold option must be a number >= 0 (a NaN would pass everything).
fn non_negative(option: &str, value: f64, most: f64) -> Result<()> {
    if value.is_finite() && value >= 0.0 && value <= most {
        return Ok(());
    }
    Err(Error::invalid_option(
        option,
        value.to_string(),
        format!("must be a number from 0 to {most}"),
    ))
}

/// Checks every option of `req` that needs no file.
fn check_options(req: &CompareRequest) -> Result<()> {
    if req.second_reference.is_some() && req.mask.is_none() {
        return Err(Error::invalid_option(
            "second-reference",
            "",
            "splits the error at a mask: give `mask` mask.exr too",
        ));
    }
    non_negative("fail-percent", req.fail_percent, 100.0)?;
    if let Some(d) = req.max_distance {
        non_negative("max-distance", d, f64::MAX)?;
    }
    if let Some(d) = req.max_distance_per_pixel {
        non_negative("max-distance-per-pixel", d, f64::MAX)?;
    }
    if let Some(deg) = req.view_degrees {
        if !(deg.is_finite() && deg > 0.0 && deg <= 360.0) {
            return Err(Error::invalid_option(
                "view-degrees",
                deg.to_string(),
                "the visual angle of the image's width must be a number of degrees in (0, 360]",
            ));
        }
    }
    Ok(())
}

/// What comparing `a` and `b` will hold at most, from the files' headers alone (before any
/// decoding: a small file of a huge image is refused here); `pixels` for the pixel-by-pixel
/// check, `perceptual` for the metric (the two run one after the other). Images of different
/// sizes are refused here too, naming both.
pub fn check_compare(a: &Path, b: &Path, pixels: bool, perceptual: bool, limit: u64) -> Result<()> {
    let (ha, hb) = (
        imageio::read_image_header(a)?,
        imageio::read_image_header(b)?,
    );
    sizes_agree(a, b, (ha.width, ha.height), (hb.width, hb.height))?;
    let n = ha.width as u64 * ha.height as u64;
    let float = ha.float || hb.float;
    let mut per_pixel = 0;
    if pixels {
        per_pixel = PIXELS_PIXEL_BYTES[float as usize];
    }
    if perceptual {
        per_pixel = per_pixel.max(PERCEPTUAL_PIXEL_BYTES);
    }
    let mut e = crate::budget::Estimate::new(
        format!("comparing {} with {}", a.display(), b.display()),
        "compare smaller images, or raise `memory-limit`",
    );
    e.add(
        format!("{} x {} pixels", ha.width, ha.height),
        n.saturating_mul(per_pixel),
    );
    e.check(limit)
}

/// Refuses a PNG beside a float image unless `convert`; with it, says what was converted.
fn encodings_agree(a: &Path, b: &Path, convert: bool) -> Result<Option<String>> {
    let (fa, fb) = (
        imageio::read_image_header(a)?.float,
        imageio::read_image_header(b)?.float,
    );
    if fa == fb {
        return Ok(None);
    }
    let (png, float) = if fa { (b, a) } else { (a, b) };
    if !convert {
        return Err(Error::invalid_option(
            "images",
            "",
            format!(
                "{} is a PNG and {} a linear float image: different encodings (the PNG holds \
                 sRGB code values after the render's exposure and clamping, quantised to 8 or \
                 16 bits), so their values do not compare; compare the float image with a \
                 float image (render `exr`), or give `convert` to decode the PNG from sRGB to \
                 linear anyway",
                png.display(),
                float.display()
            ),
        ));
    }
    Ok(Some(format!(
        "{} decoded from sRGB to linear to compare with the float image {} (--convert); its \
         exposure and clamping are not undone",
        png.display(),
        float.display()
    )))
}

fn sizes_agree(a: &Path, b: &Path, sa: (u32, u32), sb: (u32, u32)) -> Result<()> {
    if sa == sb {
        return Ok(());
    }
    Err(Error::invalid_option(
        "images",
        "",
        format!(
            "sizes differ: {} is {} x {}, {} is {} x {}",
            a.display(),
            sa.0,
            sa.1,
            b.display(),
            sb.0,
            sb.1
        ),
    ))
}

/// Runs a `compare` request within the memory `limit` (module docs). Errors ([`Error::Input`] or
/// [`Error::InvalidOption`], exit code 2): a bad option, an unreadable image, images of
/// different sizes or (without `convert`) encodings, an all-black image for the perceptual
/// measures. A failed check is not an error: it is in the report.
pub fn run_compare(req: &CompareRequest, limit: u64) -> Result<CompareReport> {
    check_options(req)?;
    let perceptual = req.perceptual();
    check_compare(&req.a, &req.b, req.tolerance.is_some(), perceptual, limit)?;
    let converted = encodings_agree(&req.a, &req.b, req.convert)?;
    let most = base::output::input_limit_for(crate::budget::data_limit(limit));
    let ia = imageio::read_image_up_to(&req.a, most)?;
    let ib = imageio::read_image_up_to(&req.b, most)?;
    sizes_agree(&req.a, &req.b, (ia.width, ia.height), (ib.width, ib.height))?;
    let masked = match &req.mask {
        Some(path) => {
            let second = match &req.second_reference {
                Some(p2) => {
                    let i2 = imageio::read_image_up_to(p2, most)?;
                    sizes_agree(&req.b, p2, (ib.width, ib.height), (i2.width, i2.height))?;
                    Some(i2)
                }
                None => None,
            };
            Some(masked_split(path, &ia, &ib, second.as_ref(), most)?)
        }
        None => None,
    };
    let mut checks = Vec::new();
    let pixels = match req.tolerance {
        Some(tolerance) => {
            let d = metric::pixels::diff(&ia, &ib, tolerance, req.floor)?;
            checks.push(Check::new(
                "fail-percent",
                req.fail_percent,
                d.differing_percent,
            ));
            Some(d)
        }
        None => None,
    };
    let metrics = if perceptual {
        let ppd = req.view_degrees.map_or(req.ppd, |d| ia.width as f64 / d);
        let c = compare_images((&req.a, &ia), (&req.b, &ib), ppd)?;
        if let Some(m) = req.max_distance {
            checks.push(Check::new("max-distance", m, c.perceptual_distance));
        }
        if let Some(m) = req.max_distance_per_pixel {
            checks.push(Check::new(
                "max-distance-per-pixel",
                m,
                c.perceptual_distance_per_pixel,
            ));
        }
        Some(c)
    } else {
        None
    };
    Ok(CompareReport {
        a: req.a.display().to_string(),
        b: req.b.display().to_string(),
        converted,
        metrics,
        pixels,
        masked,
        passed: checks.iter().all(|c| c.passed),
        checks,
    })
}

/// The luminance error of `ia` against `ib` split at the mask image `path` (pixels whose
/// luminance is above one half are in it); the mask must have the images' size.
fn masked_split(
    path: &Path,
    ia: &LinearImage,
    ib: &LinearImage,
    ib2: Option<&LinearImage>,
    most: u64,
) -> Result<MaskedSplit> {
    let mask = imageio::read_image_up_to(path, most)?;
    if (mask.width, mask.height) != (ia.width, ia.height) {
        return Err(Error::input(
            Location::file(path),
            format!(
                "the mask is {} x {}, the images {} x {}",
                mask.width, mask.height, ia.width, ia.height
            ),
        ));
    }
    let inside: Vec<bool> = mask.luminance().iter().map(|&y| y > 0.5).collect();
    let (ya, yb) = (ia.luminance(), ib.luminance());
    let split = metric::edges::split_at(&ya, &yb, &inside);
    let cross = ib2.map(|i2| metric::edges::cross_split_at(&ya, &yb, &i2.luminance(), &inside));
    Ok(MaskedSplit {
        mask: path.display().to_string(),
        split,
        ratio: (split.rmse_far > 0.0).then(|| split.rmse_near / split.rmse_far),
        cross,
        cross_ratio: cross
            .filter(|c| c.rmse_far > 0.0)
            .map(|c| c.rmse_near / c.rmse_far),
    })
}

/// [`metric::compare`] of two decoded images, an all-black one refused naming its file.
fn compare_images(
    (a, ia): (&Path, &LinearImage),
    (b, ib): (&Path, &LinearImage),
    ppd: f64,
) -> Result<Comparison> {
    for (path, img) in [(a, ia), (b, ib)] {
        let m = img.mean_luminance();
        // The pixels are finite (checked), so the mean is finite: `<=` catches every bad case.
        if m <= 0.0 {
            return Err(Error::input(
                Location::file(path),
                format!(
                    "mean luminance is {m} (an all-black image?): the perceptual metric \
                     normalises by it and is undefined"
                ),
            ));
        }
    }
    compare(ia, ib, ppd)
}

/// Reads two image files (EXR, Radiance HDR, PFM or PNG; see [`imageio::read`]) and compares
/// them with [`metric::compare`], `b` the reference.
///
/// Errors name the file: unreadable, unknown format, truncated or non-finite ([`Error::Input`],
/// from the reader), all black ([`Error::Input`] at that file), and different sizes
/// ([`Error::InvalidOption`] naming both files and both sizes).
pub fn compare_files(a: &Path, b: &Path, ppd: f64) -> Result<Comparison> {
    let ia = imageio::read_image(a)?;
    let ib = imageio::read_image(b)?;
    sizes_agree(a, b, (ia.width, ia.height), (ib.width, ib.height))?;
    compare_images((a, &ia), (b, &ib), ppd)
}
