//! Frames of a prepared scene: each method drawn into an engine frame context
//! ([`render_frame_in`], reusing its buffers; [`render_frame`], a cold frame), the reference
//! method's progress ([`render_frame_observed`]), and what a context must reserve before frames
//! are timed ([`reserve_frames`]).

use base::error::Result;
use base::method::Method;
use base::progress::{Observer, Stage};
use radiosity::{self};

use crate::prepare::Prepared;

/// A frame's pixels as an image (to measure it).
pub fn frame_image(f: engine::frame::Frame) -> Result<imageio::LinearImage> {
    imageio::LinearImage::new(f.width, f.height, f.pixels)
}

/// Renders one frame of a prepared scene with `method`, in a new frame context (a cold frame;
/// [`render_frame_in`] reuses one).
pub fn render_frame(
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
) -> Result<engine::frame::Frame> {
    let mut ctx = engine::frame::FrameContext::new();
    let stats = render_frame_in(&mut ctx, p, method, camera, opts)?;
    Ok(ctx.into_frame(stats))
}

/// The stage a reference frame reports (every sample of it is a gather from the whole solution:
/// tens of seconds a frame where the other methods take milliseconds).
pub const REFERENCE_STAGE: &str = "reference";

/// [`render_frame`] with progress to `observer`: a reference frame runs as stage
/// [`REFERENCE_STAGE`] ([`render_frame_in_observed`]); the pixels are the same for any observer.
pub fn render_frame_observed(
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
    observer: &dyn Observer,
) -> Result<engine::frame::Frame> {
    let mut ctx = engine::frame::FrameContext::new();
    let stats = render_frame_in_observed(&mut ctx, p, method, camera, opts, observer)?;
    Ok(ctx.into_frame(stats))
}

/// [`render_frame_in`] with progress to `observer`. A reference frame reports stage
/// [`REFERENCE_STAGE`]: the fraction of its samples evaluated, out of the samples a first pass
/// with a shader that evaluates nothing counted (rasterization and composition only,
/// milliseconds; every pixel it wrote is written again). Other methods report nothing (a frame
/// takes milliseconds). The pixels and counters are those of [`render_frame_in`].
pub fn render_frame_in_observed(
    ctx: &mut engine::frame::FrameContext,
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
    observer: &dyn Observer,
) -> Result<engine::frame::FrameStats> {
    use engine::shading::Shader;
    use std::sync::atomic::{AtomicU64, Ordering};
    if method != Method::Reference {
        return render_frame_in(ctx, p, method, camera, opts);
    }
    let stage = std::sync::Mutex::new(Stage::start(observer, REFERENCE_STAGE));
    let oracle = radiosity::Oracle::new(&p.solution, &p.scene).map_err(|e| p.file_error(e))?;
    let nothing = |_: u32, _: f32, _: f32| glam::Vec3::ZERO;
    let total = ctx
        .render(&p.scene, camera, &Shader::Reference(&nothing), method, opts)?
        .pixels_shaded
        .max(1);
    // About a thousand reports a frame; a worker that finds the stage busy skips its report.
    let step = (total / 1000).max(1);
    let done = AtomicU64::new(0);
    let f = |poly: u32, u: f32, v: f32| {
        let c = oracle.radiosity(poly as usize, u as f64, v as f64);
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        if n.is_multiple_of(step) {
            if let Ok(mut s) = stage.try_lock() {
                s.advance(n as f64 / total as f64);
            }
        }
        c
    };
    let stats = ctx.render(&p.scene, camera, &Shader::Reference(&f), method, opts)?;
    if let Ok(mut s) = stage.lock() {
        s.advance(1.0);
    }
    Ok(stats)
}

/// Builds, once per job, what `method` draws from (the textures, the mesh), so that neither a
/// reservation nor a frame timed after it pays for that.
pub(crate) fn build_method_data(p: &Prepared, method: Method) -> Result<()> {
    match method {
        Method::Texture(_) => p.textures().map(|_| ()),
        Method::Mesh => p.mesh().map(|_| ()),
        Method::Direct | Method::Reference => Ok(()),
    }
}

