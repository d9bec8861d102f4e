//! The x86-64 tokens: [`Avx2`] (8 lanes in AVX registers), [`Avx512`] (16 lanes in AVX-512
//! registers, masks in mask registers) and [`Avx512Half`] (the AVX2 operations compiled with
//! AVX-512 enabled: EVEX encoding, 32 vector registers, compares into mask registers, the
//! coefficient broadcasts folded into the arithmetic).
//!
//! Every operation is an `#[inline(always)]` method around `core::arch` intrinsics. On its own
//! such a method has no target features, so the intrinsic stays a call; inlined into a kernel
//! that [`Simd::vectorize`] compiles with the features, the intrinsic is inlined too and becomes
//! one instruction. Calling an intrinsic needs the CPU to support it: each `unsafe` block below
//! relies on the token, which exists only after its `try_new` checked the CPU.

use std::arch::x86_64::*;

use glam::Vec3;

use crate::{Kernel, Simd, LANES};

/// AVX2: 8 lanes in 256-bit registers. Constructed only on CPUs with AVX2.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Avx2(());

/// AVX-512 (F, VL, with AVX2 and POPCNT): 16 lanes in 512-bit registers, masks in mask registers.
/// Constructed only on CPUs with all four.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Avx512(());

/// The 8-lane operations of [`Avx2`], compiled with [`Avx512`]'s features (see the module
/// documentation). Obtained from an [`Avx512`] token.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Avx512Half(());

impl Avx2 {
    /// The token, if this CPU has AVX2.
    pub fn try_new() -> Option<Avx2> {
        is_x86_feature_detected!("avx2").then_some(Avx2(()))
    }
}

impl Avx512 {
    /// The token, if this CPU has AVX2, AVX-512F, AVX-512VL and POPCNT.
    pub fn try_new() -> Option<Avx512> {
        (is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512vl")
            && is_x86_feature_detected!("popcnt"))
        .then_some(Avx512(()))
    }

    /// The AVX2 token (every CPU with this token has AVX2).
    pub fn avx2(self) -> Avx2 {
        Avx2(())
    }
}

/// The blend of `new` into the 8 lanes at `dst` where `mask` is all ones, stored with one
/// full-width store. Written in inline assembly because LLVM otherwise folds exactly this
/// load-select-store into a masked store (`vmaskmovps` / `vpmaskmovd`), which in the
/// rasterizer's inner loop was slow to retire and blocked store-to-load forwarding for the next
/// primitive's depth test on the same block.
///
/// # Safety
/// The CPU must support AVX2; `dst` must be valid for reading and writing 32 bytes.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn blend_store8(dst: *mut u32, new: __m256i, mask: __m256i) {
    // SAFETY: `dst` is valid for 32 bytes (the caller's promise); the assembly writes exactly
    // those bytes.
    unsafe {
        let old = _mm256_loadu_si256(dst as *const __m256i);
        let r = _mm256_blendv_epi8(old, new, mask);
        std::arch::asm!(
            "vmovdqu ymmword ptr [{p}], {r}",
            p = in(reg) dst,
            r = in(ymm_reg) r,
            options(nostack, preserves_flags)
        );
    }
}

/// The 8 lanes of r, g, b, each clamped by the token's `sanitize`, as 8 pixels at `dst` (24
/// floats, 3 registers). Output float k is channel k % 3 of pixel k / 3, so every channel's lanes
/// land at distinct positions modulo 3 in the three registers: one permutation per channel puts
/// each lane at its position within its register, and two blends per register pick the channels.
///
/// # Safety
/// The CPU must support AVX2; `dst` must be valid for 24 f32 writes.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn store_rgb8(dst: *mut f32, r: __m256, g: __m256, b: __m256) {
    // r_i goes to float 3i, g_i to 3i + 1, b_i to 3i + 2 (register k / 8, position k % 8).
    let r = _mm256_permutevar8x32_ps(r, _mm256_setr_epi32(0, 3, 6, 1, 4, 7, 2, 5));
    let g = _mm256_permutevar8x32_ps(g, _mm256_setr_epi32(5, 0, 3, 6, 1, 4, 7, 2));
    let b = _mm256_permutevar8x32_ps(b, _mm256_setr_epi32(2, 5, 0, 3, 6, 1, 4, 7));
    // Register 0: r at 0, 3, 6; g at 1, 4, 7; b at 2, 5. Registers 1 and 2 rotate the roles.
    let o0 = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(r, g), b);
    let o1 = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(b, r), g);
    let o2 = _mm256_blend_ps::<0b0010_0100>(_mm256_blend_ps::<0b1001_0010>(g, b), r);
    // SAFETY: `dst` is valid for 24 floats (the caller's promise).
    unsafe {
        _mm256_storeu_ps(dst, o0);
        _mm256_storeu_ps(dst.add(8), o1);
        _mm256_storeu_ps(dst.add(16), o2);
    }
}

