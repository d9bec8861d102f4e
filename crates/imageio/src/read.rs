//! Image input: reads the images `pixelflow-sim compare` measures into a linear-RGB
//! [`LinearImage`], the counterpart of [`crate::write`].
//!
//! Formats are recognised by their first bytes, not by the file name:
//! - OpenEXR (`76 2f 31 01`) and Radiance HDR (`#?RADIANCE` / `#?RGBE`): linear floats, decoded by
//!   the `image` crate (its `exr` and `hdr` features) and taken as they are.
//! - PFM (`PF` colour, `Pf` greyscale): read here (a dozen lines; the `image` crate has no PFM).
//!   Header: the magic, then width, height and scale as whitespace-separated ASCII, then exactly
//!   one whitespace byte, then `width * height * channels` 32-bit floats, **rows bottom to top**.
//!   A negative scale means little-endian floats, a positive one big-endian; its magnitude is not
//!   applied (as most readers: writers put 1; applying it would change RMSE, never the perceptual
//!   distance). A greyscale PFM becomes R = G = B.
//! - PNG, 8 or 16 bits per channel, greyscale or RGB (alpha is ignored; palettes are expanded by
//!   the decoder): code values are taken as sRGB and decoded with the exact sRGB EOTF,
//!   `c / 12.92` for `c <= 0.04045`, `((c + 0.055) / 1.055)^2.4` above, `c` = code / 255 or
//!   code / 65535. This inverts [`crate::srgb_encode`] (the encoder's 0.0031308
//!   threshold maps to 0.04045). A PNG's exposure is not undone: compare PNGs written with the
//!   same exposure, or EXRs.
//!
//! Every error names the file and is an [`Error::Input`] (exit code 2): unreadable, unknown format,
//! truncated or malformed, or a NaN / infinite pixel (reported with its position, never passed
//! on to the metric). Rows are returned top to bottom for every format.

use std::path::Path;

use ::image::{DynamicImage, ImageFormat};
use glam::Vec3;

use crate::LinearImage;
use base::error::{Error, Location, Result};

/// Largest accepted PFM side, so a corrupt header cannot ask for an absurd allocation (the data
/// length is also checked against the file before anything is allocated).
pub const MAX_PFM_DIM: u32 = 1 << 16;

/// The exact sRGB EOTF: an encoded value in [0, 1] to linear (IEC 61966-2-1).
pub fn srgb_decode(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Reads an image file (EXR, Radiance HDR, PFM or PNG) as linear RGB. Errors name the file; a
/// file over [`base::output::MAX_INPUT_BYTES`] is refused ([`read_image_up_to`] takes a job's
/// smaller cap).
pub fn read_image(path: &Path) -> Result<LinearImage> {
    read_image_up_to(path, base::output::MAX_INPUT_BYTES)
}

/// [`read_image`] refusing a file over `max` bytes before it is read whole.
pub fn read_image_up_to(path: &Path, max: u64) -> Result<LinearImage> {
    let bytes = base::output::read_limited(path, max)
        .map_err(|e| Error::input(Location::file(path), format!("cannot read the image: {e}")))?;
    decode_image(&bytes, path)
}

const UNKNOWN_FORMAT: &str = "unknown image format (expected OpenEXR, Radiance HDR, PFM or PNG; \
     recognised by the file's first bytes)";

/// What an image file holds, from its header alone: its size, and whether its values are floats
/// (OpenEXR, Radiance HDR, PFM: decoded through 16 bytes a pixel) or 8/16-bit integers (PNG).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageHeader {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Float samples (EXR, HDR, PFM) rather than PNG's integers.
    pub float: bool,
}

/// Reads only the header of an image file (at most what the format's header takes, not the
/// pixels): its size, known before anything is decoded, so a decompression bomb (a small
/// file of a huge image) is refused by its size instead of exhausting memory. Errors name the
/// file, as [`read_image`]'s do.
pub fn read_image_header(path: &Path) -> Result<ImageHeader> {
    use std::io::{Read, Seek};
    let err = |m: String| Error::input(Location::file(path), m);
    let mut f =
        std::fs::File::open(path).map_err(|e| err(format!("cannot read the image: {e}")))?;
    let mut head = Vec::new();
    (&mut f)
        .take(256)
        .read_to_end(&mut head)
        .map_err(|e| err(format!("cannot read the image: {e}")))?;
    if head.starts_with(b"PF") || head.starts_with(b"Pf") {
        let h = pfm_header(&head, path)?;
        return Ok(ImageHeader {
            width: h.width,
            height: h.height,
            float: true,
        });
    }
    let format = ::image::guess_format(&head).ok();
    let (float, format) = match format {
        Some(f @ ImageFormat::Png) => (false, f),
        Some(f @ (ImageFormat::OpenExr | ImageFormat::Hdr)) => (true, f),
        _ => return Err(err(UNKNOWN_FORMAT.into())),
    };
    f.rewind()
        .map_err(|e| err(format!("cannot read the image: {e}")))?;
    let mut reader = ::image::ImageReader::new(std::io::BufReader::new(f));
    reader.set_format(format);
    let (width, height) = reader
        .into_dimensions()
        .map_err(|e| err(format!("cannot read the image's header: {e}")))?;
    Ok(ImageHeader {
        width,
        height,
        float,
    })
}

