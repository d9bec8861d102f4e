//! The application: what pixelflow-sim's commands run on top of the stages. A job starts from
//! its [`context`] (the memory limit, the instruction set and the observer, passed down
//! explicitly; an [`Input`] loaded and checked before any solve), makes the scene ready to draw
//! ([`mod@prepare`]: the solution and its RRPs, the textures and mesh built on first use), draws
//! [`frames`], and runs one of the [`commands`]. Beside them: the memory [`budget`] every job is
//! checked against before it allocates ([`memory`] estimates it), the [`viewer`]'s frame source,
//! the text [`report`]s the binary prints, the [`rates`] timing commands share and the [`text`]
//! drawn into the viewer's status strip.
//!
//! The application has no user interface: it prints nothing, reads no environment variables and
//! reports progress through [`base::progress::Observer`]. The studies built on it live in the
//! `study` crate, file formats in `imageio` and `export`.

#![forbid(unsafe_code)]

pub mod context;
pub mod budget;
pub mod prepare;
pub mod memory;
pub mod frames;
pub mod rates;
pub mod commands;
pub mod report;
pub mod text;
pub mod viewer;

pub use context::{notes_line, Context, Input, TextureOptions};
pub use frames::{
    render_frame, render_frame_in, render_frame_in_observed, render_frame_observed, reserve_frames,
    REFERENCE_STAGE,
};
pub use prepare::{prepare, prepare_path, prepare_progressively, seams_of, spot_light, Prepared};
