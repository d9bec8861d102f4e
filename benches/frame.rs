//! Frame benchmark: frame time of the direct method at 512, 1024 and 2048 pixels square
//! for a code-built room of a few hundred quads seen from inside (every pixel covered), frame time
//! against polygon count at 1024, and the deferred pass alone in Mpixel/s: RRPs (direct) and the
//! texture filters on the same G-buffers.
//!
//! Run briefly: `cargo bench -p pixelflow-bench --profile release --bench frame --
//! --warm-up-time 1 --measurement-time 3` (`--profile release`: see the package's library doc).

// `criterion_group!` defines a public function it cannot document.
#![allow(missing_docs)]

use base::method::Method;
use criterion::{criterion_group, BatchSize, BenchmarkId, Criterion, Throughput};
use engine::composition::{composite_in_place, merge_records_in_place, MergeScratch};
use engine::frame::{render_patches as render_frame, FrameContext, FrameOptions, FrameStats};
use engine::raster::gbuffer::{PatchScratch, RegionGBuffer};
use engine::raster::region::{rasterize, RegionGrid};
use engine::raster::{
    bin_round_robin_into, build_primitives, build_primitives_into, rasterize_region_into,
    sample_offsets,
};
use engine::shading::{shade_regions, Rows, Shader};
use glam::{DVec3, Vec3};
use lanes::{Isa, Level};
use rayon::prelude::*;
use reconstruction::texture::{Filter, Placement, RadiosityTexture, TextureMemory, TextureSet};
use reconstruction::{PatchCoeffs, PatchSource};
use scene::{Camera, Material, Polygon, Projection, Scene};

/// A 10 x 4 x 10 room, each wall cut into `n` x `n` quads, with two boxes inside.
fn room(n: usize) -> Scene {
    let mut polys = Vec::new();
    let mut wall = |o: DVec3, a: DVec3, b: DVec3| {
        for j in 0..n {
            for i in 0..n {
                let p = |di: usize, dj: usize| {
                    o + a * ((i + di) as f64 / n as f64) + b * ((j + dj) as f64 / n as f64)
                };
                polys.push(Polygon::quad([p(0, 0), p(1, 0), p(1, 1), p(0, 1)], 0, 0).unwrap());
            }
        }
    };
    let (x, y, z) = (DVec3::X * 10.0, DVec3::Y * 4.0, DVec3::Z * 10.0);
    wall(DVec3::ZERO, x, z); // floor
    wall(y, z, x); // ceiling
    wall(DVec3::ZERO, y, x); // back
    wall(z, x, y); // front
    wall(DVec3::ZERO, z, y); // left
    wall(x, y, z); // right
    for (c, s) in [
        (DVec3::new(3.0, 0.0, 3.0), 1.5),
        (DVec3::new(6.5, 0.0, 5.0), 1.0),
    ] {
        let (a, b, h) = (DVec3::X * s, DVec3::Z * s, DVec3::Y * s * 1.5);
        for (o, u, v) in [
            (c, a, h),
            (c + a, b, h),
            (c + a + b, -a, h),
            (c + b, -b, h),
            (c + h, b, a),
        ] {
            polys.push(Polygon::quad([o, o + u, o + u + v, o + v], 0, 0).unwrap());
        }
    }
    let camera = Camera {
        eye: DVec3::new(5.0, 2.0, 9.5),
        look_at: DVec3::new(5.0, 1.5, 0.0),
        up: DVec3::Y,
        projection: Projection::Perspective { fov_y_deg: 60.0 },
    };
    let white = Material {
        name: "white".into(),
        reflectance: DVec3::splat(0.7),
        emission: DVec3::ZERO,
    };
    Scene::new(camera, 1024, 1024, vec![white], polys)
}

/// 4 x 4 bicubic patches per polygon.
struct Grid {
    patches: Vec<PatchCoeffs>,
}

impl Grid {
    fn new(polygons: usize) -> Grid {
        let mut patches = Vec::new();
        for p in 0..polygons {
            for k in 0..16u32 {
                let mut c = [[0.0f32; 16]; 3];
                for (ch, row) in c.iter_mut().enumerate() {
                    for (i, x) in row.iter_mut().enumerate() {
                        *x = ((p as u32 * 7 + k * 5 + ch as u32 * 3 + i as u32) % 9) as f32 * 0.05;
                    }
                }
                patches.push(PatchCoeffs {
                    c,
                    u0: (k % 4) as f32 / 4.0,
                    v0: (k / 4) as f32 / 4.0,
                    inv_w: 4.0,
                    bilinear: false,
                });
            }
        }
        Grid { patches }
    }
}

