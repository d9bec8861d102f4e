//! The patch shader: every visible sample evaluates the bicubic patch its region's table holds
//! for it (the direct method's RRPs; for the Gouraud mesh, each triangle's degree-(1, 1) patch).
//!
//! Neighbouring samples nearly always share one patch, so each block of 8 samples with one slot
//! is evaluated with the patch's 48 coefficients broadcast over 8 lanes (Horner in s for each of
//! the 4 rows, then Horner in t: 15 multiply-adds per channel per lane); blocks that mix patches
//! evaluate one broadcast per distinct patch and merge through masks. Both perform the scalar
//! operations in the scalar order (Rust never contracts `a * b + c` into an FMA), so which path a
//! sample takes never changes its bits.
//!
//! Three builds of the pass: portable, AVX2 (8 lanes in AVX registers), and on CPUs with
//! AVX-512 (F, VL) one that shades two neighbouring blocks at once, 16 lanes per instruction,
//! one 16-lane evaluation per distinct patch of the pair merged through mask registers, with
//! every coefficient broadcast folded into the multiply or add that uses it. The tests compare
//! the three bit for bit.

#![allow(clippy::needless_range_loop)]

use glam::Vec3;

use super::{RowOut, Rows, ShadeCounts};
use crate::lanes::{F32x8, LANES};
use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};
use crate::reconstruction::PatchCoeffs;

/// Horner's scheme: rows in s, then the rows in t.
#[cfg(test)]
#[inline(always)]
fn eval_channel(k: &[f32; 16], s: f32, t: f32) -> f32 {
    let r = |j: usize| ((k[4 * j + 3] * s + k[4 * j + 2]) * s + k[4 * j + 1]) * s + k[4 * j];
    ((r(3) * t + r(2)) * t + r(1)) * t + r(0)
}

/// Evaluates one channel for 8 lanes with broadcast coefficients; same operations, in the same
/// order, as [`eval_channel`].
#[inline(always)]
fn eval_channel8(k: &[f32; 16], s: F32x8, t: F32x8) -> F32x8 {
    let c = |i: usize| F32x8::splat(k[i]);
    let r3 = ((c(15) * s + c(14)) * s + c(13)) * s + c(12);
    let r2 = ((c(11) * s + c(10)) * s + c(9)) * s + c(8);
    let r1 = ((c(7) * s + c(6)) * s + c(5)) * s + c(4);
    let r0 = ((c(3) * s + c(2)) * s + c(1)) * s + c(0);
    ((r3 * t + r2) * t + r1) * t + r0
}

/// One patch at 8 lanes of (u, v): the local (s, t) = ((u - u0) w⁻¹, (v - v0) w⁻¹), then
/// [`eval_channel8`] for each channel. With `HW` (only in the AVX2 build) the same operations in
/// the same order run as explicit AVX intrinsics: left to itself, LLVM's SLP vectorizer
/// vectorized the four row polynomials across rows (4-wide, with shuffles) instead of across
/// the 8 lanes, and the pass ran at a third of its arithmetic rate.
///
/// Patches flagged [`PatchCoeffs::bilinear`] (the Gouraud mesh's, constant ones) take the
/// degree-(1, 1) form, 6 operations per channel instead of 30, with the same bits.
#[inline(always)]
fn eval_patch8<const HW: bool>(p: &PatchCoeffs, u: F32x8, v: F32x8) -> [F32x8; 3] {
    #[cfg(target_arch = "x86_64")]
    {
        if HW {
            // SAFETY: HW is true only in the AVX2 build, called after the CPU check.
            return unsafe {
                if p.bilinear {
                    eval_bilinear8_avx2(p, u, v)
                } else {
                    eval_patch8_avx2(p, u, v)
                }
            };
        }
    }
    let s = (u - F32x8::splat(p.u0)) * F32x8::splat(p.inv_w);
    let t = (v - F32x8::splat(p.v0)) * F32x8::splat(p.inv_w);
    if p.bilinear {
        return std::array::from_fn(|ch| eval_bilinear_channel8(&p.c[ch], s, t));
    }
    [
        eval_channel8(&p.c[0], s, t),
        eval_channel8(&p.c[1], s, t),
        eval_channel8(&p.c[2], s, t),
    ]
}

