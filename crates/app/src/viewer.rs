//! The interactive walkthrough's engine: a camera the user flies or orbits, the method, renderer
//! count and region size they switch between, the scene's camera path played back, and each
//! frame drawn by the PixelFlow engine itself ([`crate::frames::render_frame_in`], the pixels
//! `render` writes for the same camera and options).
//!
//! The window is not here (the binary opens it and turns keys into [`Action`]s): this module is
//! the frame source, so it runs the same without a display. [`Script`] replays a list of
//! actions at a fixed time step (the headless test, and a reproducible recording of a session);
//! [`Viewer::status`] is the on-screen line (frame rate and the frame's stage times).
//!
//! Camera: *fly* moves the eye along the view direction, sideways and along up, and turns the
//! view about the eye; *orbit* turns the eye about the look-at point at a fixed distance and
//! dollies toward it. Speeds follow the scene's size (a quarter of its core diagonal per second)
//! and turns are 60 degrees per second, so a step depends on the time held, not the frame rate.

use std::f64::consts::PI;
use std::sync::{Arc, Mutex};

use glam::{DQuat, DVec3};

use crate::frames::build_method_data;
use crate::frames::render_frame_in;
use crate::frames::reserve_frames;
use crate::prepare::Prepared;
use base::error::{Error, Result};
use base::method::{Filter, Method};
use base::progress::Observer;
use engine::frame::{FrameContext, FrameOptions, FrameStats};
use scene::Camera;

/// What a key does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// Held: move along the view direction (fly) or dolly in (orbit).
    Forward,
    /// Held: the opposite of [`Action::Forward`].
    Back,
    /// Held: move left (fly) or orbit left.
    Left,
    /// Held: move right (fly) or orbit right.
    Right,
    /// Held: move along up.
    Up,
    /// Held: move against up.
    Down,
    /// Held: turn the view left (fly) or orbit left.
    TurnLeft,
    /// Held: turn right.
    TurnRight,
    /// Held: look up (fly) or orbit over.
    LookUp,
    /// Held: look down.
    LookDown,
    /// Pressed: the next method in [`METHODS`].
    NextMethod,
    /// Pressed: the method at this index of [`METHODS`].
    Method(usize),
    /// Pressed: one more virtual renderer (up to 64).
    MoreRenderers,
    /// Pressed: one fewer (down to 1).
    FewerRenderers,
    /// Pressed: double the region side (up to 512).
    LargerRegions,
    /// Pressed: halve it (down to 16).
    SmallerRegions,
    /// Pressed: play or pause the scene's camera path.
    Play,
    /// Pressed: switch between fly and orbit.
    Orbit,
    /// Pressed: back to the scene's camera.
    Reset,
}

/// The methods the viewer switches between, in key order (1 to 5).
pub const METHODS: [Method; 5] = [
    Method::Direct,
    Method::Texture(Filter::Nearest),
    Method::Texture(Filter::Bilinear),
    Method::Texture(Filter::MITCHELL),
    Method::Mesh,
];

/// Seconds the scene's camera path takes per keyframe segment when played.
pub const SECONDS_PER_SEGMENT: f64 = 4.0;

/// Turn rate, radians per second.
const TURN: f64 = PI / 3.0;

/// The viewer's state: camera, method, renderer settings, playback.
#[derive(Debug, Clone)]
pub struct ViewState {
    /// The camera (its projection is the scene's).
    pub camera: Camera,
    /// Index into [`METHODS`].
    pub method: usize,
    /// Virtual renderers.
    pub renderers: u32,
    /// Region side in pixels.
    pub region: u32,
    /// Orbit instead of fly.
    pub orbit: bool,
    /// Path time while the scene's camera path plays (`None`: not playing).
    pub playing: Option<f64>,
    /// Scene units per second.
    speed: f64,
}

impl ViewState {
    /// At the scene's camera, the direct method, one renderer, 128-pixel regions.
    pub fn new(scene: &scene::Scene) -> ViewState {
        ViewState {
            camera: scene.camera,
            method: 0,
            renderers: 1,
            region: 128,
            orbit: false,
            playing: None,
            speed: 0.25 * scene.core_diagonal().max(1e-6),
        }
    }

    /// The method drawn.
    pub fn method(&self) -> Method {
        METHODS[self.method]
    }

