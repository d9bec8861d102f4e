//! The portable token: 8 lanes as plain arrays, every operation an element-wise loop in the form
//! the compiler vectorizes for the baseline instruction set (SSE2 on x86-64). It runs on every
//! CPU and is the reference the other tokens are tested against.

use glam::Vec3;

use crate::{F32x8, Kernel, Simd, U32x8, LANES};

/// The portable instruction set: any CPU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Portable(());

impl Portable {
    /// The token (every CPU has the portable instruction set).
    pub const fn new() -> Portable {
        Portable(())
    }
}

/// Lane-wise map of two arrays.
#[inline(always)]
fn zip<T: Copy, R: Copy + Default>(
    a: [T; LANES],
    b: [T; LANES],
    f: impl Fn(T, T) -> R,
) -> [R; LANES] {
    let mut r = [R::default(); LANES];
    for l in 0..LANES {
        r[l] = f(a[l], b[l]);
    }
    r
}

/// The all-ones or all-zeros lane of a comparison.
#[inline(always)]
fn lane(b: bool) -> u32 {
    (b as u32).wrapping_neg()
}

/// Runs a portable kernel as a function of its own, as the other tokens' kernels are: a kernel
/// per call site keeps the small kernels' setup from being paid by every variant inlined into
/// one body.
#[inline(never)]
fn run<K: Kernel>(kernel: K, simd: Portable) -> K::Output {
    kernel.run(simd)
}

// SAFETY: every operation is portable Rust.
unsafe impl Simd for Portable {
    const NAME: &'static str = "portable";
    const LANES: usize = LANES;
    type F = F32x8;
    type U = U32x8;
    type M = U32x8;
    type Half = Portable;

    #[inline(always)]
    fn half(self) -> Portable {
        self
    }

    #[inline(always)]
    fn vectorize<K: Kernel>(self, kernel: K) -> K::Output {
        run(kernel, self)
    }

    #[inline(always)]
    fn splat(self, x: f32) -> F32x8 {
        F32x8::splat(x)
    }

    #[inline(always)]
    fn load(self, src: &[f32]) -> F32x8 {
        F32x8::load(src)
    }

    #[inline(always)]
    fn store(self, x: F32x8, dst: &mut [f32]) {
        dst[..LANES].copy_from_slice(&x.0);
    }

    #[inline(always)]
    fn add(self, a: F32x8, b: F32x8) -> F32x8 {
        a + b
    }

    #[inline(always)]
    fn sub(self, a: F32x8, b: F32x8) -> F32x8 {
        a - b
    }

    #[inline(always)]
    fn mul(self, a: F32x8, b: F32x8) -> F32x8 {
        a * b
    }

