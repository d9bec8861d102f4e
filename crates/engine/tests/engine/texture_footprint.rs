//! How much of a texture one lookup filters: the level of detail must follow the footprint of
//! what is drawn, in the scene's metric and at the sample's own share of a pixel, or the
//! texture methods blur what the direct method draws sharply.
//!
//! Both cases compare the texture method with the direct method on the same RRP, so the
//! difference is the texture's own error: bilinear interpolation of the RRP at the level it
//! reads, at most `h^2 / 8 (|f_uu| + |f_vv|)` for texel spacing h (in parameter units) at
//! level 0, and four times that plus a box filter's blur one level up.

use base::method::{Aa, Method};
use base::quadtree::{Quadtree, SampledQuadtree};
use engine::frame::{render, render_patches, Frame, FrameOptions};
use engine::shading::Shader;
use glam::{DVec3, Vec3};
use reconstruction::texture::{Filter, Placement, SizePolicy, TextureSet};
use reconstruction::{Estimator, Reconstruction};
use scene::{Camera, Material, Polygon, Projection, Scene};
use std::f64::consts::PI;

/// A `length` x 1 rectangle on z = 0 (u along x, v along y) seen from above by an
/// orthographic camera that fits it, in a `w` x `h` image.
fn plane(length: f64, w: u32, h: u32) -> Scene {
    let c = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    let quad = Polygon::quad(
        [c(0.0, 0.0), c(length, 0.0), c(length, 1.0), c(0.0, 1.0)],
        0,
        0,
    )
    .unwrap();
    let camera = Camera {
        eye: DVec3::new(0.5 * length, 0.5, 2.0),
        look_at: DVec3::new(0.5 * length, 0.5, 0.0),
        up: DVec3::Y,
        projection: Projection::Orthographic {
            width: length,
            height: 1.0,
        },
    };
    let white = Material {
        name: "white".into(),
        reflectance: DVec3::splat(0.5),
        emission: DVec3::ZERO,
    };
    Scene::new(camera, w, h, vec![white], vec![quad])
}

/// `f` sampled on the uniform quadtree of depth `depth`, and its RRP.
fn rrp(depth: u32, f: fn(f64, f64) -> Vec3) -> (Vec<SampledQuadtree>, Reconstruction) {
    let mut tree = Quadtree::new();
    for _ in 0..depth {
        let leaves = tree.leaves();
        for leaf in leaves {
            tree.split(leaf);
        }
    }
    let trees = vec![SampledQuadtree::from_fn(tree, f)];
    let recon = Reconstruction::build(&trees, Estimator::default()).unwrap();
    (trees, recon)
}

/// The direct and the bilinear texture frames of `scene` with the textures `policy` sizes,
/// looked up with `opts.anisotropy`.
fn frames(
    scene: &Scene,
    trees: &[SampledQuadtree],
    recon: &Reconstruction,
    policy: SizePolicy,
    opts: &FrameOptions,
) -> (Frame, Frame, TextureSet) {
    let direct = render_patches(scene, &scene.camera, recon, opts).unwrap();
    let extents = TextureSet::extents(trees, &scene.polygons, 32).unwrap();
    let set = TextureSet::build(recon, &extents, policy, Placement::Centre).unwrap();
    let filter = Filter::Bilinear;
    let shader = Shader::Texture {
        set: &set,
        filter,
        anisotropy: opts.anisotropy,
    };
    let texture = render(scene, &scene.camera, &shader, Method::Texture(filter), opts).unwrap();
    (direct, texture, set)
}

fn largest_difference(a: &Frame, b: &Frame) -> f32 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (*p - *q).abs().max_element())
        .fold(0.0, f32::max)
}

fn along(u: f64, _: f64) -> Vec3 {
    Vec3::splat((1.0 + 0.5 * (2.0 * PI * 4.0 * u).sin()) as f32)
}