/// Decodes an image file's bytes; `source` names the file in errors.
pub fn decode_image(bytes: &[u8], source: &Path) -> Result<LinearImage> {
    let err = |m: String| Error::input(Location::file(source), m);
    let img = if bytes.starts_with(b"PF") || bytes.starts_with(b"Pf") {
        decode_pfm(bytes, source)?
    } else {
        match ::image::guess_format(bytes) {
            Ok(ImageFormat::Png) => decode_png(bytes, source)?,
            Ok(f @ (ImageFormat::OpenExr | ImageFormat::Hdr)) => {
                let d = ::image::load_from_memory_with_format(bytes, f)
                    .map_err(|e| err(format!("cannot decode the {f:?} image: {e}")))?;
                let rgb = d.to_rgb32f();
                let (w, h) = rgb.dimensions();
                let pixels = rgb.pixels().map(|p| Vec3::from_array(p.0)).collect();
                LinearImage::new(w, h, pixels).map_err(|e| err(e.to_string()))?
            }
            _ => return Err(err(UNKNOWN_FORMAT.into())),
        }
    };
    if let Some((x, y, p)) = img.first_non_finite() {
        return Err(err(format!(
            "pixel ({x}, {y}) (row 0 on top) is {p}: NaN and infinite values cannot be compared"
        )));
    }
    Ok(img)
}

/// An image file's pixels in any format the codecs know, as 8-bit RGB as stored (no transfer
/// function undone): for readers that decode sRGB themselves, as the glTF readback does.
pub fn decode_rgb8(bytes: &[u8]) -> std::result::Result<(u32, u32, Vec<[u8; 3]>), String> {
    let d = ::image::load_from_memory(bytes).map_err(|e| e.to_string())?;
    let rgb = d.to_rgb8();
    Ok((
        rgb.width(),
        rgb.height(),
        rgb.pixels().map(|p| p.0).collect(),
    ))
}

/// An image file's pixels in any format the codecs know, as float RGB as stored: linear for
/// EXR and HDR.
pub fn decode_rgb32f(bytes: &[u8]) -> std::result::Result<(u32, u32, Vec<[f32; 3]>), String> {
    let d = ::image::load_from_memory(bytes).map_err(|e| e.to_string())?;
    let rgb = d.to_rgb32f();
    Ok((
        rgb.width(),
        rgb.height(),
        rgb.pixels().map(|p| p.0).collect(),
    ))
}

/// Decodes a PNG (8 or 16 bits, grey or RGB, alpha ignored) from sRGB to linear.
fn decode_png(bytes: &[u8], source: &Path) -> Result<LinearImage> {
    let err = |m: String| Error::input(Location::file(source), m);
    let d = ::image::load_from_memory_with_format(bytes, ImageFormat::Png)
        .map_err(|e| err(format!("cannot decode the PNG image: {e}")))?;
    let sixteen = matches!(
        d,
        DynamicImage::ImageLuma16(_)
            | DynamicImage::ImageLumaA16(_)
            | DynamicImage::ImageRgb16(_)
            | DynamicImage::ImageRgba16(_)
    );
    let (w, h) = (d.width(), d.height());
    let pixels: Vec<Vec3> = if sixteen {
        d.to_rgb16()
            .pixels()
            .map(|p| Vec3::from_array(p.0.map(|c| srgb_decode(c as f64 / 65535.0) as f32)))
            .collect()
    } else {
        let lut: Vec<f32> = (0..256)
            .map(|c| srgb_decode(c as f64 / 255.0) as f32)
            .collect();
        d.to_rgb8()
            .pixels()
            .map(|p| Vec3::from_array(p.0.map(|c| lut[c as usize])))
            .collect()
    };
    LinearImage::new(w, h, pixels).map_err(|e| err(e.to_string()))
}

/// Reads one whitespace-delimited ASCII token of the PFM header starting at `*pos`.
fn pfm_token<'a>(bytes: &'a [u8], pos: &mut usize) -> Option<&'a str> {
    while *pos < bytes.len() && bytes[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    let start = *pos;
    while *pos < bytes.len() && !bytes[*pos].is_ascii_whitespace() {
        *pos += 1;
    }
    // A header token longer than 32 bytes is not a number this format uses.
    if start == *pos || *pos - start > 32 {
        return None;
    }
    std::str::from_utf8(&bytes[start..*pos]).ok()
}

/// A PFM header: channels, width, height, scale and where the data starts.
struct PfmHeader {
    channels: usize,
    width: u32,
    height: u32,
    scale: f64,
    data: usize,
}