    /// Applies a pressed key.
    pub fn press(&mut self, a: Action, scene: &scene::Scene) {
        match a {
            Action::NextMethod => self.method = (self.method + 1) % METHODS.len(),
            Action::Method(i) if i < METHODS.len() => self.method = i,
            Action::MoreRenderers => self.renderers = (self.renderers + 1).min(64),
            Action::FewerRenderers => self.renderers = self.renderers.saturating_sub(1).max(1),
            Action::LargerRegions => self.region = (self.region * 2).min(512),
            Action::SmallerRegions => self.region = (self.region / 2).max(16),
            Action::Orbit => self.orbit = !self.orbit,
            Action::Reset => {
                self.camera = scene.camera;
                self.playing = None;
            }
            Action::Play => {
                self.playing = match (self.playing, &scene.camera_path) {
                    (None, Some(_)) => Some(0.0),
                    _ => None,
                }
            }
            _ => {}
        }
    }

    /// Advances `dt` seconds with `held` keys down (and the path, while it plays).
    pub fn advance(&mut self, held: &[Action], dt: f64, scene: &scene::Scene) {
        if let (Some(t), Some(path)) = (self.playing, &scene.camera_path) {
            let end = path.segments() as f64;
            let t = (t + dt / SECONDS_PER_SEGMENT).min(end);
            self.camera = path.camera_at(scene.camera.projection, t);
            self.playing = (t < end).then_some(t);
            return;
        }
        let c = &mut self.camera;
        let view = (c.look_at - c.eye).normalize_or_zero();
        let up = c.up.normalize_or_zero();
        let side = view.cross(up).normalize_or_zero();
        let mut step = DVec3::ZERO;
        let (mut yaw, mut pitch) = (0.0, 0.0);
        for a in held {
            match a {
                Action::Forward => step += view,
                Action::Back => step -= view,
                Action::Right => step += side,
                Action::Left => step -= side,
                Action::Up => step += up,
                Action::Down => step -= up,
                Action::TurnLeft => yaw += TURN * dt,
                Action::TurnRight => yaw -= TURN * dt,
                Action::LookUp => pitch += TURN * dt,
                Action::LookDown => pitch -= TURN * dt,
                _ => {}
            }
        }
        let step = step * self.speed * dt;
        if self.orbit {
            orbit(c, step.dot(view), step.dot(side), yaw, pitch);
        } else {
            c.eye += step;
            c.look_at += step;
            turn(c, yaw, pitch);
        }
    }
}

/// Turns the view about the eye: `yaw` about up, `pitch` about the side axis, keeping the view
/// at least 1 degree from up.
fn turn(c: &mut Camera, yaw: f64, pitch: f64) {
    let d = c.look_at - c.eye;
    let up = c.up.normalize_or_zero();
    let side = d.cross(up).normalize_or_zero();
    let turned = DQuat::from_axis_angle(up, yaw) * d;
    let pitched = DQuat::from_axis_angle(side, pitch) * turned;
    let c_up = pitched.normalize_or_zero().dot(up).abs();
    c.look_at = c.eye
        + if c_up < (1.0f64).to_radians().cos() {
            pitched
        } else {
            turned
        };
}

/// Orbits the eye about the look-at point: `yaw` about up, `pitch` over; dollies by `dolly`
/// (not past a tenth of the distance) and turns by `sideways` scene units along the orbit.
fn orbit(c: &mut Camera, dolly: f64, sideways: f64, yaw: f64, pitch: f64) {
    let r = c.eye - c.look_at;
    let dist = r.length().max(1e-9);
    let up = c.up.normalize_or_zero();
    let side = r.cross(up).normalize_or_zero();
    let yaw = yaw - sideways / dist;
    let turned = DQuat::from_axis_angle(up, yaw) * r;
    let pitched = DQuat::from_axis_angle(side, -pitch) * turned;
    let r = if pitched.normalize_or_zero().dot(up).abs() < (1.0f64).to_radians().cos() {
        pitched
    } else {
        turned
    };
    let d = (dist - dolly).max(0.1 * dist);
    c.eye = c.look_at + r.normalize_or_zero() * d;
}

/// A viewer: the state, the prepared solution it draws and the frame context kept across
/// frames.
pub struct Viewer {
    prepared: Arc<Prepared>,
    /// The view.
    pub state: ViewState,
    ctx: FrameContext,
    opts: FrameOptions,
    last: Option<FrameStats>,
    /// The method and options `ctx` was last reserved for (reserving touches every buffer:
    /// done again only when they change).
    reserved: Option<(Method, u32, u32)>,
}

