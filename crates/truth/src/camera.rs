//! Camera rays: the renderer's view and projection, written again from its definition so that
//! the reference depends on no part of the renderer, and the pixel filters a truth image can
//! average over.
//!
//! The view is the renderer's (`render`): forward = normalize(look_at - eye), right =
//! normalize(forward x up), up' = right x forward. Pixel coordinates are continuous, pixel
//! (i, j) covering [i, i + 1] x [j, j + 1] with its centre at (i + 0.5, j + 0.5), row 0 at the
//! top. A perspective camera takes the vertical field of view from the scene and the
//! horizontal one from the image's aspect ratio: the point at view coordinates (x, y, w) lands
//! on px = w_img / 2 + x / w * w_img / (2 tan(fov_x / 2)), py = h_img / 2 - y / w * h_img /
//! (2 tan(fov_y / 2)), with tan(fov_x / 2) = tan(fov_y / 2) * w_img / h_img. An orthographic
//! camera maps its width x height rectangle onto the image (pixels need not be square) and sees
//! only what is in front of the eye's plane. [`CameraRays::ray`] inverts this map and
//! [`CameraRays::project`] applies it, so a ray's hit point projects back onto the pixel
//! position the ray was cast through.
//!
//! The filters: [`PixelFilter::Box`] draws positions uniformly over the pixel, so the expected
//! value of a pixel is the average of B over the pixel's box, the integral `render --aa 4` and
//! `--aa 16` approximate with fixed points; [`PixelFilter::Pattern`] draws one of the renderer's
//! own `--aa` sample positions at random, so the expected value is exactly what `render --aa N`
//! computes from a perfect solution (the mean of B at those positions).

use glam::DVec3;

use base::error::{Error, Result};
use base::method::Aa;
use scene::{Camera, Projection};

/// Where in its pixel each camera sample lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFilter {
    /// Uniform over the pixel's box: the expected value is the box average.
    Box,
    /// One of the renderer's `--aa` positions (1, 4 or 16), drawn uniformly: the expected value
    /// is the mean over the pattern, what `render --aa N` computes.
    Pattern(Aa),
}

/// The pixel centre: `render --aa 1`.
const CENTRE: [(f64, f64); 1] = [(0.5, 0.5)];
/// The rotated grid of `render --aa 4`.
const ROTATED_GRID: [(f64, f64); 4] = [
    (0.375, 0.125),
    (0.875, 0.375),
    (0.125, 0.625),
    (0.625, 0.875),
];
/// The 4 x 4 grid of `render --aa 16`, at the centres of the quarter-pixel cells, row by row.
const STRATIFIED_16: [(f64, f64); 16] = {
    let mut o = [(0.0f64, 0.0f64); 16];
    let c = [0.125, 0.375, 0.625, 0.875];
    let mut k = 0;
    while k < 16 {
        o[k] = (c[k % 4], c[k / 4]);
        k += 1;
    }
    o
};

impl PixelFilter {
    /// The filter of `--aa`: `None` is the box, otherwise the renderer's pattern.
    pub fn from_aa(aa: Option<Aa>) -> PixelFilter {
        aa.map_or(PixelFilter::Box, PixelFilter::Pattern)
    }

    /// The renderer's sample positions of this pattern (offsets from the pixel's top-left
    /// corner), `None` for the box.
    pub fn positions(&self) -> Option<&'static [(f64, f64)]> {
        match self {
            PixelFilter::Box => None,
            PixelFilter::Pattern(n) => Some(pattern(*n)),
        }
    }

    /// An offset within the pixel drawn from `rng`.
    pub(crate) fn offset(&self, rng: &mut base::rng::Rng) -> (f64, f64) {
        match self.positions() {
            None => (rng.next_f64(), rng.next_f64()),
            Some(p) if p.len() == 1 => p[0],
            Some(p) => p[rng.below(p.len() as u32) as usize],
        }
    }
}