/// The 8 texels `texels[idx[l]]` as three channels of 8 lanes.
///
/// By plain loads where every index is below the last texel: one 16-byte load per texel (its
/// three floats and the next texel's first, which the transpose drops), transposed into the
/// channels by 11 shuffles. The gather instruction (one per channel, at float offsets 3 idx +
/// channel) is kept for a block that reads the last texel, whose 16-byte load would pass the
/// array's end; the bits are the same either way. On the AMD EPYC (Zen 4) this was measured
/// on, the gathers' own cost was most of the texture pass's fetch time: the Cornell box's
/// bilinear pass at 1024 x 1024 took 6.2 ms with them and 4.8 ms with the loads (the same
/// pass with gathers from one address took as long as with the gathers spread out, so their
/// cost was not cache misses).
///
/// # Safety
/// The CPU must support AVX2; every lane of `idx` must be a valid index of `texels` whose
/// float offset 3 idx + 2 fits in i32.
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn gather_rgb8(texels: &[Vec3], idx: __m256i) -> [__m256; 3] {
    let base = texels.as_ptr() as *const f32;
    // SAFETY: 3 idx + ch addresses a float of `texels` and fits in i32 (the caller's promise);
    // the 16-byte loads run only where idx < len - 1, so 3 idx + 3 < 3 len.
    unsafe {
        let below_last = _mm256_cmpgt_epi32(_mm256_set1_epi32(texels.len() as i32 - 1), idx);
        if _mm256_movemask_ps(_mm256_castsi256_ps(below_last)) != 0xff {
            let i3 = _mm256_add_epi32(idx, _mm256_add_epi32(idx, idx));
            return [
                _mm256_i32gather_ps::<4>(base, i3),
                _mm256_i32gather_ps::<4>(base.add(1), i3),
                _mm256_i32gather_ps::<4>(base.add(2), i3),
            ];
        }
        let mut k = [0i32; LANES];
        _mm256_storeu_si256(k.as_mut_ptr() as *mut __m256i, idx);
        // [r g b x] of texel k[l], from float 3 k[l]; lanes l and l + 4 share a register
        // (low and high half). Written out, not as closures: a closure would be compiled
        // without this function's target features unless inlined.
        let t: [__m128; LANES] = [
            _mm_loadu_ps(base.add(3 * k[0] as usize)),
            _mm_loadu_ps(base.add(3 * k[1] as usize)),
            _mm_loadu_ps(base.add(3 * k[2] as usize)),
            _mm_loadu_ps(base.add(3 * k[3] as usize)),
            _mm_loadu_ps(base.add(3 * k[4] as usize)),
            _mm_loadu_ps(base.add(3 * k[5] as usize)),
            _mm_loadu_ps(base.add(3 * k[6] as usize)),
            _mm_loadu_ps(base.add(3 * k[7] as usize)),
        ];
        let a0 = _mm256_set_m128(t[4], t[0]);
        let a1 = _mm256_set_m128(t[5], t[1]);
        let a2 = _mm256_set_m128(t[6], t[2]);
        let a3 = _mm256_set_m128(t[7], t[3]);
        // [r0 r1 g0 g1 | r4 r5 g4 g5], [b0 b1 . . | b4 b5 . .], and lanes 2, 3, 6, 7 alike.
        let (t0, t1) = (_mm256_unpacklo_ps(a0, a1), _mm256_unpackhi_ps(a0, a1));
        let (t2, t3) = (_mm256_unpacklo_ps(a2, a3), _mm256_unpackhi_ps(a2, a3));
        [
            _mm256_shuffle_ps::<0b01_00_01_00>(t0, t2),
            _mm256_shuffle_ps::<0b11_10_11_10>(t0, t2),
            _mm256_shuffle_ps::<0b01_00_01_00>(t1, t3),
        ]
    }
}