#[test]
fn a_long_strips_texture_is_as_sharp_along_its_length_as_across() {
    // A strip 16 x 1 whose light varies along its length: 4 periods of a sine. A square
    // texture of 128 texels spans 16 pixels across the strip, 8 texels a pixel, so its level
    // of detail is 3 and along the strip it is read at 16 texels: interpolation error
    // (1/16)^2 / 8 f_uu = 0.15 (f_uu <= 0.5 (8 pi)^2 = 316). Sides in the strip's ratio,
    // 128 x 8, are magnified both ways (half a texel a pixel): level 0, 1/128 along u, error
    // at most (1/128)^2 / 8 * 316 = 2.4e-3.
    let scene = plane(16.0, 256, 16);
    let (trees, recon) = rrp(6, along);
    let opts = FrameOptions::new(256, 16);
    let (direct, texture, set) = frames(&scene, &trees, &recon, SizePolicy::FromDepth, &opts);
    let t = &set.textures[0];
    assert_eq!((t.width, t.height), (128, 8));
    let bound = (1.0f32 / 128.0).powi(2) / 8.0 * 0.5 * (8.0 * PI as f32).powi(2) + 1e-5;
    let e = largest_difference(&direct, &texture);
    assert!(e <= bound, "texture differs from direct by {e} > {bound}");
}

fn waves(u: f64, v: f64) -> Vec3 {
    let f = 1.0 + 0.5 * (2.0 * PI * 3.0 * u).sin() * (2.0 * PI * 2.0 * v).sin();
    Vec3::new(f as f32, (0.5 * f) as f32, 1.0)
}

#[test]
fn supersampled_texture_lookups_filter_once() {
    // 128 texels over 64 pixels: 2 texels a pixel, level 1 for one sample a pixel. With 16
    // samples a pixel each sample stands for a quarter of the pixel's side, half a texel:
    // level 0, and the pixel's box filter over its 16 samples is the only averaging, as the
    // direct method's. Level 0 differs from the RRP by at most (1/128)^2 / 8 (|f_uu| + |f_vv|)
    // = (0.5 (6 pi)^2 + 0.5 (4 pi)^2) / 131072 = 2.0e-3; reading level 1 (the pixel's
    // footprint) would add four times that and a two-texel box filter.
    let scene = plane(1.0, 64, 64);
    let (trees, recon) = rrp(6, waves);
    let mut opts = FrameOptions::new(64, 64);
    opts.aa = Aa::new("aa", 16).unwrap();
    let (direct, texture, _) = frames(&scene, &trees, &recon, SizePolicy::Fixed(128), &opts);
    let fuu = 0.5 * (6.0 * PI).powi(2);
    let fvv = 0.5 * (4.0 * PI).powi(2);
    let bound = ((1.0 / 128.0f64).powi(2) / 8.0 * (fuu + fvv)) as f32 + 1e-5;
    let e = largest_difference(&direct, &texture);
    assert!(e <= bound, "16 samples: texture differs by {e} > {bound}");
}

fn across(_: f64, v: f64) -> Vec3 {
    Vec3::splat((1.0 + 0.5 * (2.0 * PI * 4.0 * v).sin()) as f32)
}

#[test]
fn a_grazing_footprint_is_as_sharp_across_as_the_direct_method_with_anisotropic_lookups() {
    // A unit square drawn into 16 x 256 pixels (a floor seen at a grazing angle, in an
    // orthographic view): a pixel spans 8 texels of a 128-texel texture along u and half a
    // texel along v, where the light varies (4 periods of a sine). Isotropically the level of
    // detail follows the longer axis (level 3, 16 texels for the 4 periods): the light across
    // is mostly averaged away. With 16 taps along u each reads level 0, and the light, constant
    // along u, is level 0's interpolation: at most (1/128)^2 / 8 f_vv = 2.4e-3 from the RRP
    // (f_vv <= 0.5 (8 pi)^2 = 316).
    let scene = plane(1.0, 16, 256);
    let (trees, recon) = rrp(6, across);
    let mut opts = FrameOptions::new(16, 256);
    let bound = (1.0f32 / 128.0).powi(2) / 8.0 * 0.5 * (8.0 * PI as f32).powi(2) + 1e-5;
    let mut errors = Vec::new();
    for anisotropy in [1, 16] {
        opts.anisotropy = anisotropy;
        let (direct, texture, set) = frames(&scene, &trees, &recon, SizePolicy::Fixed(128), &opts);
        assert_eq!((set.textures[0].width, set.textures[0].height), (128, 128));
        errors.push(largest_difference(&direct, &texture));
    }
    assert!(errors[1] <= bound, "anisotropic: {} > {bound}", errors[1]);
    assert!(errors[0] > 20.0 * bound, "isotropic: {}", errors[0]);
}