impl PatchSource for Grid {
    fn locate(&self, polygon: u32, u: f32, v: f32) -> u32 {
        let i = ((u * 4.0) as u32).min(3);
        let j = ((v * 4.0) as u32).min(3);
        polygon * 16 + j * 4 + i
    }
    fn patch(&self, id: u32) -> PatchCoeffs {
        self.patches[id as usize]
    }
    // u * 4 is exact, so the quarter cells are exactly where `locate` answers.
    fn cell(&self, id: u32) -> Option<[f32; 4]> {
        let p = &self.patches[id as usize];
        Some([p.u0, p.u0 + 0.25, p.v0, p.v0 + 0.25])
    }
}

fn frame(c: &mut Criterion) {
    let scene = room(8);
    let source = Grid::new(scene.polygons.len());
    let mut g = c.benchmark_group("frame");
    g.sample_size(10);
    for size in [512u32, 1024, 2048] {
        let opts = FrameOptions::new(size, size);
        let f = render_frame(&scene, &scene.camera, &source, &opts).unwrap();
        eprintln!("frame {size}: {}", serde_json_like(&f.stats));
        g.throughput(Throughput::Elements((size * size) as u64));
        let name = format!("room-{}", scene.polygons.len());
        // Warm: one frame context for every frame, as a walkthrough renders.
        let mut ctx = FrameContext::new();
        let shader = Shader::Patches(&source);
        g.bench_with_input(BenchmarkId::new(&name, size), &opts, |b, o| {
            b.iter(|| {
                ctx.render(&scene, &scene.camera, &shader, Method::Direct, o)
                    .unwrap()
            })
        });
        // Cold: a new context per frame (allocation and first touch of every buffer).
        g.bench_with_input(
            BenchmarkId::new(format!("{name}-cold"), size),
            &opts,
            |b, o| b.iter(|| render_frame(&scene, &scene.camera, &source, o).unwrap()),
        );
        for r in [2u32, 3] {
            let o = FrameOptions {
                renderers: r,
                ..opts.clone()
            };
            g.bench_with_input(
                BenchmarkId::new(format!("{name}-r{r}"), size),
                &o,
                |b, o| {
                    b.iter(|| {
                        ctx.render(&scene, &scene.camera, &shader, Method::Direct, o)
                            .unwrap()
                    })
                },
            );
        }
    }
    for n in [4usize, 16] {
        let scene = room(n);
        let source = Grid::new(scene.polygons.len());
        let opts = FrameOptions::new(1024, 1024);
        g.throughput(Throughput::Elements(1024 * 1024));
        g.bench_with_input(
            BenchmarkId::new(format!("room-{}", scene.polygons.len()), 1024),
            &opts,
            |b, o| {
                let mut ctx = FrameContext::new();
                let shader = Shader::Patches(&source);
                b.iter(|| {
                    ctx.render(&scene, &scene.camera, &shader, Method::Direct, o)
                        .unwrap()
                })
            },
        );
    }
    g.finish();
}

