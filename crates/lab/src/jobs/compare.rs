//! Comparing image files: [`compare_files`] reads two images (any format [`crate::image::read`]
//! decodes) and compares them with the metric, for the `compare` command.

use std::path::Path;

use base::error::{Error, Location, Result};
use metric::{compare, Comparison};

/// Reads two image files (EXR, Radiance HDR, PFM or PNG; see [`crate::image::read`]) and compares
/// them with [`metric::compare`], `b` the reference.
///
/// Errors name the file: unreadable, unknown format, truncated or non-finite ([`Error::Input`],
/// from the reader), all black ([`Error::Input`] at that file), and different sizes
/// ([`Error::InvalidOption`] naming both files and both sizes).
pub fn compare_files(a: &Path, b: &Path, ppd: f64) -> Result<Comparison> {
    let ia = crate::image::read_image(a)?;
    let ib = crate::image::read_image(b)?;
    if (ia.width, ia.height) != (ib.width, ib.height) {
        return Err(Error::invalid_option(
            "images",
            "",
            format!(
                "sizes differ: {} is {} x {}, {} is {} x {}",
                a.display(),
                ia.width,
                ia.height,
                b.display(),
                ib.width,
                ib.height
            ),
        ));
    }
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
