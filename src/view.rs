//! `view`: the interactive walkthrough window (minifb, X11), or with `--script` a headless
//! replay that writes the last frame. The frames, the camera and the keys' meaning live in
//! `app::viewer`; this module only turns keys into its actions and shows its pixels.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use minifb::{InputCallback, Key, Window, WindowOptions};

use crate::args::ViewArgs;
use crate::commands::{in_pool, wrote, Settings};
use crate::terminal::Terminal;
use app::viewer::{Action, Script, SolveProgress, Viewer};

/// The action a pressed key triggers (`shift` held).
fn pressed(k: Key, shift: bool) -> Option<Action> {
    Some(match k {
        Key::M => Action::NextMethod,
        Key::Key1 => Action::Method(0),
        Key::Key2 => Action::Method(1),
        Key::Key3 => Action::Method(2),
        Key::Key4 => Action::Method(3),
        Key::Key5 => Action::Method(4),
        Key::R if shift => Action::FewerRenderers,
        Key::R => Action::MoreRenderers,
        Key::G if shift => Action::SmallerRegions,
        Key::G => Action::LargerRegions,
        Key::P => Action::Play,
        Key::Tab => Action::Orbit,
        Key::Home => Action::Reset,
        _ => return None,
    })
}

/// The action a held key continues.
fn held(k: &Key) -> Option<Action> {
    Some(match k {
        Key::W => Action::Forward,
        Key::S => Action::Back,
        Key::A => Action::Left,
        Key::D => Action::Right,
        Key::E => Action::Up,
        Key::Q => Action::Down,
        Key::Left => Action::TurnLeft,
        Key::Right => Action::TurnRight,
        Key::Up => Action::LookUp,
        Key::Down => Action::LookDown,
        _ => return None,
    })
}

pub(crate) fn view(settings: &Settings, args: ViewArgs) -> anyhow::Result<()> {
    in_pool(args.threads, || -> anyhow::Result<()> {
        let terminal = Terminal::new(true, false);
        let observer = SolveProgress::new(&terminal);
        let ctx = settings.context(&observer);
        let input = app::context::Input::load_opts(
            &args.input,
            args.scene.as_deref(),
            &settings.load_options(&args.options),
        )?;
        let texture = args.texture.options();
        let policy = texture.policy(&input.scene)?;
        let placement = texture.placement(&input.scene)?;
        let script = match &args.script {
            // The script is an input: unreadable or not text is bad input (exit 2).
            Some(path) => Some(Script::parse(
                &base::output::read_text(path, settings.input_limit()).map_err(|e| {
                    base::Error::input(base::error::Location::file(path), e.to_string())
                })?,
                path,
            )?),
            None => None,
        };
        let opts = engine::frame::FrameOptions {
            aa: input.scene.render.aa_samples,
            renderers: args.renderers,
            region: args.region,
            isa: settings.isa(),
            anisotropy: texture.anisotropy(),
            ..engine::frame::FrameOptions::new(args.width, args.height)
        };
        // The viewer's frame (and the screenshot's PNG) under the memory limit, as `render`'s,
        // before the solve; and, for the window, a display to open it on.
        app::budget::check_frame_options(&opts, (true, false), ctx.memory_limit)?;
        if script.is_none() || args.screenshot.is_none() {
            check_display()?;
        }
        let exposure = input.scene.display.exposure;
        match (script, &args.screenshot) {
            (Some(script), Some(png)) => {
                let prepared = Arc::new(app::prepare::prepare(&ctx, input, policy, placement)?);
                let mut viewer = Viewer::new(Arc::clone(&prepared), opts)?;
                script.play(&mut viewer.state, &prepared.scene);
                // Every frame as the window draws it (frame, sRGB, status line), timed.
                let mut times = Vec::with_capacity(args.frames as usize);
                let mut seconds = 0.0;
                for _ in 0..args.frames {
                    let t = Instant::now();
                    viewer.frame()?;
                    let _shown = viewer.display(exposure, Some(&viewer.status(seconds)))?;
                    seconds = t.elapsed().as_secs_f64();
                    times.push(seconds);
                }
                let rgb = viewer.display(exposure, None)?;
                imageio::write::write_srgb_png(&ctx.outputs, png, args.width, args.height, rgb)?;
                wrote(png, false);
                times.sort_by(f64::total_cmp);
                let median = times[times.len() / 2];
                crate::out(&format!(
                    "{}\n{} frames as shown: median {:.2} ms ({:.0} fps)\n",
                    viewer.status(median),
                    times.len(),
                    1e3 * median,
                    1.0 / median
                ))
            }
            _ => {
                // The solve runs beside the window, which opens at once and draws each of its
                // snapshots as it comes (progressive radiosity's early picture).
                let (tx, rx) = crossbeam_channel::unbounded();
                let finished = AtomicBool::new(false);
                rayon::in_place_scope(|scope| {
                    let (ctx, finished) = (&ctx, &finished);
                    scope.spawn(move |_| {
                        let send = |p| {
                            let _ = tx.send(Update::Snapshot(p));
                        };
                        let done = app::prepare::prepare_progressively(
                            ctx,
                            input,
                            policy,
                            placement,
                            Some(&send),
                        );
                        let _ = tx.send(Update::Done(done));
                        finished.store(true, Ordering::Release);
                    });
                    let shown = window(&rx, &observer, opts, exposure);
                    if !finished.load(Ordering::Acquire) {
                        leave_the_solve(shown);
                    }
                    shown
                })
            }
        }
    })?
}

