//! Every instruction-set build of every engine kernel against the kernel's scalar rule, bit for
//! bit: the rasterizer (every projection, (u, v) inverse, edge count and edge-lane width), the
//! patch shader (uniform and mixed groups, degree-(1, 1) and non-finite patches, 1 and 4 samples
//! per pixel, regions of widths that leave tails), the texture shader (every filter, magnified,
//! blended and clamped levels of detail) and the composition merge (ties, signed zeros, NaN,
//! unsigned ids).
//!
//! A test binary of its own without the libtest harness, so that what it prints is shown: a line
//! per kernel and instruction set, `ok` or `NOT RUN` with what this CPU lacks. A build this CPU
//! cannot run is reported, never passed silently; any mismatch panics (exit code 101).

#[path = "common/mod.rs"]
mod common;

use std::panic::{catch_unwind, AssertUnwindSafe};

use engine::composition::merge_records_into;
use engine::frame::FrameOptions;
use engine::raster::build_primitives;
use engine::raster::gbuffer::{RegionGBuffer, NO_POLYGON};
use engine::raster::geometry::plane;
use engine::raster::region::{rasterize, RegionGrid};
use engine::raster::setup::{clamp_uv, invert_bilinear, triangle_u, InverseKind, Prim, ONE};
use engine::raster::{sample_offsets, sample_spacing};
use engine::shading::{shade_region_with, shade_sample, Shader};
use glam::Vec3;
use lanes::{sanitize1, Isa, Level};
use reconstruction::texture::{
    lod_from_squares, Filter, Placement, RadiosityTexture, Sampler, TextureMemory, TextureSet,
};
use scene::Scene;

use common::{lane_test_scenes, GridSource};

/// Smallest Q = 1/w the rasterizer accepts (its documented clamp).
const MIN_Q: f32 = 1e-30;

fn main() {
    type Check = fn(Isa) -> usize;
    let checks: [(&str, Check, Level); 4] = [
        ("rasterizer kernels", check_raster, Level::Avx512),
        ("patch shader", check_patches, Level::Avx512),
        ("texture shader", check_texture, Level::Avx2),
        ("composition merge", check_merge, Level::Avx512),
    ];
    println!("\ninstruction-set builds against the scalar rules, bit for bit:");
    let mut failed = Vec::new();
    let mut not_run = Vec::new();
    for (name, check, widest) in checks {
        let mut line = format!("  {name:<20}");
        for level in Level::ALL {
            match Isa::at(level) {
                None => {
                    line += &format!("  {}: NOT RUN", level.name());
                    not_run.push(level);
                }
                Some(isa) => match catch_unwind(AssertUnwindSafe(|| check(isa))) {
                    Ok(n) if level > widest => {
                        line += &format!(
                            "  {}: ok ({n} checks, the {} build)",
                            level.name(),
                            widest.name()
                        )
                    }
                    Ok(n) => line += &format!("  {}: ok ({n} checks)", level.name()),
                    Err(_) => {
                        line += &format!("  {}: FAILED", level.name());
                        failed.push(format!("{name} ({})", level.name()));
                    }
                },
            }
        }
        println!("{line}");
    }
    not_run.sort();
    not_run.dedup();
    for level in not_run {
        println!(
            "  NOT RUN: the {} builds (this CPU lacks {})",
            level.name(),
            level.requirement()
        );
    }
    if !failed.is_empty() {
        panic!(
            "builds that differ from the scalar rule: {}",
            failed.join(", ")
        );
    }
}