/// Each stage of a 1024 x 1024 direct frame alone, on reused buffers: geometry and setup,
/// binning, rasterization with patch location (every region), composition of two renderers'
/// G-buffers (every region), and the deferred pass (in `deferred`).
///
/// One criterion group, kept as one function: its cases share the scene and buffers built at
/// the top, and each is a short setup followed by its `bench_function`; split, they would pass
/// that state around without reading any easier.
fn stages(c: &mut Criterion) {
    let isa = Isa::detect();
    let scene = room(8);
    let source = Grid::new(scene.polygons.len());
    let (w, h) = (1024, 1024);
    let opts = FrameOptions::new(w, h);
    let grid = RegionGrid::new(w, h, opts.region);
    let offsets = sample_offsets(base::method::Aa::ONE);
    let mut g = c.benchmark_group("stages");
    g.sample_size(20);
    g.throughput(Throughput::Elements((w * h) as u64));
    let mut prims = Vec::new();
    g.bench_function("geometry-1024", |b| {
        b.iter(|| build_primitives_into(&scene, &scene.camera, w, h, false, &mut prims).unwrap())
    });
    let mut bins = Vec::new();
    g.bench_function("binning-1024", |b| {
        b.iter(|| bin_round_robin_into(&grid, &prims, 1, &mut bins))
    });
    // Region `r`'s share `ids` of the primitives into `gb`, with the instruction set `isa`.
    let raster =
        |isa: Isa, ids: &[u32], r: usize, gb: &mut RegionGBuffer, scratch: &mut PatchScratch| {
            rasterize_region_into(
                isa,
                &grid,
                r as u32,
                &prims,
                ids,
                offsets,
                Some(&source),
                gb,
                scratch,
            );
        };

    // One G-buffer and scratch per region, reused by every iteration.
    let mut work: Vec<(RegionGBuffer, PatchScratch)> = (0..grid.count())
        .map(|_| (RegionGBuffer::default(), PatchScratch::default()))
        .collect();
    g.bench_function("raster-1024", |b| {
        b.iter(|| {
            work.par_iter_mut()
                .enumerate()
                .for_each(|(r, (gb, scratch))| raster(isa, &bins[0][r], r, gb, scratch))
        })
    });
    // The same with every narrower instruction set the CPU has, for the ratios in one run.
    for level in Level::ALL.into_iter().filter(|&l| l < isa.level()) {
        let narrow = isa.capped(level);
        g.bench_function(format!("raster-1024-{}", level.name()), |b| {
            b.iter(|| {
                work.par_iter_mut()
                    .enumerate()
                    .for_each(|(r, (gb, scratch))| raster(narrow, &bins[0][r], r, gb, scratch))
            })
        });
    }
    // Two renderers: each region's two G-buffers, merged in place.
    bin_round_robin_into(&grid, &prims, 2, &mut bins);
    // Each region's two renderers' reports, with patch tables or with pixel records only.
    let reports = |source: Option<&dyn PatchSource>| -> Vec<Vec<RegionGBuffer>> {
        (0..grid.count())
            .map(|r| {
                (0..2)
                    .map(|k| {
                        let mut gb = RegionGBuffer::default();
                        rasterize_region_into(
                            isa,
                            &grid,
                            r as u32,
                            &prims,
                            &bins[k][r],
                            offsets,
                            source,
                            &mut gb,
                            &mut PatchScratch::default(),
                        );
                        gb
                    })
                    .collect()
            })
            .collect()
    };
    let parts = reports(Some(&source));
    g.bench_function("composition-2-renderers-1024", |b| {
        b.iter_batched_ref(
            || parts.clone(),
            |parts| {
                parts
                    .par_iter_mut()
                    .for_each_init(MergeScratch::default, |m, p| composite_in_place(isa, p, m))
            },
            BatchSize::LargeInput,
        )
    });
    // What the frame does: reports of pixel records only, merged, then the merged region's
    // patches located once.
    let records = reports(None);
    g.bench_function("merge-and-locate-2-renderers-1024", |b| {
        b.iter_batched_ref(
            || records.clone(),
            |parts| {
                parts
                    .par_iter_mut()
                    .for_each_init(PatchScratch::default, |scratch, p| {
                        merge_records_in_place(isa, p);
                        p[0].assign_patches_with(&source, scratch);
                    })
            },
            BatchSize::LargeInput,
        )
    });
    g.finish();
}

fn serde_json_like(s: &FrameStats) -> String {
    format!(
        "prims {} regions {} shaded {} table {} geometry {:.2} raster {:.2} composition {:.2} shading {:.2} frame {:.2} ms",
        s.primitives, s.regions_touched, s.pixels_shaded, s.patch_table_entries, s.geometry_ms, s.raster_ms,
        s.composition_ms, s.shading_ms, s.frame_ms
    )
}

