//! Comparing image files: [`compare_files`] reads two images (any format [`crate::image::read`]
//! decodes) and compares them with the metric, for the `compare` command.

use std::path::Path;

use base::error::{Error, Location, Result};
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

/// What comparing `a` and `b` will hold at most, from the files' headers alone (before any
/// decoding: a small file of a huge image is refused here); `pixels` for the pixel-by-pixel
/// check, `perceptual` for the metric (the two run one after the other). Images of different
/// sizes are refused here too, naming both.
pub fn check_compare(a: &Path, b: &Path, pixels: bool, perceptual: bool, limit: u64) -> Result<()> {
    let (ha, hb) = (
        crate::image::read_image_header(a)?,
        crate::image::read_image_header(b)?,
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
    let mut e = super::budget::Estimate::new(
        format!("comparing {} with {}", a.display(), b.display()),
        "compare smaller images, or raise --memory-limit",
    );
    e.add(
        format!("{} x {} pixels", ha.width, ha.height),
        n.saturating_mul(per_pixel),
    );
    e.check(limit)
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

/// Reads two image files (EXR, Radiance HDR, PFM or PNG; see [`crate::image::read`]) and compares
/// them with [`metric::compare`], `b` the reference.
///
/// Errors name the file: unreadable, unknown format, truncated or non-finite ([`Error::Input`],
/// from the reader), all black ([`Error::Input`] at that file), and different sizes
/// ([`Error::InvalidOption`] naming both files and both sizes).
pub fn compare_files(a: &Path, b: &Path, ppd: f64) -> Result<Comparison> {
    let ia = crate::image::read_image(a)?;
    let ib = crate::image::read_image(b)?;
    sizes_agree(a, b, (ia.width, ia.height), (ib.width, ib.height))?;
    for (path, img) in [(a, &ia), (b, &ib)] {
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
    compare(&ia, &ib, ppd)
}