/// The degree-(1, 1) form of [`eval_channel8`] for coefficients that pass
/// [`PatchCoeffs::bilinear_exact`]: `(k5 s + k4) t + (k1 s + k0)`, the operations Horner's
/// scheme is left with once its products with zero coefficients are dropped.
#[inline(always)]
fn eval_bilinear_channel8(k: &[f32; 16], s: F32x8, t: F32x8) -> F32x8 {
    let c = |i: usize| F32x8::splat(k[i]);
    let r1 = c(5) * s + c(4);
    let r0 = c(1) * s + c(0);
    r1 * t + r0
}

/// The patch's local (s, t) = ((u - u0) inv_w, (v - v0) inv_w) of 8 lanes in AVX registers.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn local_st_avx2(
    p: &PatchCoeffs,
    u: F32x8,
    v: F32x8,
) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
    use std::arch::x86_64::*;
    // SAFETY: F32x8 is 8 f32, 32-byte aligned: the loads stay inside it.
    unsafe {
        let w = _mm256_set1_ps(p.inv_w);
        let local = |x: &F32x8, o: f32| {
            _mm256_mul_ps(
                _mm256_sub_ps(_mm256_load_ps(x.0.as_ptr()), _mm256_set1_ps(o)),
                w,
            )
        };
        (local(&u, p.u0), local(&v, p.v0))
    }
}

/// [`eval_bilinear_channel8`] for the three channels in AVX registers (no FMA; same operations,
/// same order).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn eval_bilinear8_avx2(p: &PatchCoeffs, u: F32x8, v: F32x8) -> [F32x8; 3] {
    use std::arch::x86_64::*;
    let mut out = [F32x8::splat(0.0); 3];
    // SAFETY: F32x8 is 8 f32, 32-byte aligned: the loads and stores stay inside it.
    unsafe {
        let (s, t) = local_st_avx2(p, u, v);
        for (ch, o) in out.iter_mut().enumerate() {
            let k = &p.c[ch];
            let r1 = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(k[5]), s), _mm256_set1_ps(k[4]));
            let r0 = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(k[1]), s), _mm256_set1_ps(k[0]));
            let a = _mm256_add_ps(_mm256_mul_ps(r1, t), r0);
            _mm256_store_ps(o.0.as_mut_ptr(), a);
        }
    }
    out
}

/// [`eval_patch8`] in AVX registers: every operation is the separate IEEE multiply or add of the
/// portable form (no FMA), in the same order, so the bits are the same.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn eval_patch8_avx2(p: &PatchCoeffs, u: F32x8, v: F32x8) -> [F32x8; 3] {
    use std::arch::x86_64::*;
    let mut out = [F32x8::splat(0.0); 3];
    // SAFETY: F32x8 is 8 f32, 32-byte aligned: the loads and stores stay inside it.
    unsafe {
        let (s, t) = local_st_avx2(p, u, v);
        macro_rules! horner {
            ($x:expr, $a:expr, $b:expr, $c:expr, $d:expr) => {{
                // ((a x + b) x + c) x + d
                let r = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps($a), $x), _mm256_set1_ps($b));
                let r = _mm256_add_ps(_mm256_mul_ps(r, $x), _mm256_set1_ps($c));
                _mm256_add_ps(_mm256_mul_ps(r, $x), _mm256_set1_ps($d))
            }};
        }
        for (ch, o) in out.iter_mut().enumerate() {
            let k = &p.c[ch];
            let r3 = horner!(s, k[15], k[14], k[13], k[12]);
            let r2 = horner!(s, k[11], k[10], k[9], k[8]);
            let r1 = horner!(s, k[7], k[6], k[5], k[4]);
            let r0 = horner!(s, k[3], k[2], k[1], k[0]);
            let a = _mm256_add_ps(_mm256_mul_ps(r3, t), r2);
            let a = _mm256_add_ps(_mm256_mul_ps(a, t), r1);
            let a = _mm256_add_ps(_mm256_mul_ps(a, t), r0);
            _mm256_store_ps(o.0.as_mut_ptr(), a);
        }
    }
    out
}