fn pattern(aa: Aa) -> &'static [(f64, f64)] {
    match aa.samples() {
        1 => &CENTRE,
        4 => &ROTATED_GRID,
        _ => &STRATIFIED_16,
    }
}

/// The camera's rays for one image size.
#[derive(Debug, Clone, Copy)]
pub struct CameraRays {
    eye: DVec3,
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    perspective: bool,
    /// View units per pixel at unit depth (perspective) or per pixel (orthographic).
    kx: f64,
    ky: f64,
    width: f64,
    height: f64,
}

impl CameraRays {
    /// The rays of `camera` for a `width` x `height` image; an error for a camera the renderer
    /// would refuse too (look-at at the eye, up along the view, a field of view outside
    /// (0, 180) degrees, an empty orthographic rectangle).
    pub fn new(camera: &Camera, width: u32, height: u32) -> Result<CameraRays> {
        let bad = |why: &str| Error::invalid_option("the camera", "", why);
        if width == 0 || height == 0 {
            return Err(bad("the image needs at least one pixel"));
        }
        let f = camera.look_at - camera.eye;
        if !f.is_finite() || !camera.eye.is_finite() || f.length() == 0.0 {
            return Err(bad("look_at must be finite and differ from eye"));
        }
        let forward = f.normalize();
        let r = forward.cross(camera.up);
        if !r.is_finite() || r.length() <= 1e-9 * camera.up.length() || r.length() == 0.0 {
            return Err(bad("up must not be parallel to the view direction"));
        }
        let right = r.normalize();
        let up = right.cross(forward);
        let (w, h) = (width as f64, height as f64);
        let (perspective, kx, ky) = match camera.projection {
            Projection::Perspective { fov_y_deg } => {
                if !(fov_y_deg > 0.0 && fov_y_deg < 180.0) {
                    return Err(bad("the field of view must be in (0, 180) degrees"));
                }
                let ty = (0.5 * fov_y_deg.to_radians()).tan();
                let tx = ty * w / h;
                (true, 2.0 * tx / w, 2.0 * ty / h)
            }
            Projection::Orthographic {
                width: vw,
                height: vh,
            } => {
                if !(vw > 0.0 && vh > 0.0 && vw.is_finite() && vh.is_finite()) {
                    return Err(bad("orthographic width and height must be positive"));
                }
                (false, vw / w, vh / h)
            }
        };
        Ok(CameraRays {
            eye: camera.eye,
            right,
            up,
            forward,
            perspective,
            kx,
            ky,
            width: w,
            height: h,
        })
    }

    /// The ray through the continuous pixel position (`px`, `py`): its origin (the eye, or the
    /// point of the eye's plane for an orthographic camera) and its unit direction.
    pub fn ray(&self, px: f64, py: f64) -> (DVec3, DVec3) {
        let x = (px - 0.5 * self.width) * self.kx;
        let y = (0.5 * self.height - py) * self.ky;
        if self.perspective {
            let d = self.forward + x * self.right + y * self.up;
            (self.eye, d.normalize())
        } else {
            (self.eye + x * self.right + y * self.up, self.forward)
        }
    }

    /// The continuous pixel position a world point projects to, `None` behind the eye (or its
    /// plane): the renderer's projection, the inverse of [`CameraRays::ray`].
    pub fn project(&self, p: DVec3) -> Option<[f64; 2]> {
        let d = p - self.eye;
        let (x, y, w) = (d.dot(self.right), d.dot(self.up), d.dot(self.forward));
        if self.perspective {
            (w > 0.0).then(|| {
                [
                    0.5 * self.width + x / w / self.kx,
                    0.5 * self.height - y / w / self.ky,
                ]
            })
        } else {
            (w >= 0.0).then(|| {
                [
                    0.5 * self.width + x / self.kx,
                    0.5 * self.height - y / self.ky,
                ]
            })
        }
    }