impl Viewer {
    /// A viewer of `prepared` with frames of `opts` (its renderers and region are the state's
    /// starting values).
    pub fn new(prepared: Arc<Prepared>, opts: FrameOptions) -> Result<Viewer> {
        opts.validate()?;
        let mut state = ViewState::new(&prepared.scene);
        state.renderers = opts.renderers;
        state.region = opts.region;
        Ok(Viewer {
            prepared,
            state,
            ctx: FrameContext::new(),
            opts,
            last: None,
            reserved: None,
        })
    }

    /// Draws the current view; its linear pixels are [`Viewer::pixels`].
    pub fn frame(&mut self) -> Result<&FrameStats> {
        let method = self.state.method();
        let opts = FrameOptions {
            renderers: self.state.renderers,
            region: self.state.region,
            ..self.opts.clone()
        };
        let key = (method, opts.renderers, opts.region);
        if self.reserved != Some(key) {
            build_method_data(&self.prepared, method)?;
            reserve_frames(&mut self.ctx, &self.prepared, method, &opts)?;
            self.reserved = Some(key);
        }
        let stats = render_frame_in(
            &mut self.ctx,
            &self.prepared,
            method,
            &self.state.camera,
            &opts,
        )?;
        Ok(self.last.insert(stats))
    }

    /// The last frame's linear radiosity, row-major from the top.
    pub fn pixels(&self) -> &[glam::Vec3] {
        self.ctx.pixels()
    }

    /// The last frame as sRGB bytes (3 per pixel, after `exposure` stops, as `render`'s PNG);
    /// with `status`, that frame below a strip of [`STATUS_STRIP`] rows holding the status line
    /// ([`with_status`]: the window is that much taller, and no pixel of the frame is covered).
    pub fn display(&self, exposure: f64, status: Option<&str>) -> Result<Vec<u8>> {
        let (w, h) = self.size();
        let view = imageio::ImageView {
            width: w,
            height: h,
            pixels: self.pixels(),
        };
        let rgb = imageio::write::srgb8_bytes(view, exposure as f32);
        match status {
            Some(text) => with_status(&rgb, w, h, text),
            None => Ok(rgb),
        }
    }

    /// The prepared solution drawn.
    pub fn prepared(&self) -> &Arc<Prepared> {
        &self.prepared
    }

    /// Draws `prepared` from the next frame on, the view unchanged: a later snapshot of the
    /// same scene's solve ([`crate::prepare::prepare_progressively`]). Its method's data is built
    /// again on the next frame.
    pub fn replace(&mut self, prepared: Arc<Prepared>) {
        self.prepared = prepared;
        self.reserved = None;
        self.last = None;
    }

    /// The frame size.
    pub fn size(&self) -> (u32, u32) {
        (self.opts.width, self.opts.height)
    }

    /// The on-screen line: method, frame rate from `frame_seconds` (the window's time between
    /// frames), the last frame's engine time and its stages, renderers and region.
    pub fn status(&self, frame_seconds: f64) -> String {
        let fps = if frame_seconds > 0.0 {
            1.0 / frame_seconds
        } else {
            0.0
        };
        let mut s = format!("{}  {fps:.0} fps", self.state.method().name());
        if let Some(st) = &self.last {
            s += &format!(
                "  frame {:.1} ms (geometry {:.1}, raster {:.1}, composition {:.1}, shading {:.1})",
                st.frame_ms, st.geometry_ms, st.raster_ms, st.composition_ms, st.shading_ms
            );
        }
        s += &format!(
            "  {} renderer(s), {} px regions{}{}",
            self.state.renderers,
            self.state.region,
            if self.state.orbit { ", orbit" } else { "" },
            if self.state.playing.is_some() {
                ", playing"
            } else {
                ""
            }
        );
        s
    }
}

/// A recorded session: each line `press ACTION`, `hold ACTION[,ACTION...] SECONDS` or
/// `wait SECONDS` (`#` starts a comment), replayed at a fixed time step.
#[derive(Debug, Clone, PartialEq)]
pub struct Script {
    steps: Vec<Step>,
}

#[derive(Debug, Clone, PartialEq)]
enum Step {
    Press(Action),
    Hold(Vec<Action>, f64),
}

/// The time step a script is replayed at (a 60 Hz display).
pub const SCRIPT_STEP: f64 = 1.0 / 60.0;

