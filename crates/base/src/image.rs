//! Images: the linear-RGB image type every stage after the frame exchanges.
//!
//! [`LinearImage`] (and its borrowed form [`ImageView`]) hold linear radiosity, row-major, row 0 on
//! top; nothing here applies a tone curve. The files (PNG in sRGB, OpenEXR, reading them back) are
//! the lab's (`lab::image`), so that only the jobs depend on the image codecs.
//!
//! Why a module of its own: the renderer makes images and the metric compares them, and neither
//! should depend on the other; both depend on this.

use glam::Vec3;

use crate::error::{Error, Result};

/// A borrowed linear-RGB image: `width * height` pixels, row-major, row 0 on top.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB pixels.
    pub pixels: &'a [Vec3],
}

impl LinearImage {
    /// This image, borrowed.
    pub fn view(&self) -> ImageView<'_> {
        ImageView {
            width: self.width,
            height: self.height,
            pixels: &self.pixels,
        }
    }
}

/// Rec. 709 / sRGB luminance weights of linear R, G, B (`docs/metrics.md`, step 1).
pub const LUMINANCE_WEIGHTS: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// A linear-RGB image: `width * height` pixels, row-major, row 0 on top.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB pixels, row-major, row 0 on top (`pixels[y * width + x]`).
    pub pixels: Vec<Vec3>,
}

impl LinearImage {
    /// An image, checked: both sizes at least 1 and `pixels.len() == width * height`.
    pub fn new(width: u32, height: u32, pixels: Vec<Vec3>) -> Result<LinearImage> {
        let img = LinearImage {
            width,
            height,
            pixels,
        };
        img.check_shape()?;
        Ok(img)
    }

    /// An image of `width * height` pixels, each `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> Vec3) -> LinearImage {
        let mut pixels = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                pixels.push(f(x, y));
            }
        }
        LinearImage {
            width,
            height,
            pixels,
        }
    }

    /// The pixel at column `x`, row `y` (row 0 on top). Panics outside the image.
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// The luminance of every pixel, in `f64`, in pixel order.
    pub fn luminance(&self) -> Vec<f64> {
        self.pixels.iter().map(|p| luminance(*p)).collect()
    }

    /// The mean luminance (sequential sum in pixel order, divided by the pixel count; 0 for an
    /// empty image).
    pub fn mean_luminance(&self) -> f64 {
        mean(&self.luminance())
    }

    /// Errors unless the sizes are at least 1 and the pixel count matches.
    pub fn check_shape(&self) -> Result<()> {
        let n = self.width as usize * self.height as usize;
        if self.width == 0 || self.height == 0 || self.pixels.len() != n {
            return Err(Error::invalid_option(
                "image",
                format!("{} x {}", self.width, self.height),
                format!(
                    "holds {} pixels (needs at least 1 x 1 and width * height pixels)",
                    self.pixels.len()
                ),
            ));
        }
        Ok(())
    }

    /// The first non-finite pixel, as (x, y, value), if any.
    pub fn first_non_finite(&self) -> Option<(u32, u32, Vec3)> {
        let w = self.width.max(1) as usize;
        self.pixels
            .iter()
            .position(|p| !p.is_finite())
            .map(|i| ((i % w) as u32, (i / w) as u32, self.pixels[i]))
    }
}

/// The luminance of a linear RGB value (`docs/metrics.md`, step 1), in `f64`.
pub fn luminance(p: Vec3) -> f64 {
    LUMINANCE_WEIGHTS[0] * p.x as f64
        + LUMINANCE_WEIGHTS[1] * p.y as f64
        + LUMINANCE_WEIGHTS[2] * p.z as f64
}

/// Sequential mean (0 for an empty slice).
pub fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}