/// What the solve beside the window sends it.
enum Update {
    /// A snapshot of the solve, reconstructed.
    Snapshot(app::prepare::Prepared),
    /// The final solution, or why there is none.
    Done(base::error::Result<app::prepare::Prepared>),
}

/// Ends the process when the window closed (or failed) while the solve still ran: the window
/// writes nothing, and the solve cannot be stopped part-way, so nothing is left to wait for.
/// Its error, if any, is reported as `main` reports one, with its exit code.
fn leave_the_solve(shown: anyhow::Result<()>) -> ! {
    match shown {
        Ok(()) => std::process::exit(0),
        Err(mut e) => {
            crate::spell_options(&mut e);
            crate::note(&format!("error: {e:#}"));
            std::process::exit(crate::exit_code(&e))
        }
    }
}

/// Key events as the window delivers them, latched between frames: minifb's per-frame key
/// state loses a key pressed and released within one frame (a tap at 3 fps), so the window's
/// input callback queues every press and release here and each frame takes them all.
#[derive(Clone, Default)]
struct KeyLatch {
    events: Arc<Mutex<Vec<(Key, bool)>>>,
}

impl InputCallback for KeyLatch {
    fn add_char(&mut self, _: u32) {}

    fn set_key_state(&mut self, key: Key, down: bool) {
        self.events
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push((key, down));
    }
}

/// What one frame does with the keys: the actions of the keys pressed since the last frame
/// (each press once, however short), and the keys to treat as held (those down now, and those
/// pressed and released since the last frame, so a tap moves the camera one frame's step).
#[derive(Debug, Default, PartialEq)]
struct FrameKeys {
    pressed: Vec<Key>,
    held: Vec<Key>,
}

impl KeyLatch {
    /// Takes the events since the last frame; `down` is the set of keys down before them,
    /// updated to after them. A repeated press of a key already down (auto-repeat) is not a
    /// new press.
    fn frame(&self, down: &mut Vec<Key>) -> FrameKeys {
        let events = std::mem::take(&mut *self.events.lock().unwrap_or_else(|e| e.into_inner()));
        let mut out = FrameKeys {
            pressed: Vec::new(),
            held: down.clone(),
        };
        for (k, is_down) in events {
            if is_down {
                if !down.contains(&k) {
                    down.push(k);
                    out.pressed.push(k);
                    if !out.held.contains(&k) {
                        out.held.push(k);
                    }
                }
            } else {
                down.retain(|d| *d != k);
            }
        }
        out
    }
}

/// The error when no window opens: what to check, without Rust's debug formatting.
fn no_window(e: minifb::Error) -> anyhow::Error {
    let display = match std::env::var("DISPLAY") {
        Ok(d) if !d.is_empty() => format!("DISPLAY is `{d}`"),
        Ok(_) => "DISPLAY is empty".to_string(),
        Err(_) => "DISPLAY is not set".to_string(),
    };
    anyhow::anyhow!(
        "cannot open a window ({display}; `view` needs an X11 display, or run it with \
         `--script FILE` to replay a session without one): {e}"
    )
}

/// On X11 systems, refuses before any work when no display is named (the window could not
/// open after the solve).
fn check_display() -> anyhow::Result<()> {
    if cfg!(all(unix, not(target_os = "macos"))) && std::env::var_os("WAYLAND_DISPLAY").is_none() {
        match std::env::var("DISPLAY") {
            Ok(d) if !d.is_empty() => {}
            _ => return Err(no_window(minifb::Error::WindowCreate("no display".into()))),
        }
    }
    Ok(())
}