/// [`eval_patch8_avx2`] (and [`eval_bilinear8_avx2`]) over 16 lanes in AVX-512 registers: the
/// same IEEE operations in the same order, on twice the lanes per instruction.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn eval_patch16_avx512(
    p: &PatchCoeffs,
    u: &[f32; 2 * LANES],
    v: &[f32; 2 * LANES],
) -> [std::arch::x86_64::__m512; 3] {
    use std::arch::x86_64::*;
    // SAFETY: the loads read the 16 lanes of `u` and `v`.
    unsafe {
        let w = _mm512_set1_ps(p.inv_w);
        let s = _mm512_mul_ps(
            _mm512_sub_ps(_mm512_loadu_ps(u.as_ptr()), _mm512_set1_ps(p.u0)),
            w,
        );
        let t = _mm512_mul_ps(
            _mm512_sub_ps(_mm512_loadu_ps(v.as_ptr()), _mm512_set1_ps(p.v0)),
            w,
        );
        // a b + d: the separate IEEE multiply and add (no FMA), as in every other build.
        macro_rules! ma {
            ($a:expr, $b:expr, $d:expr) => {
                _mm512_add_ps(_mm512_mul_ps($a, $b), $d)
            };
        }
        macro_rules! c {
            ($x:expr) => {
                _mm512_set1_ps($x)
            };
        }
        let mut out = [_mm512_setzero_ps(); 3];
        // Written out (no closures: a closure would not inherit the target features and is
        // called out of line).
        for (ch, o) in out.iter_mut().enumerate() {
            let k = &p.c[ch];
            *o = if p.bilinear {
                ma!(ma!(c!(k[5]), s, c!(k[4])), t, ma!(c!(k[1]), s, c!(k[0])))
            } else {
                // ((a x + b) x + c) x + d for each row, then the rows in t.
                let r3 = ma!(
                    ma!(ma!(c!(k[15]), s, c!(k[14])), s, c!(k[13])),
                    s,
                    c!(k[12])
                );
                let r2 = ma!(ma!(ma!(c!(k[11]), s, c!(k[10])), s, c!(k[9])), s, c!(k[8]));
                let r1 = ma!(ma!(ma!(c!(k[7]), s, c!(k[6])), s, c!(k[5])), s, c!(k[4]));
                let r0 = ma!(ma!(ma!(c!(k[3]), s, c!(k[2])), s, c!(k[1])), s, c!(k[0]));
                ma!(ma!(ma!(r3, t, r2), t, r1), t, r0)
            };
        }
        out
    }
}

/// 16 neighbouring samples of one G-buffer row (two blocks).
#[cfg(target_arch = "x86_64")]
struct Group16<'a> {
    polys: &'a [u32; 2 * LANES],
    slots: &'a [u32; 2 * LANES],
    u: &'a [f32; 2 * LANES],
    v: &'a [f32; 2 * LANES],
}

/// Shades 16 samples (two blocks) in AVX-512 registers: the background where no polygon is seen,
/// and one 16-lane [`eval_patch16_avx512`] per distinct patch, merged through lane masks. Counts
/// each of the two 8-lane blocks exactly as the 8-lane path does (uniform: 8 samples of one
/// patch; mixed: any other block that sees a polygon), so the counters do not depend on the CPU.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn shade16_avx512(
    table: &[PatchCoeffs],
    g: &Group16<'_>,
    bg: &[f32; 3],
    counts: &mut ShadeCounts,
) -> [std::arch::x86_64::__m512; 3] {
    use std::arch::x86_64::*;
    // SAFETY: the loads read the 16 lanes of each array.
    unsafe {
        let p = _mm512_loadu_si512(g.polys.as_ptr() as *const _);
        let slots = _mm512_loadu_si512(g.slots.as_ptr() as *const _);
        let empty = _mm512_cmpeq_epi32_mask(p, _mm512_set1_epi32(NO_POLYGON as i32));
        let mut pending = !empty;
        counts.samples_shaded += pending.count_ones() as u64;
        let mut out = [
            _mm512_set1_ps(bg[0]),
            _mm512_set1_ps(bg[1]),
            _mm512_set1_ps(bg[2]),
        ];
        // Halves (8-lane blocks) that see a polygon, and those one patch covers.
        let seen = (((pending & 0xff) != 0) as u32) + (((pending >> 8) != 0) as u32);
        let mut whole = 0u16;
        while pending != 0 {
            let slot = g.slots[pending.trailing_zeros() as usize];
            let m = _mm512_cmpeq_epi32_mask(slots, _mm512_set1_epi32(slot as i32)) & pending;
            pending &= !m;
            whole |= (m & 0xff == 0xff) as u16 | (((m >> 8) == 0xff) as u16) << 1;
            let c = eval_patch16_avx512(&table[slot as usize], g.u, g.v);
            if m == 0xffff {
                out = c;
            } else {
                for ch in 0..3 {
                    out[ch] = _mm512_mask_mov_ps(out[ch], m, c[ch]);
                }
            }
        }
        let uniform = whole.count_ones();
        counts.uniform_blocks += uniform as u64;
        counts.mixed_blocks += (seen - uniform) as u64;
        out
    }
}

