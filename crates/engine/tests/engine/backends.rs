//! Every rendering backend against known radiosity functions: a constant and a linear function
//! sampled on an adaptive quadtree over the two-spots plane (the unit square seen by an
//! orthographic camera, so pixel (x, y) sees (u, v) = ((x + 0.5) / W, 1 - (y + 0.5) / H)) must
//! come out of the direct method, the three texture filters, the Gouraud mesh and the exact
//! (per-sample function) shader as that function, within f32 rounding. Where a backend's maths
//! makes it differ (clamp-to-edge within a filter's half-width of the polygon's border, the
//! nearest filter's steps), the test states the bound and checks it.

use std::path::Path;

use base::method::Method;
use base::quadtree::{Cell, Quadtree, SampledQuadtree};
use engine::frame::{render, render_patches as render_frame, Frame, FrameOptions};
use engine::shading::Shader;
use glam::Vec3;
use reconstruction::texture::{
    Filter, Placement, RadiosityTexture, SizePolicy, TextureMemory, TextureSet,
};
use reconstruction::{mesh::MeshModel, Estimator, Reconstruction};
use scene::{load_scene, Scene};

fn two_spots() -> Scene {
    load_scene(&Path::new(crate::REPO).join("scenes/two-spots.toml")).unwrap()
}

/// An unrestricted quadtree: depth 2 everywhere, one corner refined to depth 5, another to 3,
/// so that T-vertices and several leaf sizes occur.
fn tree() -> Quadtree {
    let mut t = Quadtree::new();
    let split_at = |t: &mut Quadtree, u: f64, v: f64, depth: u32| loop {
        let leaf = t.find_leaf(u, v);
        if t.node(leaf).cell.level >= depth {
            break;
        }
        t.split(leaf);
    };
    for &(u, v) in &[(0.1, 0.1), (0.9, 0.1), (0.1, 0.9), (0.9, 0.9)] {
        split_at(&mut t, u, v, 2);
    }
    split_at(&mut t, 0.3, 0.7, 5);
    split_at(&mut t, 0.8, 0.2, 3);
    assert!(Cell::ROOT.level == 0 && t.depth() == 5);
    t
}

fn linear(u: f64, v: f64) -> Vec3 {
    Vec3::new(
        (0.5 + 1.5 * u + 0.25 * v) as f32,
        (2.0 - 0.75 * u + 1.25 * v) as f32,
        (0.625 + 0.5 * u - 0.5 * v) as f32,
    )
}

/// |df/du| + |df/dv| per channel, the bound factor of the nearest filter.
const LINEAR_SLOPE: f32 = 2.0;

struct Backends {
    scene: Scene,
    recon: Reconstruction,
    trees: Vec<SampledQuadtree>,
}

impl Backends {
    fn new(f: fn(f64, f64) -> Vec3) -> Backends {
        let scene = two_spots();
        let trees = vec![SampledQuadtree::from_fn(tree(), f)];
        let recon = Reconstruction::build(&trees, Estimator::default()).unwrap();
        Backends {
            scene,
            recon,
            trees,
        }
    }

    fn direct(&self, opts: &FrameOptions) -> Frame {
        render_frame(&self.scene, &self.scene.camera, &self.recon, opts).unwrap()
    }

    fn texture(&self, opts: &FrameOptions, side: u32, filter: Filter) -> Frame {
        let extents = TextureSet::extents(
            &self.trees,
            &self.scene.polygons,
            self.scene.radiosity.max_depth,
        )
        .unwrap();
        let set = TextureSet::build(
            &self.recon,
            &extents,
            SizePolicy::Fixed(side),
            Placement::Centre,
        )
        .unwrap();
        let shader = Shader::Texture {
            set: &set,
            filter,
            anisotropy: 1,
        };
        let method = Method::Texture(filter);
        render(&self.scene, &self.scene.camera, &shader, method, opts).unwrap()
    }

    fn mesh(&self, opts: &FrameOptions) -> Frame {
        let mesh = MeshModel::build(&self.scene, &self.trees).unwrap();
        render_frame(&mesh.scene, &self.scene.camera, &mesh, opts).unwrap()
    }

    fn exact(&self, opts: &FrameOptions, f: fn(f64, f64) -> Vec3) -> Frame {
        let func = move |_: u32, u: f32, v: f32| f(u as f64, v as f64);
        let shader = Shader::Reference(&func);
        render(
            &self.scene,
            &self.scene.camera,
            &shader,
            Method::Reference,
            opts,
        )
        .unwrap()
    }
}

/// Largest per-channel difference between `frame` and `f` at the pixel centres whose (u, v) lies
/// at least `margin` inside the unit square.
fn worst(frame: &Frame, f: fn(f64, f64) -> Vec3, margin: f64) -> f32 {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut worst = 0.0f32;
    for y in 0..h {
        for x in 0..w {
            let u = (x as f64 + 0.5) / w as f64;
            let v = 1.0 - (y as f64 + 0.5) / h as f64;
            if u < margin || u > 1.0 - margin || v < margin || v > 1.0 - margin {
                continue;
            }
            let d = (frame.pixels[y * w + x] - f(u, v)).abs().max_element();
            worst = worst.max(d);
        }
    }
    worst
}