/// The 8-lane AVX2 operations, shared by [`Avx2`] and [`Avx512Half`] (the same instructions;
/// only the features their kernels are compiled with differ).
macro_rules! avx2_ops {
    () => {
        const LANES: usize = LANES;
        type F = __m256;
        type U = __m256i;
        type M = __m256i;

        #[inline(always)]
        fn splat(self, x: f32) -> __m256 {
            // SAFETY (this and every block below): the token proves the CPU has AVX2.
            unsafe { _mm256_set1_ps(x) }
        }

        #[inline(always)]
        fn load(self, src: &[f32]) -> __m256 {
            let src = &src[..LANES];
            unsafe { _mm256_loadu_ps(src.as_ptr()) }
        }

        #[inline(always)]
        fn store(self, x: __m256, dst: &mut [f32]) {
            let dst = &mut dst[..LANES];
            unsafe { _mm256_storeu_ps(dst.as_mut_ptr(), x) }
        }

        #[inline(always)]
        fn add(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_add_ps(a, b) }
        }

        #[inline(always)]
        fn sub(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_sub_ps(a, b) }
        }

        #[inline(always)]
        fn mul(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_mul_ps(a, b) }
        }

        #[inline(always)]
        fn lt(self, a: __m256, b: __m256) -> __m256i {
            unsafe { _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LT_OQ>(a, b)) }
        }

        #[inline(always)]
        fn eq(self, a: __m256, b: __m256) -> __m256i {
            unsafe { _mm256_castps_si256(_mm256_cmp_ps::<_CMP_EQ_OQ>(a, b)) }
        }

        #[inline(always)]
        fn select(self, m: __m256i, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_blendv_ps(b, a, _mm256_castsi256_ps(m)) }
        }

        #[inline(always)]
        fn min(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_min_ps(a, b) }
        }

        #[inline(always)]
        fn max(self, a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_max_ps(a, b) }
        }

        #[inline(always)]
        fn floor(self, a: __m256) -> __m256 {
            unsafe { _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(a) }
        }

        #[inline(always)]
        fn to_i32(self, a: __m256) -> __m256i {
            unsafe { _mm256_cvttps_epi32(a) }
        }

        #[inline(always)]
        fn sanitize(self, x: __m256) -> __m256 {
            // Three instructions: `max(x, +0)` is x for x > 0 and the second operand, +0, for
            // x <= 0 (-0 included) and for NaN (MAXPS returns its second operand when either is
            // NaN); the ordered `x < inf` then clears inf and NaN.
            unsafe {
                let kept = _mm256_max_ps(x, _mm256_setzero_ps());
                let finite = _mm256_cmp_ps::<_CMP_LT_OQ>(x, _mm256_set1_ps(f32::INFINITY));
                _mm256_and_ps(kept, finite)
            }
        }

        #[inline(always)]
        fn splat_u(self, x: u32) -> __m256i {
            unsafe { _mm256_set1_epi32(x as i32) }
        }

        #[inline(always)]
        fn load_u(self, src: &[u32]) -> __m256i {
            let src = &src[..LANES];
            unsafe { _mm256_loadu_si256(src.as_ptr() as *const __m256i) }
        }

        #[inline(always)]
        fn eq_u(self, a: __m256i, b: __m256i) -> __m256i {
            unsafe { _mm256_cmpeq_epi32(a, b) }
        }

        #[inline(always)]
        fn lt_u(self, a: __m256i, b: __m256i) -> __m256i {
            // Unsigned a < b as a signed comparison of both with the sign bit flipped.
            unsafe {
                let flip = _mm256_set1_epi32(i32::MIN);
                _mm256_cmpgt_epi32(_mm256_xor_si256(b, flip), _mm256_xor_si256(a, flip))
            }
        }

        #[inline(always)]
        fn add_i(self, a: __m256i, b: __m256i) -> __m256i {
            unsafe { _mm256_add_epi32(a, b) }
        }

        #[inline(always)]
        fn mul_i(self, a: __m256i, b: __m256i) -> __m256i {
            unsafe { _mm256_mullo_epi32(a, b) }
        }

        #[inline(always)]
        fn or_u(self, a: __m256i, b: __m256i) -> __m256i {
            unsafe { _mm256_or_si256(a, b) }
        }

        #[inline(always)]
        fn nonneg_bits(self, a: __m256i) -> u32 {
            unsafe { !(_mm256_movemask_ps(_mm256_castsi256_ps(a)) as u32) & 0xff }
        }

        #[inline(always)]
        fn and_m(self, a: __m256i, b: __m256i) -> __m256i {
            unsafe { _mm256_and_si256(a, b) }
        }

        #[inline(always)]
        fn or_m(self, a: __m256i, b: __m256i) -> __m256i {
            unsafe { _mm256_or_si256(a, b) }
        }

        #[inline(always)]
        fn bits(self, m: __m256i) -> u32 {
            unsafe { _mm256_movemask_ps(_mm256_castsi256_ps(m)) as u32 }
        }

        #[inline(always)]
        fn mask(self, bits: u32) -> __m256i {
            unsafe {
                let lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
                _mm256_cmpeq_epi32(
                    _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane_bit),
                    lane_bit,
                )
            }
        }

        #[inline(always)]
        fn any(self, m: __m256i) -> bool {
            unsafe { _mm256_testz_si256(m, m) == 0 }
        }

        #[inline(always)]
        fn blend_store(self, dst: &mut [f32], new: __m256, m: __m256i) {
            let dst = &mut dst[..LANES];
            // `dst` holds 8 floats (sliced above), read and written as 8 u32.
            unsafe { blend_store8(dst.as_mut_ptr() as *mut u32, _mm256_castps_si256(new), m) }
        }

        #[inline(always)]
        fn blend_store_u(self, dst: &mut [u32], new: __m256i, m: __m256i) {
            let dst = &mut dst[..LANES];
            unsafe { blend_store8(dst.as_mut_ptr(), new, m) }
        }

        #[inline(always)]
        fn store_rgb(self, c: &[__m256; 3], dst: &mut [Vec3]) {
            let dst = &mut dst[..LANES];
            // `dst` is 8 pixels, 24 floats (`Vec3` is three f32, `repr(C)`).
            unsafe {
                store_rgb8(
                    dst.as_mut_ptr() as *mut f32,
                    self.sanitize(c[0]),
                    self.sanitize(c[1]),
                    self.sanitize(c[2]),
                )
            }
        }

        #[inline(always)]
        unsafe fn gather_rgb(self, texels: &[Vec3], idx: __m256i) -> [__m256; 3] {
            // The indices are valid (the caller's promise).
            unsafe { gather_rgb8(texels, idx) }
        }
    };
}

