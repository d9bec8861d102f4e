//! The error along a walkthrough at fixed memory. One view says little about a method that a
//! user walks through: a texture's texels grow and shrink on screen as the camera moves, the
//! mesh's triangles too, while the direct method evaluates its RRPs at every pixel. So frames
//! spread evenly over the scene's camera path are drawn by each method and measured against the
//! same solution's exact image at that frame (the reconstruction error: the solution is the same
//! for every method, so this isolates how each draws it). Memory is fixed: the texture methods
//! get textures sized by a budget equal to the bytes the direct method's RRPs are stored in (the
//! trees and samples they are built from: [`memory::rrp_stored_bytes`]), counted at 12 bits per
//! channel with mip chains; the mesh has the bytes its subdivision needs (it has no size to
//! choose), stated beside it.
//!
//! Invariants: deterministic (images and errors do not depend on threads or timing); the frames
//! are the same for every method.

use serde::Serialize;

use app::commands::walkthrough::spread_frames;
use app::context::Context;
use app::frames::frame_image;
use app::frames::render_frame;
use app::memory;
use app::prepare::Prepared;
use base::error::Result;
use base::method::{Filter, Method};
use base::progress::Stage;
use engine::frame::FrameContext;
use engine::shading::Shader;
use metric::{compare, DEFAULT_PPD};
use reconstruction::texture::{SizePolicy, TextureSet};
use scene::CameraPath;

/// Most frames of a path measured (spread evenly over it, first and last included).
pub const MAX_WALK_FRAMES: u32 = 12;

/// One method's errors along the path.
#[derive(Debug, Clone, Serialize)]
pub struct WalkMethod {
    /// Method name.
    pub method: String,
    /// Bytes it stores (RRPs, textures with mip chains, the mesh).
    pub bytes: u64,
    /// Perceptual distance to the exact image at each measured frame.
    pub errors: Vec<f64>,
}

/// Errors along one scene's camera path.
#[derive(Debug, Clone, Serialize)]
pub struct WalkErrors {
    /// Image width and height.
    pub size: (u32, u32),
    /// The frames measured (indices into the path).
    pub frames: Vec<u32>,
    /// Every method's errors, in [`WALK_METHODS`] order.
    pub methods: Vec<WalkMethod>,
}

/// The methods measured: direct, the two filtered texture methods at its bytes, the mesh.
pub const WALK_METHODS: [Method; 4] = [
    Method::Direct,
    Method::Texture(Filter::Bilinear),
    Method::Texture(Filter::MITCHELL),
    Method::Mesh,
];

/// Measures `p` along `path` at the scene's image size.
pub fn walk_errors(job: &Context<'_>, p: &Prepared, path: &CameraPath) -> Result<WalkErrors> {
    let (w, h) = (p.scene.width, p.scene.height);
    let opts = job.frame_options(w, h);
    let rrp_bytes = memory::rrp_stored_bytes(p);
    let extents = p.texture_extents()?;
    let set = TextureSet::build(
        p.expanded()?.0,
        &extents,
        SizePolicy::Budget(rrp_bytes),
        p.scene.render.texel_placement,
    )?;
    let frames = spread_frames(path.frames, MAX_WALK_FRAMES);
    let mut methods: Vec<WalkMethod> = WALK_METHODS
        .iter()
        .map(|&m| {
            Ok(WalkMethod {
                method: m.name().to_string(),
                bytes: match m {
                    Method::Direct => rrp_bytes,
                    Method::Mesh => p.mesh()?.0.stats.bytes,
                    _ => memory::texture_bytes(&set.memory),
                },
                errors: Vec::new(),
            })
        })
        .collect::<Result<_>>()?;
    let mut stage = Stage::start(job.observer, "walkthrough errors");
    for (i, &k) in frames.iter().enumerate() {
        let camera = path.camera(p.scene.camera.projection, k);
        let exact = frame_image(render_frame(p, Method::Reference, &camera, &opts)?)?;
        for (m, row) in WALK_METHODS.iter().zip(methods.iter_mut()) {
            let frame = match m {
                Method::Texture(filter) => {
                    let mut ctx = FrameContext::new();
                    let shader = Shader::Texture {
                        set: &set,
                        filter: *filter,
                        anisotropy: opts.anisotropy,
                    };
                    let stats = ctx.render(&p.scene, &camera, &shader, *m, &opts)?;
                    ctx.into_frame(stats)
                }
                _ => render_frame(p, *m, &camera, &opts)?,
            };
            let error = compare(&frame_image(frame)?, &exact, DEFAULT_PPD)?.perceptual_distance;
            row.errors.push(error);
        }
        stage.advance((i + 1) as f64 / frames.len() as f64);
    }
    Ok(WalkErrors {
        size: (w, h),
        frames,
        methods,
    })
}

/// One scene's table: a row per measured frame, a column per method, then the median and the
/// largest error of each.
pub fn markdown(name: &str, e: &WalkErrors) -> String {
    let mut s = format!(
        "**{name}** at {} x {}: bytes stored: {}.\n\n| frame |",
        e.size.0,
        e.size.1,
        e.methods
            .iter()
            .map(|m| format!("{} {}", m.method, super::labels::mb(m.bytes)))
            .collect::<Vec<_>>()
            .join(", ")
    );
    for m in &e.methods {
        s += &format!(" {} |", m.method);
    }
    s += "\n|---|";
    s += &"---|".repeat(e.methods.len());
    s += "\n";
    for (i, k) in e.frames.iter().enumerate() {
        s += &format!("| {k} |");
        for m in &e.methods {
            s += &format!(" {:.3} |", m.errors[i]);
        }
        s += "\n";
    }
    for (label, pick) in [
        (
            "median",
            (|v: Vec<f64>| app::rates::median(v)) as fn(Vec<f64>) -> f64,
        ),
        ("largest", |v: Vec<f64>| v.into_iter().fold(0.0, f64::max)),
    ] {
        s += &format!("| **{label}** |");
        for m in &e.methods {
            s += &format!(" **{:.3}** |", pick(m.errors.clone()));
        }
        s += "\n";
    }
    s + "\n"
}