// Values are of order 1-3; every backend does a handful of f32 operations on them, and the
// rasterizer's (u, v) carries a few ulps of 1 times slopes of at most 1.5: 2e-5 is ~100 ulps.
const ROUNDING: f32 = 2e-5;

#[test]
fn a_constant_is_the_constant_through_every_backend_everywhere() {
    fn c(_: f64, _: f64) -> Vec3 {
        Vec3::new(0.7, 1.9, 0.05)
    }
    let b = Backends::new(c);
    let opts = FrameOptions::new(96, 96);
    // Everywhere, borders included: clamp-to-edge of a constant is the constant.
    assert!(worst(&b.direct(&opts), c, 0.0) < ROUNDING);
    assert!(worst(&b.mesh(&opts), c, 0.0) < ROUNDING);
    assert!(worst(&b.exact(&opts, c), c, 0.0) < ROUNDING);
    for filter in [
        Filter::Nearest,
        Filter::Bilinear,
        Filter::MITCHELL,
        Filter::CATMULL_ROM,
    ] {
        // 8 texels: magnified 12x; 512 texels: minified 5.3x (mip levels and trilinear blends).
        for side in [8, 512] {
            let e = worst(&b.texture(&opts, side, filter), c, 0.0);
            assert!(e < ROUNDING, "{filter:?} side {side}: {e}");
        }
    }
}

#[test]
fn a_linear_function_is_reproduced_by_every_backend() {
    let b = Backends::new(linear);
    let opts = FrameOptions::new(128, 128);
    // The RRP of linear samples is the linear function (C1 Hermite with exact slopes), the
    // Gouraud mesh on a parallelogram interpolates it exactly, the exact shader is f itself.
    assert!(worst(&b.direct(&opts), linear, 0.0) < ROUNDING);
    assert!(worst(&b.mesh(&opts), linear, 0.0) < ROUNDING);
    assert!(worst(&b.exact(&opts, linear), linear, 0.0) < ROUNDING);
    for side in [16u32, 64] {
        let texel = 1.0 / side as f64;
        // Bilinear interpolation between texel centres is exact for a linear function; within
        // half a texel of the border clamp-to-edge holds the edge value instead.
        let e = worst(
            &b.texture(&opts, side, Filter::Bilinear),
            linear,
            0.5 * texel,
        );
        assert!(e < ROUNDING, "bilinear {side}: {e}");
        // Mitchell-Netravali (any B, C) reproduces linear functions where the 4 x 4 footprint
        // lies inside the texture: more than 1.5 texels from the border.
        for filter in [Filter::MITCHELL, Filter::CATMULL_ROM] {
            let e = worst(&b.texture(&opts, side, filter), linear, 1.5 * texel + 1e-9);
            assert!(e < ROUNDING, "{filter:?} {side}: {e}");
        }
        // Nearest returns the value at the containing texel's centre, at most half a texel
        // away in u and in v: error <= (|df/du| + |df/dv|) / (2 N).
        let bound = LINEAR_SLOPE * 0.5 / side as f32 + ROUNDING;
        let e = worst(&b.texture(&opts, side, Filter::Nearest), linear, 0.0);
        assert!(e <= bound, "nearest {side}: {e} > {bound}");
        // ... and it is a step function: not exact (the test would pass for a broken filter
        // that interpolated, so check it really steps).
        assert!(e > 0.25 * bound, "nearest {side} looks interpolated: {e}");
    }
}

#[test]
fn minified_textures_use_coarser_levels() {
    // 512 texels over 64 pixels: 8 texels per pixel, lod 3. Level 3 of a box-filtered chain of a
    // linear function is the function at the coarser texel centres, so bilinear at lod 3 is still
    // linear inside its own half-texel border (1/128 of u).
    let b = Backends::new(linear);
    let opts = FrameOptions::new(64, 64);
    let e = worst(&b.texture(&opts, 512, Filter::Bilinear), linear, 0.5 / 64.0);
    assert!(e < ROUNDING, "{e}");
    // A checkerboard texture averages to its mean when minified 8x: the finest level would
    // alias, the chain does not.
    let texels: Vec<Vec3> = (0..256 * 256)
        .map(|k| Vec3::splat(((k % 256 + k / 256) % 2) as f32))
        .collect();
    let set = TextureSet {
        textures: vec![RadiosityTexture::from_texels(256, 256, texels).unwrap()],
        memory: TextureMemory::of_sides(&[256], 0),
        placement: Placement::Centre,
        gutter: 0,
    };
    let scene = two_spots();
    let frame = render(
        &scene,
        &scene.camera,
        &Shader::Texture {
            set: &set,
            filter: Filter::Bilinear,
            anisotropy: 1,
        },
        Method::Texture(Filter::Bilinear),
        &FrameOptions::new(32, 32),
    )
    .unwrap();
    // 256 texels over 32 pixels: lod 3; every texel of level 3 (and coarser) is the mean of
    // an 8 x 8 block of the checkerboard, 0.5 exactly, so every pixel is 0.5 exactly. Level 0
    // would give 0 or 1 (or blends of them) at pixel centres.
    for p in &frame.pixels {
        assert_eq!(*p, Vec3::splat(0.5));
    }
}
