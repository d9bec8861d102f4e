//! Anisotropic texture filtering: a lookup whose footprint is longer one way than the other (a
//! floor or a ceiling seen at a grazing angle, a long strip seen along its length) takes several
//! isotropic lookups along the footprint's longer axis, each at the level of detail of the
//! footprint's width, and averages them, as graphics hardware does under
//! `EXT_texture_filter_anisotropic` (a footprint-assembly approximation of an elliptical
//! filter: Schilling, Knittel and Strasser, "Texram: a smart memory for texturing", IEEE CG&A
//! 1996).
//!
//! Why: the isotropic level of detail follows the footprint's longer axis, so at a grazing view
//! a texture is blurred across its shorter axis by the ratio of the two (the ceiling's light
//! falling within a centimetre beside a lamp, seen from across a room, is spread over several
//! centimetres). The paper's hardware filtered isotropically, so the texture methods do by
//! default (`anisotropy` 1); a higher setting is the sharper filter any current GPU offers.
//!
//! The taps: with squared footprint lengths `major2 >= minor2` (level-0 texels per sample), the
//! count is `n = ceil(sqrt(major2 / minor2))` capped at the setting (`MAX_ANISOTROPY` at most),
//! the level of detail that of a footprint `sqrt(major2) / n` by `sqrt(minor2)`, and tap `k` sits
//! at `((k + 0.5) / n - 0.5)` times the longer axis's (u, v) step from the sample. A footprint of
//! `n` = 1 (round, magnified, or not finite) is the isotropic lookup.
//!
//! Invariant: the lane form performs, lane by lane, the scalar form's operations in its order
//! (the same tap count, positions, level and sum from 0), so its bits equal the scalar form's,
//! as the isotropic lane form's do.

#![allow(clippy::needless_range_loop)]

use glam::Vec3;

use super::{lod_from_squares, RadiosityTexture, Rgb8, Sampler};
use lanes::{F32x8, Simd, LANES};

/// The largest anisotropy (taps per lookup) a sampler takes, as common hardware caps it.
pub const MAX_ANISOTROPY: u32 = 16;

/// The taps of one lookup: their count, the squared footprint the level of detail is taken
/// from (`lx2`, `ly2` of [`lod_from_squares`]) and the (u, v) step along which they lie.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Taps {
    n: u32,
    lx2: f32,
    ly2: f32,
    axis: (f32, f32),
}

/// The taps for the (u, v) steps `d` = (du/dx, dv/dx, du/dy, dv/dy) per sample of a texture of
/// `w` x `h` texels at level 0, at most `max` of them.
#[inline(always)]
fn taps(d: [f32; 4], (w, h): (f32, f32), max: u32) -> Taps {
    let [ux, vx, uy, vy] = d;
    let lx2 = (ux * w) * (ux * w) + (vx * h) * (vx * h);
    let ly2 = (uy * w) * (uy * w) + (vy * h) * (vy * h);
    let (major2, minor2, axis) = if lx2 >= ly2 {
        (lx2, ly2, (ux, vx))
    } else {
        (ly2, lx2, (uy, vy))
    };
    let isotropic = Taps {
        n: 1,
        lx2,
        ly2,
        axis: (0.0, 0.0),
    };
    // Magnified, NaN or infinite footprints: the isotropic rule (level 0, or the last level).
    if major2.is_nan() || major2 <= 1.0 || major2.is_infinite() || max <= 1 {
        return isotropic;
    }
    // minor2 = 0 (a polygon one sample wide across) gives an infinite ratio: the most taps.
    let ratio = (major2 / minor2).sqrt();
    let n = if ratio.is_nan() {
        1
    } else {
        (ratio.ceil() as u32).clamp(1, max)
    };
    if n == 1 {
        return isotropic;
    }
    let nf = n as f32;
    Taps {
        n,
        lx2: major2 / (nf * nf),
        ly2: minor2,
        axis,
    }
}

/// Where tap `k` of `n` sits along the axis, as a share of the axis's step: centred on the
/// sample, `1/n` apart.
#[inline(always)]
fn offset(k: u32, n: u32) -> f32 {
    (k as f32 + 0.5) / n as f32 - 0.5
}

