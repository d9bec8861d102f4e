//! Lanes: the fixed-width SIMD-style value type the rasterizer and the deferred pass compute with,
//! 8 `f32` lanes in a plain array. Every operation is a separate element-wise loop over the array,
//! the form LLVM reliably turns into one vector instruction (SSE2 by default, AVX2 in the
//! functions compiled for it), so the hot loops stay portable, safe, stable Rust.
//!
//! Invariant: every operation is the lane-wise IEEE operation and nothing else (no fused
//! multiply-add, no reassociation), so a lane computes the same bits as the scalar expression
//! written in the same order.
//!
//! AVX2 builds and the `portable` feature: the rasterizer, the patch and texture shaders and
//! (through the texture shader) the texel gather are compiled twice, a portable body and a
//! `#[target_feature(enable = "avx2")]` build of the same body; each dispatch site takes the AVX2
//! build only when [`avx2_available`] says so. Built with the cargo feature `portable`
//! (`cargo test --release --features portable`), [`avx2_available`] is always `false`, so every
//! hot loop runs its portable body even on a CPU with AVX2: that is how the portable bodies get
//! tested on such machines (the default build's tests compare the builds bit for bit). The patch
//! shader, the raster kernels and the compositor's records merge have a third build for CPUs with
//! AVX-512 ([`avx512_available`]). [`cap_build`] caps
//! the build at run time (the binary's `PIXELFLOW_SIM_LANES`), to measure the builds against
//! each other in one binary. The image does not depend on the build.

use std::ops::{Add, Mul, Sub};

/// Number of lanes.
pub const LANES: usize = 8;

/// The builds of the hot loops, narrowest first. Every build computes the same bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Build {
    /// The portable bodies (fixed-width arrays the compiler vectorizes for the baseline ISA).
    Portable,
    /// The `#[target_feature(enable = "avx2")]` builds.
    Avx2,
    /// The AVX-512 builds: the patch shader's 16-lane evaluation of two blocks at once, the
    /// compositor's 16-lane records merge, and the AVX2 intrinsics of the raster kernels
    /// EVEX-encoded (coefficient broadcasts folded into the arithmetic).
    Avx512,
}

/// Parses a build's name, as the binary's `PIXELFLOW_SIM_LANES` gives it: `portable`, `avx2`,
/// `avx512`, or `auto` (`Ok(None)`: no cap).
pub fn parse_build(value: &str) -> Result<Option<Build>, String> {
    match value {
        "portable" => Ok(Some(Build::Portable)),
        "avx2" => Ok(Some(Build::Avx2)),
        "avx512" => Ok(Some(Build::Avx512)),
        "auto" | "" => Ok(None),
        _ => Err("expected portable, avx2, avx512 or auto".to_string()),
    }
}

/// The build cache: `u8::MAX` until first asked, then the [`Build`] as `u8`.
static BUILD: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(u8::MAX);

/// The build the dispatch sites take: the widest the CPU supports, `Portable` under the
/// `portable` cargo feature, and never wider than a [`cap_build`]. Detected once and cached.
#[inline(always)]
pub fn build() -> Build {
    match BUILD.load(std::sync::atomic::Ordering::Relaxed) {
        0 => Build::Portable,
        1 => Build::Avx2,
        2 => Build::Avx512,
        _ => {
            let b = cpu_build();
            BUILD.store(b as u8, std::sync::atomic::Ordering::Relaxed);
            b
        }
    }
}

/// Caps the build at `cap` from now on (what the CPU lacks stays off): for timing the builds
/// against each other in one binary. The images do not change.
pub fn cap_build(cap: Build) {
    BUILD.store(
        cpu_build().min(cap) as u8,
        std::sync::atomic::Ordering::Relaxed,
    );
}

/// The widest build this CPU and the cargo features allow.
fn cpu_build() -> Build {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        if cfg!(feature = "portable") || !has!("avx2") {
            Build::Portable
        } else if has!("avx512f") && has!("avx512vl") && has!("popcnt") {
            Build::Avx512
        } else {
            Build::Avx2
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Build::Portable
    }
}

/// Whether the dispatch sites may run their AVX2 builds: [`build`] is at least
/// [`Build::Avx2`] (the CPU supports AVX2, the crate was built without the `portable` feature,
/// and no [`cap_build`] said `Portable`). Always `false` off x86-64 and with `portable`.
/// The library calls a `#[target_feature(enable = "avx2")]` function only after this returned
/// `true` (the tests that compare the builds check the CPU themselves).
#[inline(always)]
pub fn avx2_available() -> bool {
    build() >= Build::Avx2
}