/// Every test scene's frame rasterized region by region with `isa` and with the scalar rule, at
/// 1, 4 and 16 samples per pixel; returns the number of regions compared.
fn check_raster(isa: Isa) -> usize {
    let mut regions = 0;
    let mut kernels = std::collections::BTreeSet::new();
    for (name, scene) in lane_test_scenes() {
        for aa in [1, 4, 16] {
            let opts = FrameOptions {
                region: 64, // a narrower last column and row of regions
                aa: base::method::Aa::new("aa", aa).expect("a sample count"),
                ..FrameOptions::new(scene.width, scene.height)
            };
            let prims = build_primitives(&scene, &scene.camera, opts.width, opts.height, false)
                .expect("primitives");
            for p in &prims {
                kernels.insert((p.perspective, format!("{:?}", p.kind), p.n_edges > 4));
            }
            let offsets = sample_offsets(base::method::Aa::new("aa", aa).expect("a sample count"));
            let grid = RegionGrid::new(opts.width, opts.height, opts.region);
            for (r, bin) in grid.bin(prims.iter().enumerate()).iter().enumerate() {
                let (x0, y0, w, h) = grid.rect(r as u32);
                let mut got = RegionGBuffer::new(r as u32, x0, y0, w, h, aa);
                let mut want = got.clone();
                let (mut f_got, mut f_want) = (0, 0);
                for &k in bin {
                    f_got += rasterize(isa, &prims[k as usize], &mut got, offsets);
                    f_want += rasterize_scalar(&prims[k as usize], &mut want, offsets);
                }
                let at = format!("{name} aa {aa} region {r}");
                assert_eq!(f_got, f_want, "{at}: fragments");
                assert_eq!(bits(&got.depth), bits(&want.depth), "{at}: depth");
                assert_eq!(got.polygon, want.polygon, "{at}: polygon");
                assert_eq!(bits(&got.u), bits(&want.u), "{at}: u");
                assert_eq!(bits(&got.v), bits(&want.v), "{at}: v");
                regions += 1;
            }
        }
    }
    // Every kernel family ran: perspective or not, each inverse, clipped polygons.
    for persp in [false, true] {
        for kind in ["Linear", "Triangle", "General"] {
            assert!(
                kernels.iter().any(|k| k.0 == persp && k.1 == kind),
                "{persp} {kind}"
            );
        }
    }
    assert!(kernels.iter().any(|k| k.2), "no clipped primitive");
    regions
}

/// The rasterizer's scalar rule, one sample at a time: a sample is covered when every edge
/// function is >= 0 at it; its w, (s, t) and (u, v) are the per-pixel expressions re-based at
/// the region's origin, evaluated in f32 in the kernel's order; it is written when nearer, or as
/// near with a smaller polygon id.
fn rasterize_scalar(prim: &Prim, gb: &mut RegionGBuffer, offsets: &[(f32, f32)]) -> u64 {
    let local = |k: usize| {
        let p = prim.planes[k];
        (
            p.a as f32,
            p.b as f32,
            p.at(gb.x0 as f64, gb.y0 as f64) as f32,
        )
    };
    let (q, sa, sb, ta, tb) = (
        local(plane::Q),
        local(plane::SA),
        local(plane::SB),
        local(plane::TA),
        local(plane::TB),
    );
    let mut inv = prim.inverse;
    inv.triangle = false;
    let (stride, plane_len) = (gb.stride as usize, (gb.stride * gb.height) as usize);
    let mut fragments = 0;
    for (si, &(ox, oy)) in offsets.iter().enumerate() {
        let off = ((ox * ONE as f32) as i64, (oy * ONE as f32) as i64);
        let (fx, fy) = (off.0 as f32 / ONE as f32, off.1 as f32 / ONE as f32);
        for ly in 0..gb.height {
            for lx in 0..gb.width {
                let (sx, sy) = (
                    (gb.x0 + lx) as i64 * ONE + off.0,
                    (gb.y0 + ly) as i64 * ONE + off.1,
                );
                if !prim.edges[..prim.n_edges].iter().all(|e| e.at(sx, sy) >= 0) {
                    continue;
                }
                fragments += 1;
                let (x, yf) = (lx as f32 + fx, ly as f32 + fy);
                let qv = q.0 * x + (q.1 * yf + q.2);
                let w = if prim.perspective {
                    1.0 / qv.max(MIN_Q)
                } else {
                    qv
                };
                let i = si * plane_len + ly as usize * stride + lx as usize;
                let (d, p) = (gb.depth[i], gb.polygon[i]);
                if !((w < d) | ((w == d) & (prim.id < p))) {
                    continue;
                }
                let s = sa.0 * x + (sa.1 * yf + sa.2) + w * (sb.0 * x + (sb.1 * yf + sb.2));
                let t = ta.0 * x + (ta.1 * yf + ta.2) + w * (tb.0 * x + (tb.1 * yf + tb.2));
                let (u, v) = match prim.kind {
                    InverseKind::Linear => clamp_uv(s, t),
                    InverseKind::Triangle => clamp_uv(triangle_u(s, t), t),
                    InverseKind::General => invert_bilinear(&inv, s, t),
                };
                (gb.depth[i], gb.polygon[i], gb.u[i], gb.v[i]) = (w, prim.id, u, v);
            }
        }
    }
    fragments
}

