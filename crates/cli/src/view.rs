//! `view`: the interactive walkthrough window (minifb, X11), or with `--script` a headless
//! replay that writes the last frame. The frames, the camera and the keys' meaning live in
//! `lab::viewer`; this module only turns keys into its actions and shows its pixels.

use std::time::Instant;

use minifb::{Key, KeyRepeat, Window, WindowOptions};

use crate::args::ViewArgs;
use crate::commands::{in_pool, wrote, Settings};
use crate::terminal::Terminal;
use lab::viewer::{Action, Script, Viewer};

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

pub fn view(settings: &Settings, args: ViewArgs) -> anyhow::Result<()> {
    in_pool(args.threads, || -> anyhow::Result<()> {
        let observer = Terminal::new(true, false);
        let ctx = settings.context(&observer);
        let input = lab::jobs::Input::load_opts(
            &args.input,
            args.scene.as_deref(),
            &args.options.load_options(),
        )?;
        let texture = args.texture.options();
        let policy = texture.policy(&input.scene)?;
        let placement = texture.placement(&input.scene)?;
        let script = match &args.script {
            // The script is an input: unreadable or not text is bad input (exit 2).
            Some(path) => Some(Script::parse(
                &base::output::read_text(path).map_err(|e| {
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
            ..engine::frame::FrameOptions::new(args.width, args.height)
        };
        // The viewer's frame (and the screenshot's PNG) under the memory limit, as `render`'s,
        // before the solve.
        lab::jobs::budget::check_frame_options(&opts, (true, false), ctx.memory_limit)?;
        let prepared = lab::jobs::prepare(&ctx, input, policy, placement)?;
        let mut viewer = Viewer::new(&prepared, opts)?;
        let exposure = prepared.scene.display.exposure;
        match (script, &args.screenshot) {
            (Some(script), Some(png)) => {
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
                lab::image::write::write_srgb_png(&ctx.outputs, png, args.width, args.height, rgb)?;
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
            _ => window(&mut viewer, exposure),
        }
    })?
}

/// The window loop: keys to actions, one frame per window update, until Esc or close.
fn window(viewer: &mut Viewer<'_>, exposure: f64) -> anyhow::Result<()> {
    let (w, h) = viewer.size();
    let mut win = Window::new(
        "pixelflow-sim view",
        w as usize,
        h as usize,
        WindowOptions::default(),
    )
    .map_err(|e| {
        anyhow::anyhow!(
            "cannot open a window (is there a display? DISPLAY is {:?}): {e}",
            std::env::var("DISPLAY").ok()
        )
    })?;
    let mut buf = vec![0u32; w as usize * h as usize];
    let mut last = Instant::now();
    let mut seconds = 0.0;
    while win.is_open() && !win.is_key_down(Key::Escape) {
        let shift = win.is_key_down(Key::LeftShift) || win.is_key_down(Key::RightShift);
        // The prepared solution outlives the viewer's borrow: the state can change beside it.
        let scene = &viewer.prepared().scene;
        for k in win.get_keys_pressed(KeyRepeat::No) {
            if let Some(a) = pressed(k, shift) {
                viewer.state.press(a, scene);
            }
        }
        let keys: Vec<Action> = win.get_keys().iter().filter_map(held).collect();
        let now = Instant::now();
        let dt = (now - last).as_secs_f64();
        last = now;
        seconds = 0.9 * seconds + 0.1 * dt;
        viewer.state.advance(&keys, dt.min(0.25), scene);
        viewer.frame()?;
        let rgb = viewer.display(exposure, Some(&viewer.status(seconds)))?;
        for (px, c) in buf.iter_mut().zip(rgb.chunks_exact(3)) {
            *px = (c[0] as u32) << 16 | (c[1] as u32) << 8 | c[2] as u32;
        }
        win.update_with_buffer(&buf, w as usize, h as usize)?;
    }
    Ok(())
}
