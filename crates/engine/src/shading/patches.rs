//! The patch shader: every visible sample evaluates the bicubic patch its region's table holds
//! for it (the direct method's RRPs), or for the Gouraud mesh its triangle's degree-(1, 1) patch,
//! read by polygon from the mesh's compact patches ([`Source::Gouraud`]: no table to fill, which
//! was a fifth of a mesh frame's work).
//!
//! Neighbouring samples nearly always share one patch, so each group of `S::LANES` samples of a
//! row (8, or 16 on AVX-512) is evaluated with the patch's 48 coefficients broadcast over the
//! lanes (Horner in s for each of the 4 rows, then Horner in t: 15 multiply-adds per channel per
//! lane); groups that mix patches evaluate one broadcast per distinct patch and merge through
//! masks. Every lane performs the operations of the scalar rule [`shade_sample`] in its order
//! (separate IEEE multiplies and adds, never fused), so neither the group a sample falls in nor
//! the instruction set changes its bits.
//!
//! The kernel is written once over [`Simd`]; the explicit token operations keep the lanes across
//! samples (left to itself, LLVM's SLP vectorizer vectorized the four row polynomials across rows,
//! 4-wide with shuffles, and the pass ran at a third of its arithmetic rate). The counters count
//! blocks of 8 whatever the width (uniform: 8 samples of one patch; mixed: any other block that
//! sees a polygon), so they do not depend on the CPU either.

use glam::Vec3;
use lanes::{Isa, Kernel, Simd, LANES};
use reconstruction::mesh::GouraudPatch;
use reconstruction::PatchCoeffs;

use super::{RowOut, Rows, ShadeCounts};
use crate::raster::gbuffer::{RegionGBuffer, NO_POLYGON};

/// The scalar rule of the patch shader: patch `p` at (u, v), with (s, t) = ((u - u0) w⁻¹,
/// (v - v0) w⁻¹) unclamped and Horner's scheme per channel, rows in s, then the rows in t; for a
/// patch flagged [`PatchCoeffs::bilinear`], the degree-(1, 1) form `(k5 s + k4) t + (k1 s + k0)`
/// (the same bits as Horner's scheme for coefficients that pass
/// [`PatchCoeffs::bilinear_exact`]). Every build of the deferred pass reproduces it bit for bit.
pub fn shade_sample(p: &PatchCoeffs, u: f32, v: f32) -> [f32; 3] {
    let s = (u - p.u0) * p.inv_w;
    let t = (v - p.v0) * p.inv_w;
    p.c.map(|k| {
        if p.bilinear {
            return (k[5] * s + k[4]) * t + (k[1] * s + k[0]);
        }
        let r = |j: usize| ((k[4 * j + 3] * s + k[4 * j + 2]) * s + k[4 * j + 1]) * s + k[4 * j];
        ((r(3) * t + r(2)) * t + r(1)) * t + r(0)
    })
}

/// `a b + d`: the separate IEEE multiply and add (never fused).
#[inline(always)]
fn ma<S: Simd>(simd: S, a: S::F, b: S::F, d: S::F) -> S::F {
    simd.add(simd.mul(a, b), d)
}

/// Row `j` of a channel's coefficients in s, by Horner: ((k3 s + k2) s + k1) s + k0.
#[inline(always)]
fn row<S: Simd>(simd: S, k: &[f32; 16], j: usize, s: S::F) -> S::F {
    let [k0, k1, k2, k3] = [k[4 * j], k[4 * j + 1], k[4 * j + 2], k[4 * j + 3]];
    let r = ma(simd, simd.splat(k3), s, simd.splat(k2));
    let r = ma(simd, r, s, simd.splat(k1));
    ma(simd, r, s, simd.splat(k0))
}