    /// The eye.
    pub fn eye(&self) -> DVec3 {
        self.eye
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(projection: Projection) -> Camera {
        Camera {
            eye: DVec3::new(0.3, 1.0, 4.0),
            look_at: DVec3::new(-0.2, 0.8, 0.0),
            up: DVec3::Y,
            projection,
        }
    }

    /// A ray through any position projects back onto it, for both projections and a
    /// non-square image, and the image's centre looks straight ahead.
    #[test]
    fn ray_and_projection_are_inverse() {
        for projection in [
            Projection::Perspective { fov_y_deg: 39.3 },
            Projection::Orthographic {
                width: 3.0,
                height: 1.5,
            },
        ] {
            let c = CameraRays::new(&camera(projection), 96, 64).unwrap();
            let (o, d) = c.ray(48.0, 32.0);
            let f = (camera(projection).look_at - camera(projection).eye).normalize();
            assert!((d - f).length() < 1e-12);
            assert!((o - camera(projection).eye).length() < 1e-12);
            for (px, py) in [(0.5, 0.5), (95.5, 63.5), (10.25, 50.75), (0.0, 64.0)] {
                let (o, d) = c.ray(px, py);
                let q = c.project(o + 2.7 * d).unwrap();
                assert!(
                    (q[0] - px).abs() < 1e-9 && (q[1] - py).abs() < 1e-9,
                    "{q:?}"
                );
            }
        }
    }

    /// The perspective image spans the vertical field of view exactly, the horizontal one from
    /// the aspect ratio; the orthographic one spans the camera's rectangle.
    #[test]
    fn image_edges_span_the_field_of_view() {
        let fov = 50.0f64;
        let c = CameraRays::new(
            &camera(Projection::Perspective { fov_y_deg: fov }),
            200,
            100,
        )
        .unwrap();
        let (_, top) = c.ray(100.0, 0.0);
        let (_, bottom) = c.ray(100.0, 100.0);
        assert!((top.angle_between(bottom).to_degrees() - fov).abs() < 1e-9);
        let (_, left) = c.ray(0.0, 50.0);
        let (_, right) = c.ray(200.0, 50.0);
        let tx = 2.0 * (0.5 * fov.to_radians()).tan();
        assert!((left.angle_between(right) - 2.0 * tx.atan()).abs() < 1e-12);
        let o = CameraRays::new(
            &camera(Projection::Orthographic {
                width: 3.0,
                height: 1.5,
            }),
            30,
            10,
        )
        .unwrap();
        assert!(((o.ray(0.0, 5.0).0 - o.ray(30.0, 5.0).0).length() - 3.0).abs() < 1e-12);
        assert!(((o.ray(15.0, 0.0).0 - o.ray(15.0, 10.0).0).length() - 1.5).abs() < 1e-12);
        // Row 0 is at the top: a smaller py is higher up.
        assert!(o.ray(15.0, 0.0).0.y > o.ray(15.0, 10.0).0.y);
    }

    #[test]
    fn patterns_are_the_renderers_and_others_are_refused() {
        let aa = |n| Aa::new("aa", n).unwrap();
        assert_eq!(
            PixelFilter::Pattern(aa(1)).positions().unwrap(),
            &[(0.5, 0.5)]
        );
        assert_eq!(PixelFilter::Pattern(aa(4)).positions().unwrap().len(), 4);
        let p16 = PixelFilter::Pattern(aa(16)).positions().unwrap();
        assert_eq!(p16[5], (0.375, 0.375));
        assert!(Aa::new("aa", 3).is_err());
        assert_eq!(PixelFilter::from_aa(None), PixelFilter::Box);
        let bad = Camera {
            up: DVec3::new(-0.5, -0.2, -4.0),
            ..camera(Projection::Perspective { fov_y_deg: 40.0 })
        };
        assert!(CameraRays::new(&bad, 8, 8).is_err());
    }
}
