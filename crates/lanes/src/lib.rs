//! Lanes: the one SIMD abstraction every hot loop of pixelflow-sim is written in, once.
//!
//! An instruction set is a type, a zero-sized *token* ([`Portable`], [`Avx2`], [`Avx512`],
//! [`Avx512Half`]) whose only constructors check the CPU, so holding one proves the CPU can run
//! its operations. A kernel is a type implementing [`Kernel`]: its body is written once, generic
//! over `S: Simd`, in terms of the token's lane types and operations (`s.add(a, b)`,
//! `s.lt(a, b)`, `s.blend_store(..)`). [`Simd::vectorize`] runs a kernel inside a
//! `#[target_feature]` function of the token's instruction set, so the generic body, inlined
//! there, is compiled for that set; the token's operations are `#[inline(always)]` and become
//! single instructions. [`Isa`] is the run-time choice: detected once ([`Isa::detect`]), capped on
//! request ([`Isa::capped`]), carried in the frame's options and matched once per kernel call.
//!
//! Invariants:
//! - every operation is the lane-wise IEEE operation and nothing else (no fused multiply-add, no
//!   reassociation, ordered comparisons that are false on NaN), so every token computes the same
//!   bits as the scalar expression written in the same order, and a kernel's result does not
//!   depend on the token it ran with (the test suites compare them bit for bit);
//! - a token's `LANES` is 8 or 16; `Half` is the 8-lane token of the same instruction set (the
//!   token itself when it has 8 lanes), for a kernel's tail or for kernels built on blocks of 8.
//!
//! Writing a kernel (each rule learnt from a measured slowdown):
//! - no out-of-line call inside a kernel's loops, not even on a cold path (a copy through
//!   `copy_from_slice`, a helper marked `#[inline(never)]`): every vector register is
//!   caller-saved, so the loop spills and reloads what it keeps in registers (the 16-lane patch
//!   shader ran 20 % slower with one `memcpy` on its row-tail path); panics are fine (they never
//!   return);
//! - no closure that calls a token operation: a closure is a function of its own, compiled
//!   without the kernel's target features unless the optimizer happens to inline it (the patch
//!   shader ran 30 times slower with its channels in a `map` closure); helpers are
//!   `#[inline(always)]` functions;
//! - values needed once per patch are loaded where they are used rather than held across a loop
//!   (16-lane rows need most of the 32 registers).
//!
//! Why tokens rather than a `const HW: bool` or per-ISA copies: the compiler checks that AVX-512
//! operations are only reachable through a value that proves the CPU has them, and a kernel has
//! one body whatever the instruction set. Why our own rather than a crate: the kernels need a few
//! operations with exact semantics the crates do not offer (a blend written with full-width
//! stores, the sign-bit test of edge functions, the image's clamp in three instructions, pixels
//! interleaved by permutation), and measured against `pulp` on the patch shader's arithmetic
//! (`tools/compare-pulp`) the set kept here is as fast with AVX2 and faster with AVX-512.

// Lane loops index several fixed-width arrays with one lane index on purpose: that is the form
// the compiler vectorizes and the reader checks lane by lane.
#![allow(clippy::needless_range_loop)]

use std::fmt;
use std::ops::{Add, Mul, Sub};

use glam::Vec3;

mod portable;
#[cfg(target_arch = "x86_64")]
mod x86;

pub use portable::Portable;
#[cfg(target_arch = "x86_64")]
pub use x86::{Avx2, Avx512, Avx512Half};

/// Lanes of the 8-lane types ([`F32x8`], the blocks of the rasterizer and the shaders).
pub const LANES: usize = 8;

/// Code generic over the instruction set: [`Simd::vectorize`] (or [`Isa::run`]) calls
/// [`Kernel::run`] inside a function compiled for the token's instruction set. Implementations
/// mark `run` `#[inline(always)]` so the body is compiled there rather than called.
pub trait Kernel {
    /// What the kernel returns.
    type Output;
    /// The kernel's body, with the token `simd`.
    fn run<S: Simd>(self, simd: S) -> Self::Output;
}