/// The action a script names.
pub fn action(name: &str) -> Option<Action> {
    Some(match name {
        "forward" => Action::Forward,
        "back" => Action::Back,
        "left" => Action::Left,
        "right" => Action::Right,
        "up" => Action::Up,
        "down" => Action::Down,
        "turn-left" => Action::TurnLeft,
        "turn-right" => Action::TurnRight,
        "look-up" => Action::LookUp,
        "look-down" => Action::LookDown,
        "next-method" => Action::NextMethod,
        "more-renderers" => Action::MoreRenderers,
        "fewer-renderers" => Action::FewerRenderers,
        "larger-regions" => Action::LargerRegions,
        "smaller-regions" => Action::SmallerRegions,
        "play" => Action::Play,
        "orbit" => Action::Orbit,
        "reset" => Action::Reset,
        m => {
            let i = METHODS.iter().position(|x| x.name() == m)?;
            Action::Method(i)
        }
    })
}

/// Longest a whole script may hold and wait, in seconds (each step of [`SCRIPT_STEP`] costs a
/// camera update, so the bound keeps a replay's work bounded whatever the file's length).
pub const MAX_SCRIPT_SECONDS: f64 = 3600.0;

impl Script {
    /// Parses a script; errors name the file's line.
    pub fn parse(text: &str, file: &std::path::Path) -> Result<Script> {
        let mut steps = Vec::new();
        let mut total = 0.0;
        for (n, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let at = || base::error::Location::file(file).at_line(n + 1);
            let words: Vec<&str> = line.split_whitespace().collect();
            let secs = |w: Option<&&str>| -> Result<f64> {
                w.and_then(|s| s.parse::<f64>().ok())
                    .filter(|s| s.is_finite() && (0.0..=3600.0).contains(s))
                    .ok_or_else(|| Error::input(at(), "needs a duration in seconds, 0 to 3600"))
            };
            let actions = |w: Option<&&str>| -> Result<Vec<Action>> {
                let list = w.ok_or_else(|| Error::input(at(), "names no action"))?;
                list.split(',')
                    .map(|a| {
                        action(a).ok_or_else(|| Error::input(at(), format!("unknown action `{a}`")))
                    })
                    .collect()
            };
            steps.push(match words[0] {
                "press" if words.len() == 2 => {
                    let a = actions(words.get(1))?;
                    if a.len() != 1 {
                        return Err(Error::input(at(), "press takes one action"));
                    }
                    Step::Press(a[0])
                }
                "hold" if words.len() == 3 => {
                    Step::Hold(actions(words.get(1))?, secs(words.get(2))?)
                }
                "wait" if words.len() == 2 => Step::Hold(Vec::new(), secs(words.get(1))?),
                _ => {
                    return Err(Error::input(
                        at(),
                        "expected `press ACTION`, `hold ACTION[,ACTION] SECONDS` or `wait SECONDS`",
                    ))
                }
            });
            if let Some(Step::Hold(_, s)) = steps.last() {
                total += s;
                if total > MAX_SCRIPT_SECONDS {
                    return Err(Error::input(
                        at(),
                        format!(
                            "the script's holds and waits add up to more than \
                             {MAX_SCRIPT_SECONDS} s here; replay a shorter session"
                        ),
                    ));
                }
            }
        }
        Ok(Script { steps })
    }

    /// The seconds its holds and waits add up to (at most [`MAX_SCRIPT_SECONDS`]).
    pub fn seconds(&self) -> f64 {
        self.steps
            .iter()
            .map(|s| match s {
                Step::Hold(_, secs) => *secs,
                Step::Press(_) => 0.0,
            })
            .sum()
    }

    /// Replays the script on `state` at [`SCRIPT_STEP`].
    pub fn play(&self, state: &mut ViewState, scene: &scene::Scene) {
        for s in &self.steps {
            match s {
                Step::Press(a) => state.press(*a, scene),
                Step::Hold(held, secs) => {
                    let n = (secs / SCRIPT_STEP).round() as u64;
                    for _ in 0..n {
                        state.advance(held, SCRIPT_STEP, scene);
                    }
                }
            }
        }
    }
}

/// What a solve running beside the window has reported: an observer that passes everything
/// on to another (the terminal) and keeps the latest progress, phase and time left for the
/// window's status line ([`SolveProgress::line`]).
pub struct SolveProgress<'a> {
    inner: &'a dyn Observer,
    latest: Mutex<Latest>,
}

/// The latest report of the solve stage.
#[derive(Default)]
struct Latest {
    fraction: f64,
    phase: String,
    seconds: Option<f64>,
    finished: bool,
}

/// The stage a [`SolveProgress`] reports on.
const SOLVE_STAGE: &str = radiosity::STAGE;