/// The lanes and coordinates of tap `k` of 8 anisotropic lookups with `n[l]` taps along the
/// axes (`au[l]`, `av[l]`): the lanes of `mask` that have a k-th tap, and (u, v) moved to it
/// (lanes with one tap keep theirs). Not inlined: the deferred pass's isotropic blocks, which
/// never call it, then carry none of its per-lane conversions (inlined, the compiler hoists
/// them in front of the tap loop, where every block pays for them); a lane's values are the
/// same IEEE operations either way.
#[inline(never)]
fn tap(
    k: u32,
    n: &[u32; LANES],
    mask: &[bool; LANES],
    (u, v): (F32x8, F32x8),
    (au, av): (&[f32; LANES], &[f32; LANES]),
) -> ([bool; LANES], F32x8, F32x8) {
    let mut on = *mask;
    let (mut uk, mut vk) = (u, v);
    for l in 0..LANES {
        on[l] &= k < n[l];
        if n[l] > 1 {
            let s = offset(k, n[l]);
            uk.0[l] = u.0[l] + au[l] * s;
            vk.0[l] = v.0[l] + av[l] * s;
        }
    }
    (on, uk, vk)
}

impl Sampler {
    /// The anisotropically filtered value of `tex` at (u, v) for the (u, v) steps `d` =
    /// (du/dx, dv/dx, du/dy, dv/dy) between neighbouring samples, with at most `max` taps
    /// (see the module doc). With one tap it is [`Sampler::sample`] at the level of detail of
    /// the footprint `d` spans.
    pub fn sample_anisotropic(
        &self,
        tex: &RadiosityTexture,
        d: [f32; 4],
        (u, v): (f32, f32),
        max: u32,
    ) -> Vec3 {
        let t = taps(d, (tex.width as f32, tex.height as f32), max);
        let lod = lod_from_squares(t.lx2, t.ly2, tex.last_level());
        if t.n == 1 {
            return self.sample(tex, lod, u, v);
        }
        let mut acc = Vec3::ZERO;
        for k in 0..t.n {
            let s = offset(k, t.n);
            acc += self.sample(tex, lod, u + t.axis.0 * s, v + t.axis.1 * s);
        }
        let nf = t.n as f32;
        Vec3::new(acc.x / nf, acc.y / nf, acc.z / nf)
    }

    /// The lookups of 8 samples with the footprint `fp`: lane l of the result has, for every
    /// lane with `mask[l]`, the bits of [`Sampler::sample`] at
    /// `lod_from_squares(lx2[l], ly2[l], tex.last_level())` for an isotropic footprint, and of
    /// `self.sample_anisotropic(tex, [d[0][l], d[1][l], d[2][l], d[3][l]], (u[l], v[l]), max)`
    /// for an anisotropic one; the other lanes hold unspecified finite values.
    ///
    /// Both run through one call of [`Sampler::sample8`] (once per tap), so the filters are
    /// inlined once into the deferred pass whichever footprint it takes: every further call
    /// site would inline every filter and placement again per instruction set (minutes of
    /// build time for the engine's tests).
    #[inline(always)]
    pub fn sample8_footprint<S: Simd>(
        &self,
        simd: S,
        tex: &RadiosityTexture,
        fp: Footprint8,
        (u, v): (F32x8, F32x8),
        mask: &[bool; LANES],
    ) -> Rgb8 {
        let mut n = [1u32; LANES];
        let (mut au, mut av) = ([0.0f32; LANES], [0.0f32; LANES]);
        let mut most = 1;
        let (lx2, ly2) = match fp {
            Footprint8::Isotropic { lx2, ly2 } => (lx2, ly2),
            Footprint8::Anisotropic { d, max } => {
                let size = (tex.width as f32, tex.height as f32);
                let (mut lx2, mut ly2) = ([0.0f32; LANES], [0.0f32; LANES]);
                for l in 0..LANES {
                    let t = taps([d[0].0[l], d[1].0[l], d[2].0[l], d[3].0[l]], size, max);
                    (n[l], lx2[l], ly2[l], au[l], av[l]) = (t.n, t.lx2, t.ly2, t.axis.0, t.axis.1);
                    if mask[l] {
                        most = most.max(t.n);
                    }
                }
                (F32x8(lx2), F32x8(ly2))
            }
        };
        let mut acc = [F32x8::splat(0.0); 3];
        let mut k = 0;
        loop {
            // One tap everywhere (every isotropic block): the lanes' own coordinates, which is
            // what `tap` would give, without its per-lane work.
            let (on, uk, vk) = if most > 1 {
                tap(k, &n, mask, (u, v), (&au, &av))
            } else {
                (*mask, u, v)
            };
            let c = self.sample8(simd, tex, lx2, ly2, uk, vk, &on);
            if most == 1 {
                return c;
            }
            for ch in 0..3 {
                acc[ch] = F32x8::select(&on, acc[ch] + c[ch], acc[ch]);
            }
            k += 1;
            if k == most {
                break;
            }
        }
        for ch in 0..3 {
            for l in 0..LANES {
                acc[ch].0[l] /= n[l] as f32;
            }
        }
        acc
    }
}