/// An instruction set at one lane width, as a token value (see the module documentation).
///
/// # Safety
/// A value of an implementing type may exist only while the CPU supports every instruction its
/// operations and its [`Simd::vectorize`] use; its constructors check the CPU.
pub unsafe trait Simd: Copy + Send + Sync + fmt::Debug + 'static {
    /// Name of the instruction set (`portable`, `avx2`, `avx512`).
    const NAME: &'static str;
    /// Lanes of [`Simd::F`], [`Simd::U`] and [`Simd::M`]: 8 or 16.
    const LANES: usize;
    /// `LANES` f32 lanes.
    type F: Copy;
    /// `LANES` u32 lanes (also the i32 lanes of [`Simd::add_i`] and [`Simd::nonneg_bits`]).
    type U: Copy;
    /// A mask of `LANES` lanes, from comparisons.
    type M: Copy;
    /// The 8-lane token of the same instruction set (`Self` when `LANES` is 8).
    type Half: Simd;

    /// The 8-lane token of the same instruction set.
    fn half(self) -> Self::Half;
    /// Runs `kernel` compiled for this instruction set.
    fn vectorize<K: Kernel>(self, kernel: K) -> K::Output;

    /// Every lane `x`.
    fn splat(self, x: f32) -> Self::F;
    /// The first `LANES` values of `src` (panics if shorter).
    fn load(self, src: &[f32]) -> Self::F;
    /// Writes the lanes into the first `LANES` values of `dst` (panics if shorter).
    fn store(self, x: Self::F, dst: &mut [f32]);
    /// `a + b`.
    fn add(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a - b`.
    fn sub(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a * b` (never fused with an add).
    fn mul(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a < b` (false when either is NaN).
    fn lt(self, a: Self::F, b: Self::F) -> Self::M;
    /// `a == b` (false when either is NaN; `-0 == +0`).
    fn eq(self, a: Self::F, b: Self::F) -> Self::M;
    /// `if m { a } else { b }` per lane, bits moved unchanged.
    fn select(self, m: Self::M, a: Self::F, b: Self::F) -> Self::F;
    /// `if a < b { a } else { b }` (so `b` where either is NaN, as x86's MINPS).
    fn min(self, a: Self::F, b: Self::F) -> Self::F;
    /// `if a > b { a } else { b }` (so `b` where either is NaN, as x86's MAXPS).
    fn max(self, a: Self::F, b: Self::F) -> Self::F;
    /// `a.floor()`.
    fn floor(self, a: Self::F) -> Self::F;
    /// `a` truncated toward 0 to i32, for lanes whose value is in i32's range (the result of
    /// others depends on the token).
    fn to_i32(self, a: Self::F) -> Self::U;
    /// The image's clamp: `x` where `0 < x < inf`, else `+0.0` (negative values, both zeros,
    /// infinities and NaN all become `+0.0`).
    fn sanitize(self, x: Self::F) -> Self::F;

    /// Every lane `x`.
    fn splat_u(self, x: u32) -> Self::U;
    /// The first `LANES` values of `src` (panics if shorter).
    fn load_u(self, src: &[u32]) -> Self::U;
    /// `a == b`.
    fn eq_u(self, a: Self::U, b: Self::U) -> Self::M;
    /// `a < b`, unsigned.
    fn lt_u(self, a: Self::U, b: Self::U) -> Self::M;
    /// `a + b` as wrapping i32.
    fn add_i(self, a: Self::U, b: Self::U) -> Self::U;
    /// `a * b` as wrapping i32 (the low 32 bits of the product).
    fn mul_i(self, a: Self::U, b: Self::U) -> Self::U;
    /// `a | b`.
    fn or_u(self, a: Self::U, b: Self::U) -> Self::U;
    /// Bit l set where lane l, as i32, is `>= 0` (its sign bit is clear).
    fn nonneg_bits(self, a: Self::U) -> u32;

    /// `a & b`.
    fn and_m(self, a: Self::M, b: Self::M) -> Self::M;
    /// `a | b`.
    fn or_m(self, a: Self::M, b: Self::M) -> Self::M;
    /// Lane l of the mask as bit l.
    fn bits(self, m: Self::M) -> u32;
    /// The mask whose lane l is bit l of `bits` (higher bits ignored).
    fn mask(self, bits: u32) -> Self::M;
    /// Whether any lane is set.
    fn any(self, m: Self::M) -> bool;

    /// `dst[l] = new[l]` where `m[l]`, over the first `LANES` values of `dst`, written with
    /// full-width stores (never masked stores: those blocked store-to-load forwarding in the
    /// rasterizer's inner loop).
    fn blend_store(self, dst: &mut [f32], new: Self::F, m: Self::M);
    /// [`Simd::blend_store`] for u32 lanes.
    fn blend_store_u(self, dst: &mut [u32], new: Self::U, m: Self::M);
    /// Writes lane l of `c[0]`, `c[1]`, `c[2]`, each through [`Simd::sanitize`], as pixel
    /// `dst[l]` for the first `LANES` pixels of `dst` (panics if shorter).
    fn store_rgb(self, c: &[Self::F; 3], dst: &mut [Vec3]);
    /// The texels `texels[idx[l]]` (`idx` as i32 lanes) as three channels.
    ///
    /// # Safety
    /// Every lane of `idx` must be a valid index of `texels`.
    unsafe fn gather_rgb(self, texels: &[Vec3], idx: Self::U) -> [Self::F; 3];
}

/// The instruction-set levels a build of the hot loops exists for, narrowest first (for caps and
/// reports; an [`Isa`] is a level the CPU has, with its token).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Level {
    /// The portable build (fixed-width arrays the compiler vectorizes for the baseline ISA).
    Portable,
    /// AVX2, 8 lanes.
    Avx2,
    /// AVX-512 (F, VL): 16 lanes where a kernel has a 16-lane form, EVEX-encoded 8-lane code
    /// elsewhere.
    Avx512,
}

impl Level {
    /// Every level, narrowest first.
    pub const ALL: [Level; 3] = [Level::Portable, Level::Avx2, Level::Avx512];

    /// The level's name (`portable`, `avx2`, `avx512`).
    pub fn name(self) -> &'static str {
        match self {
            Level::Portable => "portable",
            Level::Avx2 => "avx2",
            Level::Avx512 => "avx512",
        }
    }

    /// Parses a cap: `portable`, `avx2`, `avx512`, or `auto` (`Ok(None)`: no cap).
    pub fn parse_cap(value: &str) -> Result<Option<Level>, String> {
        match value {
            "auto" | "" => Ok(None),
            _ => Level::ALL
                .into_iter()
                .find(|l| l.name() == value)
                .map(Some)
                .ok_or_else(|| "expected portable, avx2, avx512 or auto".to_string()),
        }
    }

    /// The `f32` lanes of this level's widest kernels: 8, or 16 for AVX-512 (whose kernels
    /// without a 16-lane form run 8 lanes, EVEX-encoded).
    pub fn lanes(self) -> usize {
        match self {
            Level::Portable | Level::Avx2 => LANES,
            Level::Avx512 => 2 * LANES,
        }
    }

    /// The level named `name` (`portable`, `avx2`, `avx512`), if any.
    pub fn named(name: &str) -> Option<Level> {
        Level::ALL.into_iter().find(|l| l.name() == name)
    }

    /// `avx2 (8 f32 lanes)`: the build as reports name it.
    pub fn describe(self) -> String {
        format!("{} ({} f32 lanes)", self.name(), self.lanes())
    }

    /// The first CPU feature this level needs that the running CPU lacks (`None` when it has
    /// them all), named as in [`Level::requirement`].
    pub fn missing_feature(self) -> Option<&'static str> {
        #[cfg(target_arch = "x86_64")]
        {
            let needs: &[(&str, bool)] = match self {
                Level::Portable => &[],
                Level::Avx2 => &[("AVX2", is_x86_feature_detected!("avx2"))],
                Level::Avx512 => &[
                    ("AVX2", is_x86_feature_detected!("avx2")),
                    ("AVX-512F", is_x86_feature_detected!("avx512f")),
                    ("AVX-512VL", is_x86_feature_detected!("avx512vl")),
                    ("POPCNT", is_x86_feature_detected!("popcnt")),
                ],
            };
            needs.iter().find(|(_, has)| !has).map(|(name, _)| *name)
        }
        #[cfg(not(target_arch = "x86_64"))]
        match self {
            Level::Portable => None,
            _ => Some("x86-64"),
        }
    }

    /// What the CPU needs for this level, for reports of builds that were not run.
    pub fn requirement(self) -> &'static str {
        match self {
            Level::Portable => "nothing",
            Level::Avx2 => "x86-64 with AVX2",
            Level::Avx512 => "x86-64 with AVX2, AVX-512F, AVX-512VL and POPCNT",
        }
    }
}

/// An instruction set this CPU has, with its token: the run-time choice of the hot loops' build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// The portable build.
    Portable(Portable),
    /// The AVX2 build.
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    /// The AVX-512 build.
    #[cfg(target_arch = "x86_64")]
    Avx512(Avx512),
}

impl Default for Isa {
    /// [`Isa::detect`].
    fn default() -> Isa {
        Isa::detect()
    }
}

impl Isa {
    /// The widest instruction set this CPU has.
    pub fn detect() -> Isa {
        Level::ALL
            .into_iter()
            .rev()
            .find_map(Isa::at)
            .unwrap_or(Isa::Portable(Portable::new()))
    }

    /// The instruction set at `level`, if the CPU has it.
    pub fn at(level: Level) -> Option<Isa> {
        match level {
            Level::Portable => Some(Isa::Portable(Portable::new())),
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => Avx2::try_new().map(Isa::Avx2),
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => Avx512::try_new().map(Isa::Avx512),
            #[cfg(not(target_arch = "x86_64"))]
            _ => None,
        }
    }

    /// The widest instruction set the CPU has that is not wider than `cap`.
    pub fn capped(self, cap: Level) -> Isa {
        if self.level() <= cap {
            return self;
        }
        Level::ALL
            .into_iter()
            .rev()
            .filter(|&l| l <= cap)
            .find_map(Isa::at)
            .unwrap_or(Isa::Portable(Portable::new()))
    }

    /// [`Isa::capped`] for a cap someone asked for, and, when the CPU (whose widest set is
    /// `self`) cannot run `cap`, the warning to print: `this CPU has no AVX-512F; running avx2`.
    /// A cap narrower than the CPU is a choice, not a shortfall: no warning.
    pub fn capped_or_warn(self, cap: Level) -> (Isa, Option<String>) {
        let isa = self.capped(cap);
        let warning = (isa.level() < cap).then(|| {
            let missing = cap.missing_feature().unwrap_or(cap.requirement());
            cap_warning(missing, isa.level())
        });
        (isa, warning)
    }

    /// This instruction set's level.
    pub fn level(self) -> Level {
        match self {
            Isa::Portable(_) => Level::Portable,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(_) => Level::Avx2,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(_) => Level::Avx512,
        }
    }

    /// This instruction set's name.
    pub fn name(self) -> &'static str {
        self.level().name()
    }

    /// Runs `kernel` at this instruction set's full width (16 lanes on AVX-512).
    #[inline]
    pub fn run<K: Kernel>(self, kernel: K) -> K::Output {
        match self {
            Isa::Portable(s) => s.vectorize(kernel),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(s) => s.vectorize(kernel),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(s) => s.vectorize(kernel),
        }
    }

    /// Runs `kernel` with the 8-lane token of this instruction set (AVX-512 kernels built on
    /// blocks of 8: EVEX-encoded, 32 registers, compares into mask registers).
    #[inline]
    pub fn run8<K: Kernel>(self, kernel: K) -> K::Output {
        match self {
            Isa::Portable(s) => s.vectorize(kernel),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(s) => s.vectorize(kernel),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(s) => s.half().vectorize(kernel),
        }
    }

    /// Runs `kernel` with at most AVX2, for kernels without an AVX-512 build (one measured no
    /// faster than the AVX2 build: every AVX-512 CPU runs the AVX2 build).
    #[inline]
    pub fn run_avx2<K: Kernel>(self, kernel: K) -> K::Output {
        match self {
            Isa::Portable(s) => s.vectorize(kernel),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2(s) => s.vectorize(kernel),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512(s) => s.avx2().vectorize(kernel),
        }
    }
}

/// The warning of a cap the CPU cannot run: it lacks `missing`, and `running` runs instead.
fn cap_warning(missing: &str, running: Level) -> String {
    format!("this CPU has no {missing}; running {}", running.name())
}

/// 8 `f32` lanes in a plain array: the portable token's lane type, and the form lane code takes
/// where every instruction set runs the same element-wise loops (the compiler vectorizes them
/// for the instruction set of the function they are inlined into).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[repr(C, align(32))]
pub struct F32x8(pub [f32; LANES]);

impl F32x8 {
    /// All lanes equal to `x`.
    #[inline(always)]
    pub fn splat(x: f32) -> F32x8 {
        F32x8([x; LANES])
    }

    /// The first 8 values of `src` (panics if shorter).
    #[inline(always)]
    pub fn load(src: &[f32]) -> F32x8 {
        F32x8(src[..LANES].try_into().unwrap())
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

/// 8 `u32` lanes in a plain array (the portable token's integer lanes and masks).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(C, align(32))]
pub struct U32x8(pub [u32; LANES]);

/// The scalar form of [`Simd::sanitize`]: `x` where `0 < x < inf`, else `+0.0`.
#[inline(always)]
pub fn sanitize1(x: f32) -> f32 {
    if x.is_finite() && x > 0.0 {
        x
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builds_are_named_with_their_lanes() {
        assert_eq!(Level::Avx2.describe(), "avx2 (8 f32 lanes)");
        assert_eq!(Level::Avx512.describe(), "avx512 (16 f32 lanes)");
        assert_eq!(Level::Portable.describe(), "portable (8 f32 lanes)");
        for l in Level::ALL {
            assert_eq!(Level::named(l.name()), Some(l));
        }
        assert_eq!(Level::named("sse"), None);
        assert_eq!(Level::Portable.missing_feature(), None);
    }

    #[test]
    fn a_cap_above_the_cpu_warns_and_one_below_does_not() {
        // A CPU whose widest set is the portable one, asked for AVX-512: portable runs, and the
        // warning says so.
        let (isa, w) = Isa::Portable(Portable::new()).capped_or_warn(Level::Avx512);
        assert_eq!(isa.level(), Level::Portable);
        let w = w.expect("a warning");
        assert!(
            w.starts_with("this CPU has no ") && w.ends_with("; running portable"),
            "{w}"
        );
        // Asking for less than the CPU has (or exactly it) is a choice: no warning.
        let detected = Isa::detect();
        for cap in Level::ALL.into_iter().filter(|&l| l <= detected.level()) {
            let (isa, w) = detected.capped_or_warn(cap);
            assert_eq!((isa.level(), w), (cap.min(detected.level()), None));
        }
    }
}
