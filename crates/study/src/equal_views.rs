//! Equal-error memory across views and image sizes. The equal-error search
//! ([`crate::equal_error`]) answers for one view at one image size, and the answer moves with
//! both: a texture's texels cover more or fewer pixels as the camera nears or the image grows,
//! while the direct method evaluates its RRPs at every pixel whatever the view. So the same
//! texture sets (the quadtree-depth sides scaled by `2^k`, the scene's texel placement, drawn
//! mip-mapped as the texture methods draw them) are measured from several views (the scene's
//! camera and frames spread over its camera path) at several image sizes, each against the same
//! solution's exact image there, and each view's whole error-size curve is kept beside the
//! direct method's error at that view.
//!
//! Invariants: deterministic (errors and bytes only); every view and size sees the same sets;
//! the scales stop where the one-view search stops (every side clamped, or the memory cap).

use serde::Serialize;

use crate::equal_error::{held_bytes, ScalePoint, MAX_SCALE, MIN_SCALE, SEARCH_MEMORY_CAP};
use app::frames::frame_image;
use app::frames::render_frame;
use app::prepare::Prepared;
use base::error::Result;
use base::method::Method;
use base::progress::{Observer, Stage};
use engine::frame::{self, FrameOptions};
use engine::shading::Shader;
use metric::compare;
use reconstruction::texture::{SizePolicy, TextureMemory, TextureSet, GUTTER};
use scene::Camera;

/// How much above the direct method's error a texture may be and count as reaching it.
pub const VIEW_RATIO: f64 = 1.1;

/// Path frames measured besides the scene's camera (spread over the path, both ends included).
pub const PATH_VIEWS: u32 = 3;

/// One texture method's curve at one view and image size.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct ViewCurve {
    /// The view: `scene camera` or `path frame k`.
    pub view: String,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Texture method.
    pub method: String,
    /// The direct method's reconstruction error there.
    pub direct_error: f64,
    /// The texture method's error at every scale tried, smallest first.
    pub curve: Vec<ScalePoint>,
    /// The smallest scale within [`VIEW_RATIO`] of the direct method's error, if any.
    pub reached: Option<ScalePoint>,
}

/// The views: the scene's camera, then [`PATH_VIEWS`] frames spread over its camera path
/// (both ends included), each left out where it is a view already listed (a path that starts
/// at the scene's camera).
pub fn views(p: &Prepared) -> Vec<(String, Camera)> {
    let mut v = vec![("scene camera".to_string(), p.scene.camera)];
    if let Some(path) = &p.scene.camera_path {
        for k in app::commands::walkthrough::spread_frames(path.frames, PATH_VIEWS) {
            let camera = path.camera(p.scene.camera.projection, k);
            if v.iter().all(|(_, c)| *c != camera) {
                v.push((format!("path frame {k}"), camera));
            }
        }
    }
    v
}

/// Measures the texture methods among `methods` at every view of [`views`] and every size of
/// `sizes`, the frame options otherwise `base`'s.
pub fn across_views(
    p: &Prepared,
    methods: &[Method],
    sizes: &[(u32, u32)],
    base: &FrameOptions,
    ppd: f64,
    observer: &dyn Observer,
) -> Result<Vec<ViewCurve>> {
    let filters: Vec<Method> = methods
        .iter()
        .copied()
        .filter(|m| matches!(m, Method::Texture(_)))
        .collect();
    let views = views(p);
    // The exact and direct images of every view and size, with the direct method's error.
    let mut targets = Vec::new();
    let mut curves = Vec::new();
    for (name, camera) in &views {
        for &(width, height) in sizes {
            let opts = FrameOptions {
                width,
                height,
                ..base.clone()
            };
            let exact = frame_image(render_frame(p, Method::Reference, camera, &opts)?)?;
            let direct = frame_image(render_frame(p, Method::Direct, camera, &opts)?)?;
            let direct_error = compare(&direct, &exact, ppd)?.perceptual_distance;
            for m in &filters {
                curves.push(ViewCurve {
                    view: name.clone(),
                    width,
                    height,
                    method: m.name().to_string(),
                    direct_error,
                    curve: Vec::new(),
                    reached: None,
                });
            }
            targets.push((camera, opts, exact));
        }
    }
    let extents = p.texture_extents()?;
    let mut stage = Stage::start(observer, "equal-error across views");
    let mut previous: Option<Vec<(u32, u32)>> = None;
    for k in MIN_SCALE..=MAX_SCALE {
        let sides = TextureSet::sizes(&extents, SizePolicy::Scaled(k))?;
        let memory = TextureMemory::of_sizes(&sides, GUTTER);
        if previous.as_ref() == Some(&sides) || held_bytes(&memory) > SEARCH_MEMORY_CAP {
            break;
        }
        previous = Some(sides);
        stage.advance((k - MIN_SCALE) as f64 / (MAX_SCALE - MIN_SCALE + 1) as f64);
        let placement = p.scene.render.texel_placement;
        let set = TextureSet::build(p.expanded()?.0, &extents, SizePolicy::Scaled(k), placement)?;
        let bytes = app::memory::texture_bytes(&set.memory);
        let mut c = curves.iter_mut();
        for (camera, opts, exact) in &targets {
            for &m in &filters {
                let Method::Texture(filter) = m else { continue };
                let img = frame_image(frame::render(
                    &p.scene,
                    camera,
                    &Shader::Texture {
                        set: &set,
                        filter,
                        anisotropy: 1,
                    },
                    m,
                    opts,
                )?)?;
                let point = ScalePoint {
                    scale: k,
                    texels: set.memory.texels,
                    bytes,
                    error: compare(&img, exact, ppd)?.perceptual_distance,
                };
                if let Some(curve) = c.next() {
                    curve.curve.push(point);
                    if curve.reached.is_none() && point.error <= VIEW_RATIO * curve.direct_error {
                        curve.reached = Some(point);
                    }
                }
            }
        }
    }
    Ok(curves)
}

/// The curves as a Markdown table: a row per view, size and method, the texture's error over
/// the direct method's at every scale tried (the whole curve), and the bytes of the smallest
/// scale within [`VIEW_RATIO`] of it. Empty for no curves.
pub fn markdown(curves: &[ViewCurve], bytes: impl Fn(u64) -> String) -> String {
    let Some(last) = curves
        .iter()
        .flat_map(|c| c.curve.iter().map(|p| p.scale))
        .max()
    else {
        return String::new();
    };
    let scales: Vec<i32> = (MIN_SCALE..=last).collect();
    let mut s = String::from("| view | size | method | direct error |");
    for k in &scales {
        s += &format!(" 2^{k} |");
    }
    s += &format!(" bytes at <= {VIEW_RATIO}x |\n|---|---|---|---|");
    s += &"---|".repeat(scales.len() + 1);
    s += "\n";
    for c in curves {
        s += &format!(
            "| {} | {} x {} | {} | {:.3} |",
            c.view, c.width, c.height, c.method, c.direct_error
        );
        for k in &scales {
            s += &match c.curve.iter().find(|p| p.scale == *k) {
                Some(p) if c.direct_error > 0.0 => format!(" {:.2} |", p.error / c.direct_error),
                Some(p) => format!(" {:.3} (abs.) |", p.error),
                None => " - |".to_string(),
            };
        }
        s += &format!(
            " {} |\n",
            c.reached
                .map_or("not reached".to_string(), |p| bytes(p.bytes))
        );
    }
    s
}