/// Whether the AVX-512 builds may run: [`build`] is [`Build::Avx512`] (the CPU also has
/// AVX-512F, AVX-512VL and POPCNT). Those builds keep the 8-lane AVX2 intrinsics where they
/// have no 16-lane form, and compiled with these features LLVM encodes them as EVEX
/// instructions, folds each coefficient broadcast into the multiply or add that uses it
/// (embedded broadcast) and has 32 vector registers instead of 16.
#[inline(always)]
pub fn avx512_available() -> bool {
    build() >= Build::Avx512
}

/// 8 `f32` lanes.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[repr(C, align(32))]
pub struct F32x8(pub [f32; LANES]);

impl F32x8 {
    /// All lanes equal to `x`.
    #[inline(always)]
    pub fn splat(x: f32) -> F32x8 {
        F32x8([x; LANES])
    }

    /// Lane-wise `if m { a } else { b }`.
    #[inline(always)]
    pub fn select(m: &[bool; LANES], a: F32x8, b: F32x8) -> F32x8 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = if m[l] { a.0[l] } else { b.0[l] };
        }
        F32x8(r)
    }
}

macro_rules! lane_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for F32x8 {
            type Output = F32x8;
            #[inline(always)]
            fn $f(self, o: F32x8) -> F32x8 {
                let mut r = [0.0; LANES];
                for l in 0..LANES {
                    r[l] = self.0[l] $op o.0[l];
                }
                F32x8(r)
            }
        }
    };
}

lane_op!(Add, add, +);
lane_op!(Sub, sub, -);
lane_op!(Mul, mul, *);

/// Writes `new[l]` over `dst[l]` in the lanes where `mask` is all ones, keeping the others: the
/// old 8 lanes are loaded, blended with the new ones in a register, and the full 32 bytes
/// stored back with one plain store. Written out in inline assembly because LLVM otherwise
/// folds exactly this load-select-store into a masked store (`vmaskmovps` / `vpmaskmovd`),
/// which in the rasterizer's inner loop was slow to retire and blocked store-to-load forwarding
/// for the next primitive's depth test on the same block.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn blend_store8_avx2(
    dst: &mut [u32; LANES],
    new: &[u32; LANES],
    mask: std::arch::x86_64::__m256i,
) {
    use std::arch::x86_64::*;
    // SAFETY: `dst` and `new` are 8 u32 each (unaligned 32-byte loads and store); the assembly
    // writes exactly the 32 bytes of `dst`, which this function borrows mutably.
    unsafe {
        let old = _mm256_loadu_si256(dst.as_ptr() as *const __m256i);
        let nv = _mm256_loadu_si256(new.as_ptr() as *const __m256i);
        let r = _mm256_blendv_epi8(old, nv, mask);
        std::arch::asm!(
            "vmovdqu ymmword ptr [{p}], {r}",
            p = in(reg) dst.as_mut_ptr(),
            r = in(ymm_reg) r,
            options(nostack, preserves_flags)
        );
    }
}

/// [`blend_store8_avx2`] for `f32` lanes (the same bits moved).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn blend_store8_f32_avx2(
    dst: &mut [f32; LANES],
    new: &[f32; LANES],
    mask: std::arch::x86_64::__m256i,
) {
    // SAFETY: [f32; 8] and [u32; 8] have the same size and alignment; every bit pattern is valid
    // for both. The CPU requirement is passed on to the caller.
    unsafe {
        let d = &mut *(dst as *mut [f32; LANES] as *mut [u32; LANES]);
        let n = &*(new as *const [f32; LANES] as *const [u32; LANES]);
        blend_store8_avx2(d, n, mask)
    }
}

/// The all-ones / all-zeros lane mask of the bits of `bits` (lane l from bit l).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn lane_mask_avx2(bits: u32) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    let lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    _mm256_cmpeq_epi32(
        _mm256_and_si256(_mm256_set1_epi32(bits as i32), lane_bit),
        lane_bit,
    )
}