/// One patch at the lanes of (u, v): the local (s, t), then per channel the rows in s and the
/// rows in t (or the degree-(1, 1) form `(k5 s + k4) t + (k1 s + k0)` of a flagged patch, 6
/// operations per channel instead of 30: the operations Horner's scheme is left with once its
/// products with zero coefficients are dropped, see [`PatchCoeffs::bilinear_exact`]).
///
/// (u, v) are loaded here, from the first `S::LANES` values of `u` and `v`, rather than held in
/// registers by the caller across its loop over patches: with 16 lanes that kept the patch's
/// rows from fitting in the registers.
#[inline(always)]
pub(crate) fn eval_patch<S: Simd>(simd: S, p: &PatchCoeffs, u: &[f32], v: &[f32]) -> [S::F; 3] {
    let w = simd.splat(p.inv_w);
    let s = simd.mul(simd.sub(simd.load(u), simd.splat(p.u0)), w);
    let t = simd.mul(simd.sub(simd.load(v), simd.splat(p.v0)), w);
    let [k0, k1, k2] = &p.c;
    if p.bilinear {
        return [
            bilinear(simd, k0, s, t),
            bilinear(simd, k1, s, t),
            bilinear(simd, k2, s, t),
        ];
    }
    [
        channel(simd, k0, s, t),
        channel(simd, k1, s, t),
        channel(simd, k2, s, t),
    ]
}

/// One channel by Horner's scheme: the rows in s, then the rows in t.
#[inline(always)]
fn channel<S: Simd>(simd: S, k: &[f32; 16], s: S::F, t: S::F) -> S::F {
    let (r3, r2) = (row(simd, k, 3, s), row(simd, k, 2, s));
    let (r1, r0) = (row(simd, k, 1, s), row(simd, k, 0, s));
    ma(simd, ma(simd, ma(simd, r3, t, r2), t, r1), t, r0)
}

/// The degree-(1, 1) form of a channel: `(k5 s + k4) t + (k1 s + k0)`.
#[inline(always)]
fn bilinear<S: Simd>(simd: S, k: &[f32; 16], s: S::F, t: S::F) -> S::F {
    let r1 = ma(simd, simd.splat(k[5]), s, simd.splat(k[4]));
    let r0 = ma(simd, simd.splat(k[1]), s, simd.splat(k[0]));
    ma(simd, r1, t, r0)
}

/// Where a sample's patch comes from.
#[derive(Clone, Copy)]
pub(crate) enum Source<'a> {
    /// The region's patch table, at the sample's slot.
    Table,
    /// The Gouraud patch of the sample's polygon (`Shader::Gouraud`).
    Gouraud(&'a [GouraudPatch]),
}

/// The Gouraud patch `g` at the lanes of (u, v): the bits [`eval_patch`] gives for
/// [`GouraudPatch::patch`], which is always flagged bilinear, so evaluated as
/// `(k5 s + k4) t + (k1 s + k0)` from the four coefficients alone. That patch's local (s, t)
/// are `(u - 0) 1` and `(v - 0) 1`, which are u and v themselves (x - 0 and x 1 are x for
/// every number x, -0 included, and a NaN stays a NaN, which the resolve clears to +0), so the
/// lanes take (u, v) as they are. A polygon without a patch is black.
#[inline(always)]
fn eval_gouraud<S: Simd>(simd: S, g: Option<&GouraudPatch>, u: &[f32], v: &[f32]) -> [S::F; 3] {
    let zero = simd.splat(0.0);
    let Some(g) = g else {
        return [zero; 3];
    };
    let (s, t) = (simd.load(u), simd.load(v));
    // A loop, not `map` with a closure: a closure is compiled without the kernel's target
    // features unless it is inlined, and its token operations then become calls.
    let mut out = [zero; 3];
    for ch in 0..3 {
        let [k0, k1, k4, k5] = g.coefficients()[ch];
        let r1 = ma(simd, simd.splat(k5), s, simd.splat(k4));
        let r0 = ma(simd, simd.splat(k1), s, simd.splat(k0));
        out[ch] = ma(simd, r1, t, r0);
    }
    out
}