impl<'a> SolveProgress<'a> {
    /// A tap on `inner`.
    pub fn new(inner: &'a dyn Observer) -> SolveProgress<'a> {
        SolveProgress {
            inner,
            latest: Mutex::new(Latest::default()),
        }
    }

    /// The solve's progress as the status line shows it while it runs (`None` once it has
    /// finished): its share done, its phase and the time it expects to take still.
    pub fn line(&self) -> Option<String> {
        let l = self.latest.lock().ok()?;
        if l.finished {
            return None;
        }
        let mut s = format!("solving {:.0} %", 100.0 * l.fraction);
        if !l.phase.is_empty() {
            s += &format!(" ({})", l.phase);
        }
        if let Some(t) = l.seconds {
            s += &format!(", about {t:.0} s left");
        }
        Some(s)
    }

    fn update(&self, f: impl FnOnce(&mut Latest)) {
        if let Ok(mut l) = self.latest.lock() {
            f(&mut l);
        }
    }
}

impl Observer for SolveProgress<'_> {
    fn progress(&self, stage: &str, fraction: f64) {
        if stage == SOLVE_STAGE {
            self.update(|l| l.fraction = fraction);
        }
        self.inner.progress(stage, fraction);
    }

    fn finished(&self, stage: &str) {
        if stage == SOLVE_STAGE {
            self.update(|l| l.finished = true);
        }
        self.inner.finished(stage);
    }

    fn remaining(&self, stage: &str, phase: &str, seconds: f64) {
        if stage == SOLVE_STAGE {
            self.update(|l| {
                l.phase = phase.to_string();
                l.seconds = seconds.is_finite().then_some(seconds.max(0.0));
            });
        }
        self.inner.remaining(stage, phase, seconds);
    }

    fn tracing(&self) -> bool {
        self.inner.tracing()
    }

    fn trace(&self, line: &str) {
        self.inner.trace(line);
    }
}

/// Rows of the strip above the frame that holds the viewer's status line.
pub const STATUS_STRIP: u32 = 22;