// SAFETY: an `Avx2` exists only on CPUs with AVX2 (`Avx2::try_new`), which is all its operations
// and its kernels' target features use.
unsafe impl Simd for Avx2 {
    const NAME: &'static str = "avx2";
    type Half = Avx2;

    #[inline(always)]
    fn half(self) -> Avx2 {
        self
    }

    #[inline(always)]
    fn vectorize<K: Kernel>(self, kernel: K) -> K::Output {
        #[target_feature(enable = "avx2")]
        #[inline]
        unsafe fn run<K: Kernel>(kernel: K, simd: Avx2) -> K::Output {
            kernel.run(simd)
        }
        // SAFETY: the token proves the CPU has AVX2.
        unsafe { run(kernel, self) }
    }

    avx2_ops!();
}

// SAFETY: an `Avx512Half` comes only from an `Avx512`, which exists only on CPUs with AVX2,
// AVX-512F, AVX-512VL and POPCNT.
unsafe impl Simd for Avx512Half {
    const NAME: &'static str = "avx512";
    type Half = Avx512Half;

    #[inline(always)]
    fn half(self) -> Avx512Half {
        self
    }

    #[inline(always)]
    fn vectorize<K: Kernel>(self, kernel: K) -> K::Output {
        #[target_feature(enable = "avx2,avx512f,avx512vl,popcnt")]
        #[inline]
        unsafe fn run<K: Kernel>(kernel: K, simd: Avx512Half) -> K::Output {
            kernel.run(simd)
        }
        // SAFETY: the token proves the CPU has these features.
        unsafe { run(kernel, self) }
    }