/// Shades the `S::LANES` samples of one row from plane index `i0`: the background where no
/// polygon is seen, and one broadcast evaluation per distinct patch (by table slot, or by
/// polygon for [`Source::Gouraud`]), merged through lane masks (the whole group at once when
/// one patch covers it). Counts each block of 8 as uniform (8 samples of one patch) or mixed
/// (any other block that sees a polygon).
#[inline(always)]
fn shade_group<S: Simd>(
    simd: S,
    source: Source<'_>,
    gb: &RegionGBuffer,
    i0: usize,
    bg: [f32; 3],
    counts: &mut ShadeCounts,
) -> [S::F; 3] {
    let full = u32::MAX >> (32 - S::LANES);
    let lanes = i0..i0 + S::LANES;
    let polys = &gb.polygon[lanes.clone()];
    // The key that groups lanes: one patch per slot, or per polygon for the Gouraud mesh.
    let slots = match source {
        Source::Table => &gb.slot[lanes.clone()],
        Source::Gouraud(_) => polys,
    };
    let (u, v) = (&gb.u[lanes.clone()], &gb.v[lanes]);
    let p = simd.load_u(polys);
    let slot_lanes = simd.load_u(slots);
    let empty = simd.bits(simd.eq_u(p, simd.splat_u(NO_POLYGON)));
    let mut pending = !empty & full;
    counts.samples_shaded += pending.count_ones() as u64;
    let mut out = [simd.splat(bg[0]), simd.splat(bg[1]), simd.splat(bg[2])];
    let blocks = S::LANES / LANES;
    let mut seen = 0;
    for b in 0..blocks {
        seen += ((pending >> (LANES * b)) & 0xff != 0) as u32;
    }
    let mut whole = 0u32;
    while pending != 0 {
        let slot = slots[pending.trailing_zeros() as usize];
        let m = simd.bits(simd.eq_u(slot_lanes, simd.splat_u(slot))) & pending;
        pending &= !m;
        for b in 0..blocks {
            whole |= (((m >> (LANES * b)) & 0xff == 0xff) as u32) << b;
        }
        let c = match source {
            Source::Table => eval_patch(simd, &gb.table[slot as usize], u, v),
            Source::Gouraud(patches) => eval_gouraud(simd, patches.get(slot as usize), u, v),
        };
        if m == full {
            out = c;
        } else {
            let mask = simd.mask(m);
            for ch in 0..3 {
                out[ch] = simd.select(mask, c[ch], out[ch]);
            }
        }
    }
    let uniform = whole.count_ones();
    counts.uniform_blocks += uniform as u64;
    counts.mixed_blocks += (seen - uniform) as u64;
    out
}

/// Shades one composited region into `rows` (`gb.width` x `gb.height` pixels) with the
/// instruction set `isa` at its full width, each sample's patch taken from `source`; the image
/// and the counters do not depend on the instruction set.
pub(crate) fn shade_region_rows(
    isa: Isa,
    source: Source<'_>,
    gb: &RegionGBuffer,
    background: Vec3,
    rows: &mut Rows<'_>,
) -> ShadeCounts {
    isa.run(PatchPass {
        source,
        gb,
        background,
        rows,
    })
}

/// The patch pass over one region, as a kernel.
struct PatchPass<'a, 'r> {
    source: Source<'a>,
    gb: &'a RegionGBuffer,
    background: Vec3,
    rows: &'a mut Rows<'r>,
}

impl Kernel for PatchPass<'_, '_> {
    type Output = ShadeCounts;