/// The deferred pass alone on G-buffers rasterized once: the patch shader per instruction-set
/// build, from a warm patch cache, and the other shaders.
/// One criterion group in one function, for the reason given at [`stages`].
fn deferred(c: &mut Criterion) {
    let isa = Isa::detect();
    let scene = room(8);
    let source = Grid::new(scene.polygons.len());
    let (w, h) = (1024, 1024);
    let opts = FrameOptions::new(w, h);
    let prims = build_primitives(&scene, &scene.camera, w, h, false).unwrap();
    let grid = RegionGrid::new(w, h, opts.region);
    let bins = grid.bin(prims.iter().enumerate());
    let offsets = sample_offsets(base::method::Aa::ONE);
    let regions: Vec<RegionGBuffer> = (0..grid.count() as u32)
        .map(|r| {
            let (x0, y0, rw, rh) = grid.rect(r);
            let mut gb = RegionGBuffer::new(r, x0, y0, rw, rh, 1);
            for &k in &bins[r as usize] {
                rasterize(isa, &prims[k as usize], &mut gb, offsets);
            }
            gb.assign_patches(&source);
            gb
        })
        .collect();
    let (_, counts) = shade_regions(
        isa,
        &Shader::Patches(&source),
        &regions,
        Vec3::ZERO,
        w,
        h,
        opts.region,
    );
    eprintln!("deferred: {counts:?}");
    let mut g = c.benchmark_group("deferred");
    g.sample_size(20);
    g.throughput(Throughput::Elements((w * h) as u64));
    // Every region shaded into its own tile, the tiles kept across iterations (no allocation
    // or first touch inside the measurement).
    let mut tiles: Vec<Vec<Vec3>> = regions
        .iter()
        .map(|r| vec![Vec3::ZERO; (r.width * r.height) as usize])
        .collect();
    let pass = |isa: Isa, shader: &Shader<'_>, tiles: &mut Vec<Vec<Vec3>>| {
        tiles.par_iter_mut().zip(&regions).for_each(|(t, r)| {
            let mut rows = Rows::new(t, r.width as usize, r.width as usize, r.height as usize);
            engine::shading::shade_region_rows(isa, shader, r, Vec3::ZERO, &mut rows);
        })
    };
    g.bench_function("rrp-1024", |b| {
        b.iter(|| pass(isa, &Shader::Patches(&source), &mut tiles))
    });
    // The same pass with every narrower instruction set the CPU has, for the ratios in one run.
    for level in Level::ALL.into_iter().filter(|&l| l < isa.level()) {
        let narrow = isa.capped(level);
        g.bench_function(format!("rrp-1024-{}", level.name()), |b| {
            b.iter(|| pass(narrow, &Shader::Patches(&source), &mut tiles))
        });
    }
    // The same pass from cache: each worker shades its regions (every n-th, n workers) 8 times
    // in a row into one tile of its own, so all but the first pass over a region read its
    // G-buffer from the core's L2 and write a tile that stays there. Against `rrp-1024` (each
    // region once, 20 MB of G-buffers and 12 MB of tiles streamed through memory) it separates
    // the pass's arithmetic from its memory traffic; inside a frame the pass reads a region the
    // rasterizer has just written, so a frame sits between the two.
    const REPEAT: usize = 8;
    let side = regions
        .iter()
        .map(|r| r.width * r.height)
        .max()
        .unwrap_or(0) as usize;
    let own: Vec<std::sync::Mutex<Vec<Vec3>>> = (0..rayon::current_num_threads())
        .map(|_| std::sync::Mutex::new(vec![Vec3::ZERO; side]))
        .collect();
    g.throughput(Throughput::Elements((REPEAT as u32 * w * h) as u64));
    g.bench_function("rrp-1024-from-cache", |b| {
        b.iter(|| {
            rayon::broadcast(|ctx| {
                let mut tile = own[ctx.index()].lock().unwrap();
                for r in regions.iter().skip(ctx.index()).step_by(ctx.num_threads()) {
                    for _ in 0..REPEAT {
                        let mut rows = Rows::new(
                            &mut tile,
                            r.width as usize,
                            r.width as usize,
                            r.height as usize,
                        );
                        let shader = Shader::Patches(&source);
                        engine::shading::shade_region_rows(isa, &shader, r, Vec3::ZERO, &mut rows);
                    }
                }
            })
        })
    });
    g.throughput(Throughput::Elements((w * h) as u64));
    // The same regions through the texture pass: one 16 x 16 texture per polygon (the 4 x 4
    // patches of each polygon hold 5 x 5 samples; 16 texels per side is the next power of two
    // above 2 x 5, generous sampling), magnified as the walls are at 1024^2.
    let textures = (0..scene.polygons.len())
        .map(|p| {
            let texels = (0..16 * 16)
                .map(|k| Vec3::splat(((p * 7 + k * 5) % 11) as f32 * 0.1))
                .collect();
            RadiosityTexture::from_texels(16, 16, texels).unwrap()
        })
        .collect();
    let set = TextureSet {
        textures,
        memory: TextureMemory::of_sides(&vec![16; scene.polygons.len()], 0),
        placement: Placement::Centre,
        gutter: 0,
    };
    for (name, filter) in [
        ("texture-nearest-1024", Filter::Nearest),
        ("texture-bilinear-1024", Filter::Bilinear),
        ("texture-bicubic-1024", Filter::MITCHELL),
    ] {
        let shader = Shader::Texture {
            set: &set,
            filter,
            anisotropy: 1,
        };
        g.bench_function(name, |b| b.iter(|| pass(isa, &shader, &mut tiles)));
    }
    g.finish();
}

criterion_group!(benches, frame, stages, deferred);
fn main() {
    pixelflow_bench::require_optimized_engine(engine::OPT_LEVEL);
    benches();
    Criterion::default().configure_from_args().final_summary();
}