/// The regions of a frame of `scene` (one renderer), rasterized with the scalar rule.
fn regions_of(scene: &Scene, region: u32, aa: u32) -> Vec<RegionGBuffer> {
    let prims =
        build_primitives(scene, &scene.camera, scene.width, scene.height, false).expect("prims");
    let offsets = sample_offsets(base::method::Aa::new("aa", aa).expect("a sample count"));
    let grid = RegionGrid::new(scene.width, scene.height, region);
    let mut out = Vec::new();
    for (r, bin) in grid.bin(prims.iter().enumerate()).iter().enumerate() {
        let (x0, y0, w, h) = grid.rect(r as u32);
        let mut gb = RegionGBuffer::new(r as u32, x0, y0, w, h, aa);
        for &k in bin {
            rasterize_scalar(&prims[k as usize], &mut gb, offsets);
        }
        out.push(gb);
    }
    out
}

/// The deferred pass's scalar rule for one region: per pixel, its samples' values (`value` of
/// the sample, the background where none is seen) summed in plane order, multiplied by 1/N for N
/// > 1 samples, each channel through the image's clamp; written `pitch` apart.
fn resolve_scalar(
    gb: &RegionGBuffer,
    bg: Vec3,
    pitch: usize,
    value: impl Fn(usize, usize, usize) -> Vec3,
) -> Vec<Vec3> {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let plane_len = stride * h;
    let inv = 1.0 / gb.samples as f32;
    let mut out = vec![Vec3::splat(-7.0); (h - 1) * pitch + w];
    for y in 0..h {
        for x in 0..w {
            let mut acc = Vec3::ZERO;
            for si in 0..gb.samples as usize {
                let i = si * plane_len + y * stride + x;
                let c = if gb.polygon[i] == NO_POLYGON {
                    bg
                } else {
                    value(i, x, y)
                };
                acc = if si == 0 { c } else { acc + c };
            }
            let c = if gb.samples == 1 { acc } else { acc * inv };
            out[y * pitch + x] = Vec3::from_array(c.to_array().map(sanitize1));
        }
    }
    out
}

/// The patch shader against [`shade_sample`] and the box filter, on every test scene's regions
/// with patches that change inside polygons (uniform and mixed groups), degree-(1, 1) and
/// non-finite patches, 1 and 4 samples, regions 64 and 24 wide (16-lane groups and 8-lane tails).
fn check_patches(isa: Isa) -> usize {
    let bg = Vec3::new(0.25, -0.5, 3.0);
    let mut checked = 0;
    for (name, scene) in lane_test_scenes() {
        let source = GridSource::new(scene.polygons.len() as u32, 3).with_awkward_patches();
        for (region, aa) in [(64, 1), (24, 4)] {
            for mut gb in regions_of(&scene, region, aa) {
                gb.assign_patches(&source);
                let pitch = gb.width as usize + 5;
                let want = resolve_scalar(&gb, bg, pitch, |i, _, _| {
                    Vec3::from_array(shade_sample(
                        &gb.table[gb.slot[i] as usize],
                        gb.u[i],
                        gb.v[i],
                    ))
                });
                let mut got = vec![Vec3::splat(-7.0); want.len()];
                let shader = Shader::Patches(&source);
                shade_region_with(isa, &shader, &gb, bg, &mut got, pitch);
                let at = format!("{name} region {} aa {aa}", gb.region);
                assert_same_pixels(&got, &want, pitch, gb.width as usize, &at);
                checked += 1;
            }
        }
    }
    checked
}