/// The depth test of the rasterizer and the compositor for one block in one AVX2 register: lane l
/// passes when bit l of `bits` is set (covered) and `w[l] < depth[l]`, or `w[l] == depth[l]` and
/// `ids[l] < poly[l]` (unsigned). Returns the all-ones / all-zeros lane mask, or `None` when no
/// lane passes. The same IEEE comparisons as the scalar form (ordered: false on NaN).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub unsafe fn depth_test_avx2(
    bits: u32,
    w: &[f32; LANES],
    depth: &[f32; LANES],
    ids: &[u32; LANES],
    poly: &[u32; LANES],
) -> Option<std::arch::x86_64::__m256i> {
    use std::arch::x86_64::*;
    // SAFETY: every pointer is to 8 lanes of 4 bytes (unaligned 32-byte loads).
    unsafe {
        let covered = lane_mask_avx2(bits);
        let wv = _mm256_loadu_ps(w.as_ptr());
        let dv = _mm256_loadu_ps(depth.as_ptr());
        let nearer = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LT_OQ>(wv, dv));
        let tie = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_EQ_OQ>(wv, dv));
        // Unsigned id < poly[l] as a signed comparison of both with the sign bit flipped.
        let flip = _mm256_set1_epi32(i32::MIN);
        let pv = _mm256_xor_si256(_mm256_loadu_si256(poly.as_ptr() as *const __m256i), flip);
        let iv = _mm256_loadu_si256(ids.as_ptr() as *const __m256i);
        let smaller = _mm256_cmpgt_epi32(pv, _mm256_xor_si256(iv, flip));
        let m = _mm256_and_si256(
            covered,
            _mm256_or_si256(nearer, _mm256_and_si256(tie, smaller)),
        );
        if _mm256_testz_si256(m, m) != 0 {
            None
        } else {
            Some(m)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn avx2_builds_run_where_the_cpu_has_avx2_unless_portable() {
        #[cfg(target_arch = "x86_64")]
        let cpu = std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let cpu = false;
        assert_eq!(avx2_available(), cpu && !cfg!(feature = "portable"));
    }

    #[test]
    fn lanes_compute_the_scalar_expression() {
        let a = F32x8(std::array::from_fn(|l| l as f32 * 0.3 - 1.0));
        let b = F32x8(std::array::from_fn(|l| 2.0 - l as f32 * 0.7));
        let r = (a * b + F32x8::splat(0.1)) - a;
        let m: [bool; LANES] = std::array::from_fn(|l| l % 3 == 0);
        let s = F32x8::select(&m, r, b);
        for l in 0..LANES {
            let want = (a.0[l] * b.0[l] + 0.1) - a.0[l];
            assert_eq!(r.0[l].to_bits(), want.to_bits());
            assert_eq!(s.0[l], if l % 3 == 0 { want } else { b.0[l] });
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_depth_test_is_the_scalar_one() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        // Depths with ties, infinities, NaN and signed zeros; ids across the sign bit of i32.
        const D: [f32; 7] = [1.0, 2.0, f32::INFINITY, f32::NAN, 0.0, -0.0, 1.5];
        const P: [u32; 5] = [0, 7, 0x8000_0000, 0xffff_fffe, u32::MAX];
        let mut x = 17u64;
        let mut next = |n: usize| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 33) as usize % n
        };
        for _ in 0..5000 {
            let bits = next(256) as u32;
            let w: [f32; LANES] = std::array::from_fn(|_| D[next(D.len())]);
            let depth: [f32; LANES] = std::array::from_fn(|_| D[next(D.len())]);
            let ids: [u32; LANES] = std::array::from_fn(|_| P[next(P.len())]);
            let poly: [u32; LANES] = std::array::from_fn(|_| P[next(P.len())]);
            let want: u32 = (0..LANES)
                .map(|l| {
                    let covered = (bits >> l) & 1 != 0;
                    let pass = (w[l] < depth[l]) | ((w[l] == depth[l]) & (ids[l] < poly[l]));
                    ((covered & pass) as u32) << l
                })
                .sum();
            // SAFETY: the CPU has AVX2 (checked above).
            let got = unsafe { depth_test_avx2(bits, &w, &depth, &ids, &poly) }.map(|m| {
                use std::arch::x86_64::*;
                // SAFETY: as above.
                unsafe { _mm256_movemask_ps(_mm256_castsi256_ps(m)) as u32 }
            });
            assert_eq!(got.unwrap_or(0), want);
            assert_eq!(got.is_none(), want == 0);
        }
    }
}