/// The window loop: keys to actions, one frame per window update, until Esc or close. The
/// picture is the latest solution `updates` brought (the window opens before the first, with
/// the solve's progress in its status strip); an error of the solve ends the loop with it.
fn window(
    updates: &crossbeam_channel::Receiver<Update>,
    progress: &SolveProgress<'_>,
    opts: engine::frame::FrameOptions,
    exposure: f64,
) -> anyhow::Result<()> {
    let (w, frame_h) = (opts.width, opts.height);
    // The status line's strip above the frame.
    let h = frame_h + app::viewer::STATUS_STRIP;
    let mut win = Window::new(
        "pixelflow-sim view",
        w as usize,
        h as usize,
        WindowOptions::default(),
    )
    .map_err(no_window)?;
    let latch = KeyLatch::default();
    win.set_input_callback(Box::new(latch.clone()));
    let mut viewer: Option<Viewer> = None;
    let mut solved = false;
    let mut down = Vec::new();
    let mut buf = vec![0u32; w as usize * h as usize];
    let mut last = Instant::now();
    let mut seconds = 0.0;
    while win.is_open() && !win.is_key_down(Key::Escape) {
        if let Some(p) = latest(updates, &mut solved)? {
            match viewer.as_mut() {
                Some(v) => v.replace(Arc::new(p)),
                None => viewer = Some(Viewer::new(Arc::new(p), opts.clone())?),
            }
        }
        let keys = latch.frame(&mut down);
        let now = Instant::now();
        let dt = (now - last).as_secs_f64();
        last = now;
        seconds = 0.9 * seconds + 0.1 * dt;
        let rgb = match viewer.as_mut() {
            Some(v) => {
                act(v, &keys, dt);
                v.frame()?;
                let mut status = v.status(seconds);
                if let Some(line) = progress.line().filter(|_| !solved) {
                    status = format!("{line}  |  {status}");
                }
                v.display(exposure, Some(&status))?
            }
            None => {
                let black = vec![0u8; 3 * (w * frame_h) as usize];
                let line = progress.line().unwrap_or_else(|| "loading".into());
                app::viewer::with_status(&black, w, frame_h, &line)?
            }
        };
        for (px, c) in buf.iter_mut().zip(rgb.chunks_exact(3)) {
            *px = (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32;
        }
        win.update_with_buffer(&buf, w as usize, h as usize)?;
    }
    Ok(())
}

/// The newest solution among the updates waiting (older snapshots are dropped unseen), setting
/// `solved` when it is the final one; the solve's error if it failed.
fn latest(
    updates: &crossbeam_channel::Receiver<Update>,
    solved: &mut bool,
) -> anyhow::Result<Option<app::prepare::Prepared>> {
    let mut newest = None;
    while let Ok(u) = updates.try_recv() {
        match u {
            Update::Snapshot(p) => newest = Some(p),
            Update::Done(done) => {
                newest = Some(done?);
                *solved = true;
            }
        }
    }
    Ok(newest)
}

/// Applies one frame's keys to the viewer: presses once each, held keys for `dt` seconds.
fn act(viewer: &mut Viewer, keys: &FrameKeys, dt: f64) {
    let shift = keys
        .held
        .iter()
        .any(|k| matches!(k, Key::LeftShift | Key::RightShift));
    let prepared = Arc::clone(viewer.prepared());
    let scene = &prepared.scene;
    for &k in &keys.pressed {
        if let Some(a) = pressed(k, shift) {
            viewer.state.press(a, scene);
        }
    }
    let held: Vec<Action> = keys.held.iter().filter_map(held).collect();
    viewer.state.advance(&held, dt.min(0.25), scene);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Events fed through the callback the window calls, as a window would deliver them.
    fn feed(latch: &KeyLatch, events: &[(Key, bool)]) {
        let mut cb: Box<dyn InputCallback> = Box::new(latch.clone());
        for &(k, down) in events {
            cb.set_key_state(k, down);
        }
    }

    /// Regression: a key pressed and released within one frame (a tap at 3 fps) was lost; now
    /// it acts exactly once, at any frame rate, and moves the camera for one frame.
    #[test]
    fn a_tap_within_one_frame_acts_once() {
        let latch = KeyLatch::default();
        let mut down = Vec::new();
        feed(
            &latch,
            &[
                (Key::P, true),
                (Key::P, false),
                (Key::W, true),
                (Key::W, false),
            ],
        );
        let f = latch.frame(&mut down);
        assert_eq!(f.pressed, [Key::P, Key::W]);
        assert_eq!(f.held, [Key::P, Key::W]);
        assert!(down.is_empty());
        // The next frame: nothing more.
        assert_eq!(latch.frame(&mut down), FrameKeys::default());
        // A key held across frames, with auto-repeat presses: one press, held every frame
        // until released.
        feed(&latch, &[(Key::M, true), (Key::M, true)]);
        let f = latch.frame(&mut down);
        assert_eq!(
            (f.pressed.as_slice(), f.held.as_slice()),
            (&[Key::M][..], &[Key::M][..])
        );
        feed(&latch, &[(Key::M, true)]);
        let f = latch.frame(&mut down);
        assert_eq!((f.pressed.len(), f.held.as_slice()), (0, &[Key::M][..]));
        feed(&latch, &[(Key::M, false)]);
        let f = latch.frame(&mut down);
        assert_eq!((f.pressed.len(), f.held.as_slice()), (0, &[Key::M][..]));
        assert_eq!(latch.frame(&mut down), FrameKeys::default());
        // Two taps within one frame are two presses.
        feed(
            &latch,
            &[
                (Key::P, true),
                (Key::P, false),
                (Key::P, true),
                (Key::P, false),
            ],
        );
        assert_eq!(latch.frame(&mut down).pressed, [Key::P, Key::P]);
    }
}