/// Panics naming the first pixel whose bits differ.
fn assert_same_pixels(got: &[Vec3], want: &[Vec3], pitch: usize, width: usize, at: &str) {
    let first = (0..want.len())
        .filter(|i| i % pitch < width)
        .find(|&i| got[i].to_array().map(f32::to_bits) != want[i].to_array().map(f32::to_bits));
    if let Some(i) = first {
        panic!(
            "{at}: pixel ({}, {}) is {} instead of {}",
            i % pitch,
            i / pitch,
            got[i],
            want[i]
        );
    }
}

/// Screen derivatives of (u, v) at sample `i` (column `x`, row `y`): forward differences where
/// the next sample shows the same polygon, else backward, else 0 (the texture pass's rule).
fn uv_derivatives(gb: &RegionGBuffer, i: usize, x: usize, y: usize) -> [f32; 4] {
    let (w, h, stride) = (gb.width as usize, gb.height as usize, gb.stride as usize);
    let p = gb.polygon[i];
    let diff = |a: usize, b: usize| [gb.u[b] - gb.u[a], gb.v[b] - gb.v[a]];
    let dx = if x + 1 < w && gb.polygon[i + 1] == p {
        diff(i, i + 1)
    } else if x > 0 && gb.polygon[i - 1] == p {
        diff(i - 1, i)
    } else {
        [0.0; 2]
    };
    let dy = if y + 1 < h && gb.polygon[i + stride] == p {
        diff(i, i + stride)
    } else if y > 0 && gb.polygon[i - stride] == p {
        diff(i - stride, i)
    } else {
        [0.0; 2]
    };
    [dx[0], dx[1], dy[0], dy[1]]
}

