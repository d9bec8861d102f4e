//! The walkthrough camera path: keyframes evenly spaced in time, interpolated so the motion has
//! no jumps in velocity.
//!
//! Eye and look-at points follow a uniform Catmull-Rom spline through the keyframes (the end
//! keyframes are repeated as their own outer neighbours), which is C1: position and velocity are
//! continuous at every keyframe, so a walkthrough does not jerk where one segment meets the
//! next. Up is interpolated linearly between the two keyframes of a segment (it only has to stay
//! away from the view direction, which the loader checks at keyframes). The projection is the
//! scene camera's. Frame `k` of `n` sits at path time `t = k / (n - 1) * segments`, so the first
//! and last frames are exactly the first and last keyframes.

use glam::DVec3;

use super::{Camera, CameraPath, Keyframe, Projection};

impl CameraPath {
    /// Path segments (keyframes - 1, at least 1).
    pub fn segments(&self) -> usize {
        self.keyframes.len().saturating_sub(1).max(1)
    }

    /// The camera of frame `k` of the path's [`CameraPath::frames`], with `projection`.
    pub fn camera(&self, projection: Projection, k: u32) -> Camera {
        let n = self.frames;
        let t = if n <= 1 {
            0.0
        } else {
            k as f64 / (n - 1) as f64 * self.segments() as f64
        };
        self.camera_at(projection, t)
    }

    /// The camera at path time `t` in `[0, segments]` (keyframe `i` at `t = i`; clamped).
    pub fn camera_at(&self, projection: Projection, t: f64) -> Camera {
        let keyframes = &self.keyframes;
        let segs = self.segments();
        let t = if t.is_finite() {
            t.clamp(0.0, segs as f64)
        } else {
            0.0
        };
        let i = (t.floor() as usize).min(segs - 1);
        let f = t - i as f64;
        let last = keyframes.len() as isize - 1;
        let at = |j: isize| keyframes[j.clamp(0, last.max(0)) as usize];
        let (k0, k1, k2, k3): (Keyframe, Keyframe, Keyframe, Keyframe) = (
            at(i as isize - 1),
            at(i as isize),
            at(i as isize + 1),
            at(i as isize + 2),
        );
        let cr = |p0: DVec3, p1: DVec3, p2: DVec3, p3: DVec3| {
            let (f2, f3) = (f * f, f * f * f);
            0.5 * ((2.0 * p1)
                + (p2 - p0) * f
                + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * f2
                + (3.0 * p1 - p0 - 3.0 * p2 + p3) * f3)
        };
        let eye = cr(k0.eye, k1.eye, k2.eye, k3.eye);
        let mut look_at = cr(k0.look_at, k1.look_at, k2.look_at, k3.look_at);
        if (look_at - eye).length_squared() < 1e-18 {
            // Documented fallback: a spline that brings eye and target together keeps the keyframe
            // direction instead of producing an undefined view.
            look_at = eye + (k1.look_at - k1.eye);
        }
        let up = k1.up.lerp(k2.up, f);
        Camera {
            eye,
            look_at,
            up: if up.length_squared() > 0.0 { up } else { k1.up },
            projection,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path() -> CameraPath {
        let kf = |e: [f64; 3], l: [f64; 3]| Keyframe {
            eye: DVec3::from(e),
            look_at: DVec3::from(l),
            up: DVec3::Y,
        };
        CameraPath {
            keyframes: vec![
                kf([0.0, 1.0, 5.0], [0.0, 1.0, 0.0]),
                kf([3.0, 1.5, 4.0], [0.5, 1.0, 0.0]),
                kf([4.0, 1.0, 0.0], [0.0, 0.8, 0.0]),
                kf([1.0, 2.0, -3.0], [-1.0, 1.0, 0.0]),
            ],
            frames: 31,
        }
    }

    const PROJ: Projection = Projection::Perspective { fov_y_deg: 45.0 };

    #[test]
    fn frames_start_and_end_on_the_end_keyframes_and_pass_through_every_keyframe() {
        let p = path();
        let first = p.camera(PROJ, 0);
        let last = p.camera(PROJ, p.frames - 1);
        // The spline at f = 0 is p1 exactly; at f = 1 it is p2 up to a few roundings of values
        // below 10 (1e-12 is thousands of ulps).
        assert_eq!(first.eye, p.keyframes[0].eye);
        assert!((last.eye - p.keyframes[3].eye).length() < 1e-12);
        assert!((last.look_at - p.keyframes[3].look_at).length() < 1e-12);
        for (i, k) in p.keyframes.iter().enumerate() {
            let c = p.camera_at(PROJ, i as f64);
            assert!((c.eye - k.eye).length() < 1e-12, "keyframe {i}");
            assert!((c.look_at - k.look_at).length() < 1e-12, "keyframe {i}");
        }
    }

    /// C1 at interior keyframes: one-sided difference quotients of eye and look-at agree. With
    /// step h the one-sided quotients of a C1 piecewise cubic differ from the common derivative
    /// by at most h/2 max|x''| each side; the second derivative of these splines is below 60 (the
    /// points span a few units), so 1e-4 * 60 = 6e-3 bounds the gap, while a kink (a C0 join)
    /// would leave a gap the size of the velocity jump, order 1.
    #[test]
    fn the_path_is_c1_at_interior_keyframes() {
        let p = path();
        let h = 1e-4;
        for i in 1..p.keyframes.len() - 1 {
            let t = i as f64;
            let c = p.camera_at(PROJ, t);
            let (l, r) = (p.camera_at(PROJ, t - h), p.camera_at(PROJ, t + h));
            for (name, x, xl, xr) in [
                ("eye", c.eye, l.eye, r.eye),
                ("look_at", c.look_at, l.look_at, r.look_at),
            ] {
                let left = (x - xl) / h;
                let right = (xr - x) / h;
                assert!(
                    (left - right).length() < 6e-3,
                    "{name} at keyframe {i}: left {left} right {right}"
                );
                // The derivative is the Catmull-Rom tangent (p[i+1] - p[i-1]) / 2.
                let tangent = match name {
                    "eye" => (p.keyframes[i + 1].eye - p.keyframes[i - 1].eye) * 0.5,
                    _ => (p.keyframes[i + 1].look_at - p.keyframes[i - 1].look_at) * 0.5,
                };
                assert!((left - tangent).length() < 6e-3, "{name} at keyframe {i}");
            }
        }
    }

    #[test]
    fn out_of_range_times_are_clamped() {
        let p = path();
        assert_eq!(p.camera_at(PROJ, -3.0).eye, p.keyframes[0].eye);
        assert!((p.camera_at(PROJ, 99.0).eye - p.keyframes[3].eye).length() < 1e-12);
        assert_eq!(p.camera_at(PROJ, f64::NAN).eye, p.keyframes[0].eye);
    }
}