/// The footprint of 8 lookups ([`Sampler::sample8_footprint`]).
#[derive(Debug, Clone, Copy)]
pub enum Footprint8 {
    /// One lookup each, at the level of detail of the squared footprint lengths `lx2`, `ly2`
    /// (texels per sample; [`lod_from_squares`]).
    Isotropic {
        /// Squared footprint length along x.
        lx2: F32x8,
        /// Squared footprint length along y.
        ly2: F32x8,
    },
    /// Up to `max` lookups each along the longer axis of the (u, v) steps `d` = (du/dx, dv/dx,
    /// du/dy, dv/dy) between neighbouring samples.
    Anisotropic {
        /// The steps.
        d: [F32x8; 4],
        /// Most taps.
        max: u32,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_round_or_magnified_footprint_takes_one_tap() {
        let size = (64.0, 64.0);
        // 2 texels each way: round.
        assert_eq!(taps([2.0 / 64.0, 0.0, 0.0, 2.0 / 64.0], size, 16).n, 1);
        // Magnified: under a texel each way, however long.
        assert_eq!(taps([0.9 / 64.0, 0.0, 0.0, 0.01 / 64.0], size, 16).n, 1);
        // NaN and infinite steps fall back to the isotropic rule.
        assert_eq!(taps([f32::NAN, 0.0, 0.0, 1.0], size, 16).n, 1);
        assert_eq!(taps([f32::INFINITY, 0.0, 0.0, 1.0], size, 16).n, 1);
        // Anisotropy 1 is the isotropic filter.
        assert_eq!(taps([8.0 / 64.0, 0.0, 0.0, 1.0 / 64.0], size, 1).n, 1);
    }

    #[test]
    fn a_long_footprint_takes_taps_along_its_length_at_its_widths_level() {
        let size = (64.0, 32.0);
        // 8 texels along y (v), 2 along x (u): 4 taps, each footprint 2 x 2 texels.
        let t = taps([2.0 / 64.0, 0.0, 0.0, 8.0 / 32.0], size, 16);
        assert_eq!(t.n, 4);
        assert_eq!((t.lx2, t.ly2), (4.0, 4.0));
        assert_eq!(t.axis, (0.0, 8.0 / 32.0));
        // Capped: 100 texels by 1.
        let t = taps([100.0 / 64.0, 0.0, 0.0, 1.0 / 32.0], size, 8);
        assert_eq!(t.n, 8);
        // A footprint one sample wide across (no step measured that way): the most taps.
        assert_eq!(taps([4.0 / 64.0, 0.0, 0.0, 0.0], size, 16).n, 16);
        // A ratio of 2.5 rounds up, so the taps' footprint is at most as long as it is wide.
        let t = taps([5.0 / 64.0, 0.0, 0.0, 2.0 / 32.0], size, 16);
        assert_eq!(t.n, 3);
        assert!(t.lx2 <= t.ly2);
        // Offsets are centred on the sample and 1/n apart.
        assert_eq!([offset(0, 4), offset(3, 4)], [-0.375, 0.375]);
    }
}