    #[inline(always)]
    fn lt(self, a: F32x8, b: F32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, |x, y| lane(x < y)))
    }

    #[inline(always)]
    fn eq(self, a: F32x8, b: F32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, |x, y| lane(x == y)))
    }

    #[inline(always)]
    fn select(self, m: U32x8, a: F32x8, b: F32x8) -> F32x8 {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = f32::from_bits((a.0[l].to_bits() & m.0[l]) | (b.0[l].to_bits() & !m.0[l]));
        }
        F32x8(r)
    }

    #[inline(always)]
    fn min(self, a: F32x8, b: F32x8) -> F32x8 {
        F32x8(zip(a.0, b.0, |x, y| if x < y { x } else { y }))
    }

    #[inline(always)]
    fn max(self, a: F32x8, b: F32x8) -> F32x8 {
        F32x8(zip(a.0, b.0, |x, y| if x > y { x } else { y }))
    }

    #[inline(always)]
    fn floor(self, a: F32x8) -> F32x8 {
        // `f32::floor`'s value in lane operations: the baseline x86-64 target has no rounding
        // instruction and makes of `floor` a library call per lane. Below 2^23 in magnitude
        // the value truncated through i32, stepped down where truncation went up, with the
        // sign of the input (so -0.0 and the negative values above -1 keep theirs); larger
        // values, infinities and NaN are their own floor.
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            let x = a.0[l];
            let t = x as i32 as f32;
            let t = if t > x { t - 1.0 } else { t };
            r[l] = if x.abs() < 8_388_608.0 {
                t.copysign(x)
            } else {
                x
            };
        }
        F32x8(r)
    }

    #[inline(always)]
    fn to_i32(self, a: F32x8) -> U32x8 {
        let mut r = [0; LANES];
        for l in 0..LANES {
            r[l] = a.0[l] as i32 as u32;
        }
        U32x8(r)
    }

    #[inline(always)]
    fn sanitize(self, x: F32x8) -> F32x8 {
        // "Finite and positive" as float compares that stay vector instructions: x - x is 0
        // exactly for finite x (NaN for inf and NaN), and x > 0 fails for NaN. (Written as
        // `is_finite()` or `x < inf`, the test is folded into an integer range check that is not
        // vectorized.)
        let mut m = [false; LANES];
        for l in 0..LANES {
            let v = x.0[l];
            #[allow(clippy::eq_op)] // v - v is the finiteness test, on purpose
            let finite = v - v == 0.0;
            m[l] = (v > 0.0) & finite;
        }
        F32x8::select(&m, x, F32x8::splat(0.0))
    }

    #[inline(always)]
    fn splat_u(self, x: u32) -> U32x8 {
        U32x8([x; LANES])
    }

    #[inline(always)]
    fn load_u(self, src: &[u32]) -> U32x8 {
        U32x8(src[..LANES].try_into().unwrap())
    }

    #[inline(always)]
    fn eq_u(self, a: U32x8, b: U32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, |x, y| lane(x == y)))
    }

    #[inline(always)]
    fn lt_u(self, a: U32x8, b: U32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, |x, y| lane(x < y)))
    }

    #[inline(always)]
    fn add_i(self, a: U32x8, b: U32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, u32::wrapping_add))
    }

    #[inline(always)]
    fn mul_i(self, a: U32x8, b: U32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, u32::wrapping_mul))
    }

    #[inline(always)]
    fn or_u(self, a: U32x8, b: U32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, |x, y| x | y))
    }

    #[inline(always)]
    fn nonneg_bits(self, a: U32x8) -> u32 {
        let mut bits = 0;
        for l in 0..LANES {
            bits |= (((a.0[l] as i32) >= 0) as u32) << l;
        }
        bits
    }

    #[inline(always)]
    fn and_m(self, a: U32x8, b: U32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, |x, y| x & y))
    }

    #[inline(always)]
    fn or_m(self, a: U32x8, b: U32x8) -> U32x8 {
        U32x8(zip(a.0, b.0, |x, y| x | y))
    }

    #[inline(always)]
    fn bits(self, m: U32x8) -> u32 {
        let mut bits = 0;
        for l in 0..LANES {
            bits |= (m.0[l] >> 31) << l;
        }
        bits
    }

    #[inline(always)]
    fn mask(self, bits: u32) -> U32x8 {
        let mut m = [0; LANES];
        for l in 0..LANES {
            m[l] = lane((bits >> l) & 1 != 0);
        }
        U32x8(m)
    }

    #[inline(always)]
    fn any(self, m: U32x8) -> bool {
        let mut acc = 0;
        for l in 0..LANES {
            acc |= m.0[l];
        }
        acc != 0
    }

    #[inline(always)]
    fn blend_store(self, dst: &mut [f32], new: F32x8, m: U32x8) {
        let d: &mut [f32; LANES] = (&mut dst[..LANES]).try_into().unwrap();
        *d = self.select(m, new, F32x8(*d)).0;
    }

    #[inline(always)]
    fn blend_store_u(self, dst: &mut [u32], new: U32x8, m: U32x8) {
        let d: &mut [u32; LANES] = (&mut dst[..LANES]).try_into().unwrap();
        for l in 0..LANES {
            d[l] = (new.0[l] & m.0[l]) | (d[l] & !m.0[l]);
        }
    }

    #[inline(always)]
    fn store_rgb(self, c: &[F32x8; 3], dst: &mut [Vec3]) {
        let [r, g, b] = [
            self.sanitize(c[0]).0,
            self.sanitize(c[1]).0,
            self.sanitize(c[2]).0,
        ];
        let o: &mut [Vec3; LANES] = (&mut dst[..LANES]).try_into().unwrap();
        for l in 0..LANES {
            o[l] = Vec3::new(r[l], g[l], b[l]);
        }
    }

    #[inline(always)]
    unsafe fn gather_rgb(self, texels: &[Vec3], idx: U32x8) -> [F32x8; 3] {
        let mut r = [[0.0f32; LANES]; 3];
        for l in 0..LANES {
            // SAFETY: the caller guarantees 0 <= idx[l] < texels.len().
            let t = unsafe { *texels.get_unchecked(idx.0[l] as usize) };
            r[0][l] = t.x;
            r[1][l] = t.y;
            r[2][l] = t.z;
        }
        [F32x8(r[0]), F32x8(r[1]), F32x8(r[2])]
    }
}