    #[inline(always)]
    fn run<S: Simd>(self, simd: S) -> ShadeCounts {
        let PatchPass {
            source,
            gb,
            background,
            rows: dst,
        } = self;
        let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
        let plane = stride * h;
        let mut rows = RowOut::new(gb.samples, stride);
        let mut counts = ShadeCounts::default();
        let half = simd.half();
        let bg = background.to_array();
        for y in 0..h {
            let out_row = dst.row(y);
            for si in 0..gb.samples as usize {
                let row = si * plane + y * stride;
                let mut bx = 0;
                // Whole groups at full width (a 16-lane build), else blocks of 8. Padding lanes
                // beyond the region's width hold NO_POLYGON and are never written out.
                while bx < w {
                    if S::LANES > LANES && bx + S::LANES <= w {
                        let c = shade_group(simd, source, gb, row + bx, bg, &mut counts);
                        rows.block_whole(simd, out_row, bx, si, &c);
                        bx += S::LANES;
                        continue;
                    }
                    let c = shade_group(half, source, gb, row + bx, bg, &mut counts);
                    rows.block(half, out_row, bx, si, &c);
                    bx += LANES;
                }
            }
            // Box filter: equal weights over the pixel's samples, then the image's clamp.
            rows.finish_row(half, out_row);
        }
        counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// [`eval_patch`] over `S::LANES` lanes of (u, v) (16 given, the first `S::LANES` used), as
    /// a kernel: one result per lane.
    struct Eval<'a> {
        p: &'a PatchCoeffs,
        u: [f32; 16],
        v: [f32; 16],
    }