/// The sRGB frame `rgb` (`w` x `h`, 3 bytes per pixel) below a strip of [`STATUS_STRIP`] rows
/// with `text` in it: a `w` x (`h` + [`STATUS_STRIP`]) image whose rows below the strip are
/// the frame's, unchanged.
pub fn with_status(rgb: &[u8], w: u32, h: u32, text: &str) -> Result<Vec<u8>> {
    let strip = (3 * w * STATUS_STRIP) as usize;
    let mut out = vec![0u8; strip + rgb.len()];
    out[strip..].copy_from_slice(rgb);
    crate::text::overlay_text(&mut out, w, h + STATUS_STRIP, STATUS_STRIP, text)?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The viewer of a solve in progress: each snapshot is a prepared solution of the scene it
    /// draws like any other, and once the final solution replaces the last snapshot the frame
    /// is the final solution's, bit for bit as a viewer opened on it alone draws it (what
    /// `render` writes for that camera).
    #[test]
    fn a_viewer_draws_the_snapshots_then_the_final_solution_as_it_is() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box.toml");
        let mut input = crate::context::Input::load(&path).unwrap();
        input.scene.radiosity.max_depth = 4;
        let texture = crate::context::TextureOptions::default();
        let policy = texture.policy(&input.scene).unwrap();
        let placement = texture.placement(&input.scene).unwrap();
        let snaps = Mutex::new(Vec::new());
        let keep = |p: Prepared| snaps.lock().unwrap().push(p);
        let ctx = crate::context::Context::default();
        let done =
            crate::prepare::prepare_progressively(&ctx, input, policy, placement, Some(&keep))
                .unwrap();
        let snaps = snaps.into_inner().unwrap();
        assert!(snaps.len() >= 2, "{} snapshots", snaps.len());
        let opts = FrameOptions::new(48, 32);
        let done = Arc::new(done);
        let mut alone = Viewer::new(Arc::clone(&done), opts.clone()).unwrap();
        alone.frame().unwrap();
        let mut v = None::<Viewer>;
        let mut means = Vec::new();
        for p in snaps {
            assert_eq!(p.compact.polygon_count(), done.scene.polygons.len());
            match v.as_mut() {
                Some(v) => v.replace(Arc::new(p)),
                None => v = Some(Viewer::new(Arc::new(p), opts.clone()).unwrap()),
            }
            let v = v.as_mut().unwrap();
            v.frame().unwrap();
            let px = v.pixels();
            assert!(px.iter().all(|c| c.is_finite() && c.min_element() >= 0.0));
            means.push(px.iter().map(|c| c.x as f64).sum::<f64>());
        }
        let mut v = v.unwrap();
        v.replace(Arc::clone(&done));
        v.frame().unwrap();
        assert!(v.pixels() == alone.pixels(), "the final frame differs");
        // The indirect light only adds: each snapshot is at least as bright as the one before.
        assert!(means.windows(2).all(|w| w[1] >= w[0]), "{means:?}");
    }

    /// Regression: the status line covered the frame's top 22 rows; it now has its own strip.
    #[test]
    fn the_status_line_covers_no_pixel_of_the_frame() {
        let (w, h) = (64u32, 8u32);
        let rgb: Vec<u8> = (0..3 * w * h).map(|i| (i % 251) as u8).collect();
        let out = with_status(&rgb, w, h, "direct  60 fps").unwrap();
        assert_eq!(out.len() as u32, 3 * w * (h + STATUS_STRIP));
        let strip = (3 * w * STATUS_STRIP) as usize;
        assert_eq!(&out[strip..], &rgb[..]);
        // The strip holds the text: not one flat colour.
        let first = &out[..3];
        assert!(out[..strip].chunks_exact(3).any(|p| p != first));
    }

    fn scene() -> scene::Scene {
        let mut s = scene::Scene::new(
            fixtures::closed_form::camera(),
            8,
            8,
            Vec::new(),
            Vec::new(),
        );
        s.camera.eye = DVec3::new(0.0, 0.0, 5.0);
        s.camera.look_at = DVec3::ZERO;
        s.camera.up = DVec3::Y;
        s
    }

    /// Flying forward for one second moves the eye a quarter of the scene's size along the view;
    /// turning for 1.5 s turns 90 degrees.
    #[test]
    fn fly_moves_by_time_held() {
        let s = scene();
        let mut v = ViewState::new(&s);
        v.speed = 1.0;
        for _ in 0..60 {
            v.advance(&[Action::Forward], SCRIPT_STEP, &s);
        }
        assert!(
            (v.camera.eye - DVec3::new(0.0, 0.0, 4.0)).length() < 1e-9,
            "{}",
            v.camera.eye
        );
        for _ in 0..90 {
            v.advance(&[Action::TurnLeft], SCRIPT_STEP, &s);
        }
        let view = (v.camera.look_at - v.camera.eye).normalize();
        assert!(
            (view - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-9,
            "{view}"
        );
    }

    /// Orbiting keeps the distance to the look-at point; a quarter turn puts the eye on the side.
    #[test]
    fn orbit_keeps_the_distance() {
        let s = scene();
        let mut v = ViewState::new(&s);
        v.press(Action::Orbit, &s);
        for _ in 0..90 {
            v.advance(&[Action::TurnRight], SCRIPT_STEP, &s);
        }
        assert!((v.camera.eye.length() - 5.0).abs() < 1e-9);
        assert!(v.camera.eye.x.abs() > 4.99, "{}", v.camera.eye);
        assert_eq!(v.camera.look_at, DVec3::ZERO);
    }

    #[test]
    fn scripts_parse_and_refuse_with_the_line() {
        let f = std::path::Path::new("s.txt");
        let s = Script::parse(
            "# fly in\nhold forward,turn-left 0.5\npress texture-bilinear\nwait 1\n",
            f,
        )
        .unwrap();
        assert_eq!(s.steps.len(), 3);
        assert_eq!(s.steps[1], Step::Press(Action::Method(2)));
        for (bad, what) in [
            ("hold forward", "expected"),
            ("press fly", "unknown action"),
            ("wait -1", "duration"),
        ] {
            let e = Script::parse(&format!("wait 0\n{bad}\n"), f)
                .unwrap_err()
                .to_string();
            assert!(e.contains("s.txt:2") && e.contains(what), "{e}");
        }
        // Each wait is within its bound, their sum is not (a file of `wait 3600` lines ran for
        // hours): refused at the line that passes the total.
        let e = Script::parse(
            "wait 3000
hold forward 500
wait 200
",
            f,
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("s.txt:3") && e.contains("add up to more than 3600"),
            "{e}"
        );
        let at_the_bound = Script::parse(
            "wait 3000
hold forward 600
press play
",
            f,
        )
        .unwrap();
        assert_eq!(at_the_bound.seconds(), 3600.0);
    }
}