/// Which lanes of a block are empty (bit l: `polys[l]` is [`NO_POLYGON`]) and whether all 8
/// slots are equal.
#[inline(always)]
fn classify8<const HW: bool>(polys: &[u32; LANES], slots: &[u32; LANES]) -> (u32, bool) {
    #[cfg(target_arch = "x86_64")]
    if HW {
        use std::arch::x86_64::*;
        // SAFETY: HW is true only in the AVX2 build, run after the CPU check; the loads read
        // the 8 lanes of each array.
        return unsafe {
            let p = _mm256_loadu_si256(polys.as_ptr() as *const __m256i);
            let e = _mm256_cmpeq_epi32(p, _mm256_set1_epi32(NO_POLYGON as i32));
            (
                _mm256_movemask_ps(_mm256_castsi256_ps(e)) as u32,
                same_slot8::<HW>(slots, slots[0]) == 0xff,
            )
        };
    }
    let mut empty = 0;
    let mut same = true;
    for l in 0..LANES {
        empty |= ((polys[l] == NO_POLYGON) as u32) << l;
        same &= slots[l] == slots[0];
    }
    (empty, same)
}

/// The lanes whose slot is `slot`, as bits.
#[inline(always)]
fn same_slot8<const HW: bool>(slots: &[u32; LANES], slot: u32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    if HW {
        use std::arch::x86_64::*;
        // SAFETY: as in `classify8`.
        return unsafe {
            let v = _mm256_loadu_si256(slots.as_ptr() as *const __m256i);
            let e = _mm256_cmpeq_epi32(v, _mm256_set1_epi32(slot as i32));
            _mm256_movemask_ps(_mm256_castsi256_ps(e)) as u32
        };
    }
    (0..LANES).fold(0, |b, l| b | ((slots[l] == slot) as u32) << l)
}

/// `out[ch][l] = c[ch][l]` in the lanes whose bit is set in `m`.
#[inline(always)]
fn select8<const HW: bool>(m: u32, c: &[F32x8; 3], out: &mut [F32x8; 3]) {
    #[cfg(target_arch = "x86_64")]
    if HW {
        use std::arch::x86_64::*;
        // SAFETY: as in `classify8`; F32x8 is 8 aligned f32.
        unsafe {
            let mv = _mm256_castsi256_ps(crate::lanes::lane_mask_avx2(m));
            for ch in 0..3 {
                let r = _mm256_blendv_ps(
                    _mm256_load_ps(out[ch].0.as_ptr()),
                    _mm256_load_ps(c[ch].0.as_ptr()),
                    mv,
                );
                _mm256_store_ps(out[ch].0.as_mut_ptr(), r);
            }
        }
        return;
    }
    let mask: [bool; LANES] = std::array::from_fn(|l| (m >> l) & 1 != 0);
    for ch in 0..3 {
        out[ch] = F32x8::select(&mask, c[ch], out[ch]);
    }
}

/// Shades one composited region: returns its `width * height` resolved linear pixels (row-major,
/// row 0 at the region's top) and the counters.
pub fn shade_region(gb: &RegionGBuffer, background: Vec3) -> (Vec<Vec3>, ShadeCounts) {
    let mut out = vec![Vec3::ZERO; (gb.width * gb.height) as usize];
    let counts = shade_region_into(gb, background, &mut out, gb.width as usize);
    (out, counts)
}