    impl Kernel for Eval<'_> {
        type Output = Vec<[f32; 3]>;
        fn run<S: Simd>(self, simd: S) -> Vec<[f32; 3]> {
            let c = eval_patch(simd, self.p, &self.u, &self.v);
            let mut out = vec![[0.0; 3]; S::LANES];
            let mut tmp = [0.0f32; 16];
            for ch in 0..3 {
                simd.store(c[ch], &mut tmp);
                for l in 0..S::LANES {
                    out[l][ch] = tmp[l];
                }
            }
            out
        }
    }

    /// Every instruction set this CPU has (the engine's `isa_variants` test reports those it
    /// lacks).
    fn isas() -> Vec<Isa> {
        lanes::Level::ALL.into_iter().filter_map(Isa::at).collect()
    }

    #[test]
    fn horner_matches_the_power_basis_sum() {
        let p = poly_patch();
        for &(u, v) in &[(0.25, 0.5), (0.3, 0.6), (0.5, 0.75), (0.41, 0.52)] {
            let (s, t) = ((u - 0.25) * 4.0f64, (v - 0.5) * 4.0f64);
            let got = shade_sample(&p, u as f32, v as f32);
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

    #[test]
    fn every_build_evaluates_the_scalar_rule_bit_for_bit() {
        let p = poly_patch();
        let u: [f32; 16] = std::array::from_fn(|l| 0.25 + l as f32 * 0.013);
        let v: [f32; 16] = std::array::from_fn(|l| 0.74 - l as f32 * 0.011);
        for isa in isas() {
            let got = isa.run(Eval { p: &p, u, v });
            for (l, g) in got.iter().enumerate() {
                let want = shade_sample(&p, u[l], v[l]);
                assert_eq!(
                    g.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "{}",
                    isa.name()
                );
            }
        }
    }

    /// Degree-(1, 1) coefficients with awkward values: zeros of either sign, subnormals,
    /// opposite values that cancel, large magnitudes.
    fn bilinear_coeffs(seed: u64) -> [[f32; 16]; 3] {
        const VALUES: [f32; 10] = [0.0, -0.0, 1.0, -1.0, 0.3, -0.7, 1e-40, -3e38, 3e38, 2.5];
        let mut x = base::rng::Rng::new(seed);
        let mut next = || VALUES[x.below(VALUES.len() as u32) as usize];
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
        let u8 = [0.0, 0.25, 0.5, 0.5, 0.75, 1.0, 0.1, 0.9];
        let v8 = [0.5, 0.0, 1.0, 0.5, 0.3, 0.5, 0.99, 0.0];
        let u: [f32; 16] = std::array::from_fn(|l| u8[l % 8]);
        let v: [f32; 16] = std::array::from_fn(|l| v8[l % 8]);
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
            let mut full = p;
            full.bilinear = false;
            for isa in isas() {
                let fast = isa.run(Eval { p: &p, u, v });
                let want = isa.run(Eval { p: &full, u, v });
                for (l, (f, w)) in fast.iter().zip(&want).enumerate() {
                    assert_eq!(
                        f.map(f32::to_bits),
                        w.map(f32::to_bits),
                        "seed {seed} lane {l} {}",
                        isa.name()
                    );
                    let scalar = shade_sample(&full, u[l], v[l]);
                    assert_eq!(w.map(f32::to_bits), scalar.map(f32::to_bits));
                }
            }
        }
        assert!(flagged > 1000, "{flagged} flagged");
    }

    /// The Gouraud shader reads each sample's patch by polygon; the patch shader reads the
    /// region's table, filled here as the rasterizer fills it for the mesh. Both give the same
    /// pixels, bit for bit, for every instruction set: small polygons (several per group),
    /// awkward colours (zeros of both signs, subnormals, large values), (u, v) beyond [0, 1]
    /// and NaN, holes, 4 samples per pixel and a width that is not a whole number of groups; a
    /// polygon without a patch is black.
    #[test]
    fn the_gouraud_shader_gives_the_patch_tables_bits() {
        use crate::raster::gbuffer::RegionGBuffer;
        use reconstruction::PatchSource;
        const VALUES: [f32; 8] = [0.0, -0.0, 0.5, 1e-40, 3.0e30, 0.125, 2.0, 0.75];
        let mut rng = base::rng::Rng::new(11);
        let mut pick = || VALUES[rng.below(VALUES.len() as u32) as usize];
        let patches: Vec<GouraudPatch> = (0..97)
            .map(|_| GouraudPatch::of(std::array::from_fn(|_| Vec3::new(pick(), pick(), pick()))))
            .collect();
        struct Mesh<'a>(&'a [GouraudPatch]);
        impl PatchSource for Mesh<'_> {
            fn locate(&self, polygon: u32, _: f32, _: f32) -> u32 {
                polygon
            }
            fn patch(&self, id: u32) -> PatchCoeffs {
                self.0[id as usize].patch()
            }
        }
        let (w, h, spp) = (45u32, 7u32, 4u32);
        let mut gb = RegionGBuffer::new(0, 0, 0, w, h, spp);
        let stride = gb.stride as usize;
        let mut x = base::rng::Rng::new(5);
        for i in 0..gb.len() {
            let (col, row) = (i % stride, i / stride);
            if col >= w as usize || x.below(9) == 0 {
                continue;
            }
            // Runs of 1-4 samples per polygon along a row.
            gb.polygon[i] = ((col / (1 + row % 4)) * 13 + row * 7) as u32 % 97;
            gb.u[i] = x.next_f64() as f32 * 1.2 - 0.1;
            gb.v[i] = x.next_f64() as f32 * 1.2 - 0.1;
            gb.depth[i] = 1.0;
        }
        gb.u[3] = f32::NAN;
        let mut table_gb = gb.clone();
        table_gb.assign_patches(&Mesh(&patches));
        let bg = Vec3::new(0.5, 0.25, 2.0);
        for isa in isas() {
            let shade = |shader: &super::super::Shader<'_>, gb: &RegionGBuffer| {
                let mut px = vec![Vec3::splat(-1.0); (w * h) as usize];
                super::super::shade_region_with(isa, shader, gb, bg, &mut px, w as usize);
                px
            };
            let want = shade(&super::super::Shader::Patches(&Mesh(&patches)), &table_gb);
            let got = shade(&super::super::Shader::Gouraud(&patches), &gb);
            for (k, (g, w)) in got.iter().zip(&want).enumerate() {
                let bits = |v: &Vec3| v.to_array().map(f32::to_bits);
                assert_eq!(bits(g), bits(w), "pixel {k}: {g} vs {w} ({})", isa.name());
            }
            // Without patches every polygon is black; the background stays.
            let black = shade(&super::super::Shader::Gouraud(&[]), &gb);
            assert!(black
                .iter()
                .all(|p| *p == Vec3::ZERO || *p == bg || p.cmplt(bg).all()));
        }
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
}