    avx2_ops!();
}

/// For interleaving 16 lanes of r, g, b into 16 pixels (48 floats, 3 registers): output register
/// j, lane q holds float k = 16 j + q, channel k % 3 of pixel k / 3. The first two-source
/// permutation picks r or g (index i or 16 + i), the second keeps that (index q) or picks b
/// (16 + i).
const INTERLEAVE16: [[[i32; 16]; 2]; 3] = {
    let mut t = [[[0i32; 16]; 2]; 3];
    let mut j = 0;
    while j < 3 {
        let mut q = 0;
        while q < 16 {
            let k = 16 * j + q;
            let (i, c) = ((k / 3) as i32, k % 3);
            t[j][0][q] = match c {
                0 => i,
                1 => 16 + i,
                _ => 0,
            };
            t[j][1][q] = if c == 2 { 16 + i } else { q as i32 };
            q += 1;
        }
        j += 1;
    }
    t
};

/// Lanes of the AVX-512 token.
const W: usize = 16;

// SAFETY: an `Avx512` exists only on CPUs with AVX2, AVX-512F, AVX-512VL and POPCNT
// (`Avx512::try_new`), which is all its operations and its kernels' target features use.
unsafe impl Simd for Avx512 {
    const NAME: &'static str = "avx512";
    const LANES: usize = W;
    type F = __m512;
    type U = __m512i;
    type M = __mmask16;
    type Half = Avx512Half;

    #[inline(always)]
    fn half(self) -> Avx512Half {
        Avx512Half(())
    }

    #[inline(always)]
    fn vectorize<K: Kernel>(self, kernel: K) -> K::Output {
        #[target_feature(enable = "avx2,avx512f,avx512vl,popcnt")]
        #[inline]
        unsafe fn run<K: Kernel>(kernel: K, simd: Avx512) -> K::Output {
            kernel.run(simd)
        }
        // SAFETY: the token proves the CPU has these features.
        unsafe { run(kernel, self) }
    }

    #[inline(always)]
    fn splat(self, x: f32) -> __m512 {
        // SAFETY (this and every block below): the token proves the CPU has AVX-512F.
        unsafe { _mm512_set1_ps(x) }
    }

    #[inline(always)]
    fn load(self, src: &[f32]) -> __m512 {
        let src = &src[..W];
        unsafe { _mm512_loadu_ps(src.as_ptr()) }
    }

    #[inline(always)]
    fn store(self, x: __m512, dst: &mut [f32]) {
        let dst = &mut dst[..W];
        unsafe { _mm512_storeu_ps(dst.as_mut_ptr(), x) }
    }