/// The texture shader against [`Sampler::sample`] at the level of detail of the finite
/// differences, for every filter, textures of 4 to 256 texels (magnified and minified), polygons
/// without a texture.
fn check_texture(isa: Isa) -> usize {
    let bg = Vec3::new(0.25, -0.5, 3.0);
    let mut checked = 0;
    for (name, scene) in lane_test_scenes() {
        let n_tex = scene.polygons.len() - 3;
        let sides: Vec<u32> = (0..n_tex).map(|p| [4, 256, 16, 64][p % 4]).collect();
        let textures = sides
            .iter()
            .enumerate()
            .map(|(p, &n)| {
                let t = (0..n * n)
                    .map(|i| {
                        let h = (i ^ ((p as u32) << 20)).wrapping_mul(2654435761) >> 8;
                        Vec3::new(
                            (h % 97) as f32 * 0.01,
                            (h % 89) as f32 * 0.02 - 0.3,
                            (h % 83) as f32 * 0.5,
                        )
                    })
                    .collect();
                if p % 2 == 0 {
                    return RadiosityTexture::from_texels(n, n, t).expect("a texture");
                }
                // Every other texture with a 2-texel gutter of other values: edge lookups read
                // it instead of clamped copies of the edge texels.
                RadiosityTexture::from_fn(n, Placement::Centre, 2, |u, v| {
                    let h = (u.to_bits() ^ v.to_bits().rotate_left(13)).wrapping_mul(2654435761);
                    Vec3::new((h >> 20) as f32 * 1e-3, (h % 89) as f32 * 0.02 - 0.3, 0.5)
                })
                .expect("a texture with a gutter")
            })
            .collect();
        let set = TextureSet {
            textures,
            memory: TextureMemory::of_sides(&sides, 0),
            placement: Placement::Centre,
            gutter: 0,
        };
        for filter in [
            Filter::Nearest,
            Filter::Bilinear,
            Filter::MITCHELL,
            Filter::CATMULL_ROM,
        ] {
            let sampler = Sampler::new(filter);
            for gb in regions_of(&scene, 64, 4) {
                let pitch = gb.width as usize + 5;
                let want = resolve_scalar(&gb, bg, pitch, |i, x, y| {
                    let Some(tex) = set.textures.get(gb.polygon[i] as usize) else {
                        return Vec3::ZERO;
                    };
                    let [ux, vx, uy, vy] = uv_derivatives(&gb, i, x, y);
                    let spacing = sample_spacing(gb.samples);
                    let (tw, th) = (tex.width as f32 * spacing, tex.height as f32 * spacing);
                    let lx2 = (ux * tw) * (ux * tw) + (vx * th) * (vx * th);
                    let ly2 = (uy * tw) * (uy * tw) + (vy * th) * (vy * th);
                    let lod = lod_from_squares(lx2, ly2, tex.last_level());
                    sampler.sample(tex, lod, gb.u[i], gb.v[i])
                });
                let mut got = vec![Vec3::splat(-7.0); want.len()];
                let shader = Shader::Texture {
                    set: &set,
                    filter,
                    anisotropy: 1,
                };
                shade_region_with(isa, &shader, &gb, bg, &mut got, pitch);
                let at = format!("{name} {filter:?} region {}", gb.region);
                assert_same_pixels(&got, &want, pitch, gb.width as usize, &at);
                checked += 1;
            }
        }
    }
    checked
}

/// The records merge against its rule (nearer, or as near with a smaller id; ordered float
/// comparisons, unsigned ids), on widths whose buffers end with whole 16-lane steps, 8-lane tails
/// or neither.
fn check_merge(isa: Isa) -> usize {
    const DEPTHS: [f32; 6] = [1.0, 2.0, -0.0, 0.0, f32::INFINITY, f32::NAN];
    const IDS: [u32; 4] = [3, 7, 0x8000_0001, NO_POLYGON];
    let mut seed = base::rng::Rng::new(11);
    let mut rnd = |n: usize| seed.below(n as u32) as usize;
    let mut checked = 0;
    for width in [8, 16, 24, 40] {
        for _ in 0..100 {
            let mut make = || {
                let mut g = RegionGBuffer::new(0, 0, 0, width, 3, 1);
                for i in 0..g.len() {
                    g.depth[i] = DEPTHS[rnd(DEPTHS.len())];
                    g.polygon[i] = IDS[rnd(IDS.len())];
                    g.u[i] = rnd(8) as f32 * 0.125;
                    g.v[i] = rnd(8) as f32 * 0.125;
                }
                g
            };
            let (mut got, part) = (make(), make());
            let mut want = got.clone();
            for i in 0..want.len() {
                let (d, od) = (part.depth[i], want.depth[i]);
                if d < od || (d == od && part.polygon[i] < want.polygon[i]) {
                    want.depth[i] = d;
                    want.polygon[i] = part.polygon[i];
                    want.u[i] = part.u[i];
                    want.v[i] = part.v[i];
                }
            }
            merge_records_into(isa, &mut got, &part);
            assert_eq!(bits(&got.depth), bits(&want.depth), "width {width}");
            assert_eq!(got.polygon, want.polygon, "width {width}");
            assert_eq!(bits(&got.u), bits(&want.u), "width {width}");
            assert_eq!(bits(&got.v), bits(&want.v), "width {width}");
            checked += 1;
        }
    }
    checked
}

fn bits(x: &[f32]) -> Vec<u32> {
    x.iter().map(|x| x.to_bits()).collect()
}
