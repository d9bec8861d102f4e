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
//! tested on such machines (the default build's tests compare the two builds bit for bit). The
//! image does not depend on the build.

use std::ops::{Add, Mul, Sub};

/// Number of lanes.
pub const LANES: usize = 8;

/// Whether the dispatch sites may run their AVX2 builds: the CPU supports AVX2 (detected at run
/// time; std caches the answer) and the crate was built without the `portable` feature. Always
/// `false` off x86-64 and with `portable`. The library calls a `#[target_feature(enable =
/// "avx2")]` function only after this returned `true` (the tests that compare the two builds
/// check the CPU themselves).
#[inline(always)]
pub fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        !cfg!(feature = "portable") && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
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
}