    #[inline(always)]
    fn add(self, a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_add_ps(a, b) }
    }

    #[inline(always)]
    fn sub(self, a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_sub_ps(a, b) }
    }

    #[inline(always)]
    fn mul(self, a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_mul_ps(a, b) }
    }

    #[inline(always)]
    fn lt(self, a: __m512, b: __m512) -> __mmask16 {
        unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, b) }
    }

    #[inline(always)]
    fn eq(self, a: __m512, b: __m512) -> __mmask16 {
        unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(a, b) }
    }

    #[inline(always)]
    fn select(self, m: __mmask16, a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_mask_mov_ps(b, m, a) }
    }

    #[inline(always)]
    fn min(self, a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_min_ps(a, b) }
    }

    #[inline(always)]
    fn max(self, a: __m512, b: __m512) -> __m512 {
        unsafe { _mm512_max_ps(a, b) }
    }

    #[inline(always)]
    fn floor(self, a: __m512) -> __m512 {
        unsafe { _mm512_roundscale_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(a) }
    }

    #[inline(always)]
    fn to_i32(self, a: __m512) -> __m512i {
        unsafe { _mm512_cvttps_epi32(a) }
    }

    #[inline(always)]
    fn sanitize(self, x: __m512) -> __m512 {
        // Kept where x > 0 and x < inf (both ordered: NaN fails), zeroed elsewhere.
        unsafe {
            let m = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(x, _mm512_setzero_ps());
            let m = _mm512_mask_cmp_ps_mask::<_CMP_LT_OQ>(m, x, _mm512_set1_ps(f32::INFINITY));
            _mm512_maskz_mov_ps(m, x)
        }
    }

    #[inline(always)]
    fn splat_u(self, x: u32) -> __m512i {
        unsafe { _mm512_set1_epi32(x as i32) }
    }

    #[inline(always)]
    fn load_u(self, src: &[u32]) -> __m512i {
        let src = &src[..W];
        unsafe { _mm512_loadu_si512(src.as_ptr() as *const _) }
    }

    #[inline(always)]
    fn eq_u(self, a: __m512i, b: __m512i) -> __mmask16 {
        unsafe { _mm512_cmpeq_epi32_mask(a, b) }
    }

    #[inline(always)]
    fn lt_u(self, a: __m512i, b: __m512i) -> __mmask16 {
        unsafe { _mm512_cmplt_epu32_mask(a, b) }
    }

    #[inline(always)]
    fn add_i(self, a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_add_epi32(a, b) }
    }

    #[inline(always)]
    fn mul_i(self, a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_mullo_epi32(a, b) }
    }

    #[inline(always)]
    fn or_u(self, a: __m512i, b: __m512i) -> __m512i {
        unsafe { _mm512_or_si512(a, b) }
    }

    #[inline(always)]
    fn nonneg_bits(self, a: __m512i) -> u32 {
        unsafe { _mm512_cmpge_epi32_mask(a, _mm512_setzero_si512()) as u32 }
    }

    #[inline(always)]
    fn and_m(self, a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }

    #[inline(always)]
    fn or_m(self, a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }

    #[inline(always)]
    fn bits(self, m: __mmask16) -> u32 {
        m as u32
    }

    #[inline(always)]
    fn mask(self, bits: u32) -> __mmask16 {
        bits as __mmask16
    }

    #[inline(always)]
    fn any(self, m: __mmask16) -> bool {
        m != 0
    }

    #[inline(always)]
    fn blend_store(self, dst: &mut [f32], new: __m512, m: __mmask16) {
        let dst = &mut dst[..W];
        // Read the 16 old lanes, blend in a register, store all 16 (no masked store).
        unsafe {
            let old = _mm512_loadu_ps(dst.as_ptr());
            _mm512_storeu_ps(dst.as_mut_ptr(), _mm512_mask_mov_ps(old, m, new));
        }
    }

    #[inline(always)]
    fn blend_store_u(self, dst: &mut [u32], new: __m512i, m: __mmask16) {
        let dst = &mut dst[..W];
        unsafe {
            let old = _mm512_loadu_si512(dst.as_ptr() as *const _);
            _mm512_storeu_si512(
                dst.as_mut_ptr() as *mut _,
                _mm512_mask_mov_epi32(old, m, new),
            );
        }
    }

    #[inline(always)]
    fn store_rgb(self, c: &[__m512; 3], dst: &mut [Vec3]) {
        let dst = &mut dst[..W];
        let [r, g, b] = [
            self.sanitize(c[0]),
            self.sanitize(c[1]),
            self.sanitize(c[2]),
        ];
        let out = dst.as_mut_ptr() as *mut f32;
        // `dst` is 16 pixels, 48 floats (`Vec3` is three f32, `repr(C)`); the index loads read
        // the constant table.
        unsafe {
            for (j, idx) in INTERLEAVE16.iter().enumerate() {
                let rg = _mm512_loadu_si512(idx[0].as_ptr() as *const _);
                let tb = _mm512_loadu_si512(idx[1].as_ptr() as *const _);
                let x = _mm512_permutex2var_ps(_mm512_permutex2var_ps(r, rg, g), tb, b);
                _mm512_storeu_ps(out.add(16 * j), x);
            }
        }
    }

    #[inline(always)]
    unsafe fn gather_rgb(self, texels: &[Vec3], idx: __m512i) -> [__m512; 3] {
        let base = texels.as_ptr() as *const f32;
        // SAFETY: 3 idx + ch addresses a float of `texels` and fits in i32 (the caller's
        // promise); the token has AVX-512F.
        unsafe {
            let i3 = _mm512_add_epi32(idx, _mm512_add_epi32(idx, idx));
            [
                _mm512_i32gather_ps::<4>(i3, base),
                _mm512_i32gather_ps::<4>(i3, base.add(1)),
                _mm512_i32gather_ps::<4>(i3, base.add(2)),
            ]
        }
    }
}