/// Reserves in `ctx` what frames of `method` at `opts` need ([`engine::frame::FrameContext::reserve_scene`]
/// with the scene `method` draws: the mesh's triangles for the mesh method; for the direct method
/// also every worker's patch cache, [`engine::frame::FrameContext::reserve_source`]).
pub fn reserve_frames(
    ctx: &mut engine::frame::FrameContext,
    p: &Prepared,
    method: Method,
    opts: &engine::frame::FrameOptions,
) -> Result<()> {
    match method {
        Method::Mesh => ctx.reserve_scene(opts, &p.mesh()?.0.scene),
        Method::Direct => {
            ctx.reserve_scene(opts, &p.scene)?;
            ctx.reserve_source(&p.compact);
            Ok(())
        }
        _ => ctx.reserve_scene(opts, &p.scene),
    }
}

/// Renders one frame of a prepared scene with `method` into `ctx` (its pixels:
/// [`engine::frame::FrameContext::view`]), reusing the context's buffers.
pub fn render_frame_in(
    ctx: &mut engine::frame::FrameContext,
    p: &Prepared,
    method: Method,
    camera: &scene::Camera,
    opts: &engine::frame::FrameOptions,
) -> Result<engine::frame::FrameStats> {
    use engine::shading::Shader;
    match method {
        Method::Direct => ctx.render(&p.scene, camera, &Shader::Patches(&p.compact), method, opts),
        Method::Texture(filter) => {
            let (set, _) = p.textures()?;
            ctx.render(
                &p.scene,
                camera,
                &Shader::Texture {
                    set,
                    filter,
                    anisotropy: opts.anisotropy,
                },
                method,
                opts,
            )
        }
        Method::Mesh => {
            let (mesh, _) = p.mesh()?;
            ctx.render(
                &mesh.scene,
                camera,
                &Shader::Gouraud(&mesh.gouraud),
                method,
                opts,
            )
        }
        Method::Reference => {
            let oracle =
                radiosity::Oracle::new(&p.solution, &p.scene).map_err(|e| p.file_error(e))?;
            let f = |poly: u32, u: f32, v: f32| oracle.radiosity(poly as usize, u as f64, v as f64);
            ctx.render(&p.scene, camera, &Shader::Reference(&f), method, opts)
        }
    }
}

#[cfg(test)]
mod reference_stage_tests {
    use super::*;
    use crate::context::{Context, Input};
    use crate::prepare::prepare;
    use base::method::Placement;
    use base::progress::{Event, Recorder};
    use reconstruction::texture::SizePolicy;
    use std::path::Path;

    /// A reference frame reports its own stage, from 0 to 1 then finished, and its pixels are
    /// those of the unobserved frame, bit for bit.
    #[test]
    fn the_reference_method_reports_a_stage() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/two-spots.toml");
        let mut input = Input::load(&path).expect("scene loads");
        input.scene.radiosity.max_depth = input.scene.radiosity.min_depth.max(3);
        input.scene.radiosity.shadow_rays = 4;
        let p = prepare(
            &Context::default(),
            input,
            SizePolicy::FromDepth,
            Placement::Centre,
        )
        .expect("solves");
        let opts = Context::default().frame_options(48, 32);
        let r = Recorder::default();
        let seen = render_frame_observed(&p, Method::Reference, &p.scene.camera, &opts, &r)
            .expect("renders");
        let plain = render_frame(&p, Method::Reference, &p.scene.camera, &opts).expect("renders");
        let bits = |f: &engine::frame::Frame| -> Vec<u32> {
            f.pixels
                .iter()
                .flat_map(|c| c.to_array().map(f32::to_bits))
                .collect()
        };
        assert!(
            bits(&seen) == bits(&plain),
            "the observer changed the pixels"
        );
        let events = r.events();
        assert_eq!(
            events.first(),
            Some(&Event::Progress(REFERENCE_STAGE.into(), 0.0))
        );
        assert_eq!(
            events.last(),
            Some(&Event::Finished(REFERENCE_STAGE.into()))
        );
        let fractions: Vec<f64> = events
            .iter()
            .filter_map(|e| match e {
                Event::Progress(s, f) if s == REFERENCE_STAGE => Some(*f),
                _ => None,
            })
            .collect();
        assert_eq!(fractions.last(), Some(&1.0));
        assert!(fractions.windows(2).all(|w| w[0] <= w[1]), "{fractions:?}");
        // Other methods take milliseconds and report nothing.
        let direct = Recorder::default();
        render_frame_observed(&p, Method::Direct, &p.scene.camera, &opts, &direct)
            .expect("renders");
        assert!(direct.events().is_empty());
    }
}