/// Parses a PFM file's header; `source` names the file in errors.
fn pfm_header(bytes: &[u8], source: &Path) -> Result<PfmHeader> {
    let err = |m: String| Error::input(Location::file(source), format!("PFM: {m}"));
    let channels = match bytes.get(..2) {
        Some(b"PF") => 3usize,
        Some(b"Pf") => 1usize,
        _ => return Err(err("does not start with `PF` or `Pf`".into())),
    };
    let mut pos = 2;
    if !bytes.get(pos).is_some_and(|b| b.is_ascii_whitespace()) {
        return Err(err(
            "the magic `PF` / `Pf` must be followed by whitespace".into()
        ));
    }
    let mut dim = |what: &str| -> Result<u32> {
        let t = pfm_token(bytes, &mut pos)
            .ok_or_else(|| err(format!("header ends before the {what}")))?;
        match t.parse::<u32>() {
            Ok(v) if (1..=MAX_PFM_DIM).contains(&v) => Ok(v),
            _ => Err(err(format!(
                "{what} `{t}` is not an integer in 1..={MAX_PFM_DIM}"
            ))),
        }
    };
    let width = dim("width")?;
    let height = dim("height")?;
    let t = pfm_token(bytes, &mut pos).ok_or_else(|| err("header ends before the scale".into()))?;
    let scale: f64 = t
        .parse()
        .ok()
        .filter(|s: &f64| s.is_finite() && *s != 0.0)
        .ok_or_else(|| err(format!("scale `{t}` is not a finite non-zero number")))?;
    if !bytes.get(pos).is_some_and(|b| b.is_ascii_whitespace()) {
        return Err(err("header ends before the data".into()));
    }
    Ok(PfmHeader {
        channels,
        width,
        height,
        scale,
        data: pos + 1,
    })
}

/// Decodes a PFM file's bytes (see the module doc for the format); `source` names it in errors.
pub fn decode_pfm(bytes: &[u8], source: &Path) -> Result<LinearImage> {
    let err = |m: String| Error::input(Location::file(source), format!("PFM: {m}"));
    let PfmHeader {
        channels,
        width,
        height,
        scale,
        data: pos,
    } = pfm_header(bytes, source)?;
    let little = scale < 0.0;
    let (w, h) = (width as usize, height as usize);
    let need = w * h * channels * 4;
    let data = &bytes[pos..];
    if data.len() < need {
        return Err(err(format!(
            "truncated: a {width} x {height} {} image needs {need} bytes of data, the file has {}",
            if channels == 3 { "colour" } else { "greyscale" },
            data.len()
        )));
    }
    if data.len() > need {
        return Err(err(format!(
            "{} bytes after the {need} bytes of a {width} x {height} image (wrong header?)",
            data.len() - need
        )));
    }
    let value = |i: usize| -> f32 {
        let b = [
            data[4 * i],
            data[4 * i + 1],
            data[4 * i + 2],
            data[4 * i + 3],
        ];
        if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut pixels = Vec::with_capacity(w * h);
    // File rows run bottom to top; ours top to bottom.
    for y in 0..h {
        let file_row = h - 1 - y;
        for x in 0..w {
            let i = (file_row * w + x) * channels;
            pixels.push(if channels == 3 {
                Vec3::new(value(i), value(i + 1), value(i + 2))
            } else {
                Vec3::splat(value(i))
            });
        }
    }
    LinearImage::new(width, height, pixels).map_err(|e| err(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_decode_inverts_the_encoder() {
        // The two segments meet: 0.04045 / 12.92 and ((0.04045 + 0.055) / 1.055)^2.4 agree to
        // 1e-7 (the standard's constants are rounded); decode(encode(x)) is x to f32 precision.
        let lo = 0.04045 / 12.92;
        let hi = ((0.04045f64 + 0.055) / 1.055).powf(2.4);
        assert!((lo - hi).abs() < 1e-7);
        for i in 0..=1000 {
            let x = i as f32 / 1000.0;
            let back = srgb_decode(crate::srgb_encode(x) as f64);
            assert!((back - x as f64).abs() < 2e-6, "{x}: {back}");
        }
        assert_eq!(srgb_decode(0.0), 0.0);
        assert!((srgb_decode(1.0) - 1.0).abs() < 1e-15);
    }

    #[test]
    fn unknown_bytes_are_an_input_error_naming_the_file() {
        let e = decode_image(b"GIF89a....", Path::new("x.gif")).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(
            e.to_string().starts_with("x.gif: unknown image format"),
            "{e}"
        );
        let e = decode_image(b"", Path::new("empty.png")).unwrap_err();
        assert!(e.to_string().contains("empty.png"), "{e}");
    }

    #[test]
    fn pfm_header_errors() {
        let p = Path::new("h.pfm");
        for (bytes, what) in [
            (&b"PF"[..], "followed by whitespace"),
            (&b"PF\n0 2\n-1\n"[..], "width `0`"),
            (&b"PF\n2 x\n-1\n"[..], "height `x`"),
            (&b"PF\n2 2\n0\n"[..], "scale `0`"),
            (&b"PF\n2 2\nnan\n"[..], "scale `nan`"),
            (&b"PF\n2 2\n-1"[..], "before the data"),
            (&b"PF\n99999999 2\n-1\n"[..], "width `99999999`"),
        ] {
            let e = decode_pfm(bytes, p).unwrap_err().to_string();
            assert!(
                e.starts_with("h.pfm: PFM: ") && e.contains(what),
                "{what}: {e}"
            );
        }
    }
}