/// Shades one composited region into `dst`, whose element 0 is the region's top-left pixel and
/// whose rows are `pitch` pixels apart (a frame: pitch = frame width).
///
/// On x86-64 CPUs with AVX2 the same code is compiled a second time with 8-wide registers and
/// chosen at run time ([`crate::lanes::avx2_available`]; never with the `portable` feature);
/// without FMA the two builds perform identical IEEE operations, so the image does not depend on
/// the CPU.
pub fn shade_region_into(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    let mut rows = Rows::new(dst, pitch, gb.width as usize, gb.height as usize);
    shade_region_rows(gb, background, &mut rows)
}

/// [`shade_region_into`] writing into `rows` (`gb.width` x `gb.height` pixels).
pub fn shade_region_rows(gb: &RegionGBuffer, background: Vec3, rows: &mut Rows<'_>) -> ShadeCounts {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::lanes::avx512_available() {
            // SAFETY: the CPU supports AVX2, AVX-512F and AVX-512VL, checked just above.
            return unsafe { shade_region_avx512(gb, background, rows) };
        }
        if crate::lanes::avx2_available() {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { shade_region_avx2(gb, background, rows) };
        }
    }
    shade_region_body::<false, false>(gb, background, rows)
}

/// The portable build of [`shade_region_into`], whatever the CPU: public for the tests that
/// compare it with the AVX2 build.
#[doc(hidden)]
pub fn shade_region_into_portable(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> ShadeCounts {
    let mut rows = Rows::new(dst, pitch, gb.width as usize, gb.height as usize);
    shade_region_body::<false, false>(gb, background, &mut rows)
}

/// The AVX2 build of [`shade_region_into`] even on CPUs with AVX-512, `None` without AVX2 (or
/// with the `portable` feature): public for the tests that compare the three builds.
#[doc(hidden)]
pub fn shade_region_into_avx2(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut [Vec3],
    pitch: usize,
) -> Option<ShadeCounts> {
    let mut rows = Rows::new(dst, pitch, gb.width as usize, gb.height as usize);
    #[cfg(target_arch = "x86_64")]
    if crate::lanes::avx2_available() {
        // SAFETY: the CPU supports AVX2, checked just above.
        return Some(unsafe { shade_region_avx2(gb, background, &mut rows) });
    }
    let _ = (gb, background, &mut rows);
    None
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn shade_region_avx2(gb: &RegionGBuffer, bg: Vec3, rows: &mut Rows<'_>) -> ShadeCounts {
    shade_region_body::<true, false>(gb, bg, rows)
}

/// The AVX-512 build: pairs of blocks in 16 lanes ([`shade16_avx512`]); the 8-lane AVX2 code
/// it keeps for a row's last block is EVEX-encoded, with every coefficient broadcast folded into
/// the arithmetic (see [`crate::lanes::avx512_available`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl,popcnt")]
fn shade_region_avx512(gb: &RegionGBuffer, bg: Vec3, rows: &mut Rows<'_>) -> ShadeCounts {
    shade_region_body::<true, true>(gb, bg, rows)
}

#[inline(always)]
fn shade_region_body<const HW: bool, const WIDE: bool>(
    gb: &RegionGBuffer,
    background: Vec3,
    dst: &mut Rows<'_>,
) -> ShadeCounts {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane = stride * h;
    let mut rows = RowOut::new(gb.samples, stride);
    let mut counts = ShadeCounts::default();
    let bg = background.to_array();
    let bg8 = [
        F32x8::splat(bg[0]),
        F32x8::splat(bg[1]),
        F32x8::splat(bg[2]),
    ];
    for y in 0..h {
        let out_row = dst.row(y);
        for si in 0..gb.samples as usize {
            let row = si * plane + y * stride;
            let mut bx = 0;
            while bx < w {
                let i0 = row + bx;
                #[cfg(target_arch = "x86_64")]
                if WIDE && bx + 2 * LANES <= w {
                    // Two neighbouring blocks at once: one 16-lane evaluation per distinct patch.
                    let lanes = i0..i0 + 2 * LANES;
                    let group = Group16 {
                        polys: gb.polygon[lanes.clone()].try_into().unwrap(),
                        slots: gb.slot[lanes.clone()].try_into().unwrap(),
                        u: gb.u[lanes.clone()].try_into().unwrap(),
                        v: gb.v[lanes].try_into().unwrap(),
                    };
                    // SAFETY: WIDE is true only in the AVX-512 build, run after the CPU check.
                    unsafe {
                        let c = shade16_avx512(&gb.table, &group, &bg, &mut counts);
                        rows.block16_avx512(out_row, bx, si, &c);
                    }
                    bx += 2 * LANES;
                    continue;
                }
                let polys: &[u32; LANES] = gb.polygon[i0..i0 + LANES].try_into().unwrap();
                let slots: &[u32; LANES] = gb.slot[i0..i0 + LANES].try_into().unwrap();
                let u8x = F32x8(gb.u[i0..i0 + LANES].try_into().unwrap());
                let v8x = F32x8(gb.v[i0..i0 + LANES].try_into().unwrap());
                let (empty, same) = classify8::<HW>(polys, slots);
                let out = if empty == 0 && same {
                    // The common case: one patch, its coefficients broadcast over the 8 lanes.
                    counts.uniform_blocks += 1;
                    counts.samples_shaded += LANES as u64;
                    eval_patch8::<HW>(&gb.table[slots[0] as usize], u8x, v8x)
                } else if empty == 0xff {
                    bg8
                } else {
                    // Mixed: one broadcast evaluation per distinct patch, committed through masks
                    // (the lanes still pending are bits; the patch of the first is evaluated and
                    // written to every pending lane with the same slot).
                    counts.mixed_blocks += 1;
                    counts.samples_shaded += (LANES as u32 - empty.count_ones()) as u64;
                    let mut out = bg8;
                    let mut pending = !empty & 0xff;
                    while pending != 0 {
                        let slot = slots[pending.trailing_zeros() as usize];
                        let m = same_slot8::<HW>(slots, slot) & pending;
                        pending &= !m;
                        let c = eval_patch8::<HW>(&gb.table[slot as usize], u8x, v8x);
                        select8::<HW>(m, &c, &mut out);
                    }
                    out
                };
                rows.block::<HW>(out_row, bx, si, &out);
                bx += LANES;
            }
        }
        // Box filter: equal weights over the pixel's samples, then the non-finite clamp. Padding
        // lanes beyond the region's width hold NO_POLYGON and are never written out.
        rows.finish_row::<HW>(out_row);
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruction::PatchCoeffs;

    fn poly_patch() -> PatchCoeffs {
        let mut c = [[0.0f32; 16]; 3];
        for (ch, row) in c.iter_mut().enumerate() {
            for (k, x) in row.iter_mut().enumerate() {
                *x = ((k * 7 + ch * 3) % 11) as f32 * 0.125 - 0.5;
            }
        }
        PatchCoeffs {
            c,
            u0: 0.25,
            v0: 0.5,
            inv_w: 4.0,
            bilinear: false,
        }
    }

    #[test]
    fn horner_matches_the_power_basis_sum() {
        let p = poly_patch();
        for &(u, v) in &[(0.25, 0.5), (0.3, 0.6), (0.5, 0.75), (0.41, 0.52)] {
            let (s, t) = ((u - 0.25) * 4.0f64, (v - 0.5) * 4.0f64);
            let got = p.eval(u as f32, v as f32);
            for ch in 0..3 {
                let mut want = 0.0f64;
                for j in 0..4 {
                    for i in 0..4 {
                        want += p.c[ch][4 * j + i] as f64 * s.powi(i as i32) * t.powi(j as i32);
                    }
                }
                // |coefficients| <= 0.75, 16 terms, s, t <= 1: f32 rounding stays below 1e-5.
                assert!(
                    (got[ch] as f64 - want).abs() < 1e-5,
                    "{ch}: {} vs {want}",
                    got[ch]
                );
            }
        }
    }

    /// Degree-(1, 1) coefficients with awkward values: zeros of either sign, subnormals,
    /// opposite values that cancel, large magnitudes.
    fn bilinear_coeffs(seed: u64) -> [[f32; 16]; 3] {
        const VALUES: [f32; 10] = [0.0, -0.0, 1.0, -1.0, 0.3, -0.7, 1e-40, -3e38, 3e38, 2.5];
        let mut x = seed;
        let mut next = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            VALUES[(x >> 33) as usize % VALUES.len()]
        };
        let mut c = [[0.0f32; 16]; 3];
        for k in c.iter_mut() {
            for i in [0, 1, 4, 5] {
                k[i] = next();
            }
        }
        c
    }

    #[test]
    fn the_bilinear_form_gives_the_bicubic_bits_whenever_it_is_flagged() {
        // s and t of either sign and zero (u0 = 0.5 puts u = 0.5 at s = 0, u < 0.5 below).
        let u = F32x8([0.0, 0.25, 0.5, 0.5, 0.75, 1.0, 0.1, 0.9]);
        let v = F32x8([0.5, 0.0, 1.0, 0.5, 0.3, 0.5, 0.99, 0.0]);
        let mut flagged = 0;
        for seed in 0..4000 {
            let mut p = PatchCoeffs::whole(bilinear_coeffs(seed));
            p.u0 = 0.5;
            p.v0 = 0.5;
            p.inv_w = 2.0;
            if !p.bilinear {
                // Only -0 in k1, k4 or k5 may refuse the flag.
                let neg = |x: f32| x.to_bits() == 0x8000_0000;
                assert!(p.c.iter().any(|k| neg(k[1]) || neg(k[4]) || neg(k[5])));
                continue;
            }
            flagged += 1;
            let fast = eval_patch8::<false>(&p, u, v);
            let mut full = p;
            full.bilinear = false;
            let want = eval_patch8::<false>(&full, u, v);
            for ch in 0..3 {
                for l in 0..LANES {
                    assert_eq!(
                        fast[ch].0[l].to_bits(),
                        want[ch].0[l].to_bits(),
                        "seed {seed} channel {ch} lane {l}"
                    );
                }
            }
            #[cfg(target_arch = "x86_64")]
            if crate::lanes::avx2_available() {
                let hw = eval_patch8::<true>(&p, u, v);
                for ch in 0..3 {
                    assert_eq!(hw[ch].0.map(f32::to_bits), want[ch].0.map(f32::to_bits));
                }
            }
            #[cfg(target_arch = "x86_64")]
            if crate::lanes::avx512_available() {
                // 16 lanes: the 8 twice, both halves must give the 8-lane bits.
                let u16: [f32; 16] = std::array::from_fn(|l| u.0[l % 8]);
                let v16: [f32; 16] = std::array::from_fn(|l| v.0[l % 8]);
                let mut got = [[0.0f32; 16]; 3];
                // SAFETY: the CPU has AVX-512F, checked just above.
                unsafe {
                    let c = eval_patch16_avx512(&p, &u16, &v16);
                    for ch in 0..3 {
                        std::arch::x86_64::_mm512_storeu_ps(got[ch].as_mut_ptr(), c[ch]);
                    }
                }
                for ch in 0..3 {
                    for l in 0..16 {
                        assert_eq!(got[ch][l].to_bits(), want[ch].0[l % 8].to_bits());
                    }
                }
            }
        }
        assert!(flagged > 1000, "{flagged} flagged");
    }

    #[test]
    fn a_bicubic_term_or_a_negative_zero_keeps_the_full_evaluation() {
        let mut c = bilinear_coeffs(7);
        c[1] = [0.5; 16];
        c[1][5] = 0.25;
        assert!(!PatchCoeffs::whole(c).bilinear);
        let mut c = [[0.0f32; 16]; 3];
        assert!(PatchCoeffs::whole(c).bilinear);
        c[2][4] = -0.0;
        assert!(!PatchCoeffs::whole(c).bilinear);
        c[2][4] = 0.0;
        c[0][15] = -0.0;
        assert!(!PatchCoeffs::whole(c).bilinear);
    }

    #[test]
    fn lane_path_and_scalar_path_agree_bit_for_bit() {
        let p = poly_patch();
        let s: [f32; 8] = std::array::from_fn(|l| l as f32 * 0.13);
        let t: [f32; 8] = std::array::from_fn(|l| 1.0 - l as f32 * 0.11);
        let r = eval_channel8(&p.c[1], F32x8(s), F32x8(t));
        for l in 0..8 {
            assert_eq!(
                r.0[l].to_bits(),
                eval_channel(&p.c[1], s[l], t[l]).to_bits()
            );
        }
    }
}
