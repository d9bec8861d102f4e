//! What every job starts from: its [`Context`] (the memory limit, the instruction set and the
//! observer, passed down explicitly: the library holds no process-wide setting), its [`Input`]
//! (a scene file, or a solution file and the scene it names, loaded and checked cheaply so that
//! every option can be validated before any solve), and the texture options every command that
//! draws textures shares.

use std::path::{Path, PathBuf};

use base::error::{Error, Result};
use base::method::{check_texture_side, Method, Placement};
use base::output::Outputs;
use base::progress::Observer;
use engine::frame::FrameOptions;
use lanes::Isa;
use radiosity::{self, file as solution_file};
use reconstruction::texture::{Extent, SizePolicy, TextureSet};
use reconstruction::Estimator;
use scene::{load_scene_with, LoadOptions, Scene};

/// What a job may use, given by its caller and passed down explicitly (the library holds no
/// process-wide setting): the memory limit every estimate is checked against, the instruction
/// set frames run with, and the observer progress goes to.
#[derive(Clone)]
pub struct Context<'a> {
    /// Bytes a job may hold ([`crate::budget`]'s estimates are refused above it); `u64::MAX`: none.
    pub memory_limit: u64,
    /// The instruction set the frames' kernels run with (a choice of speed: the images are the
    /// same for every one).
    pub isa: Isa,
    /// Where progress and trace lines go.
    pub observer: &'a dyn Observer,
    /// The registry every file the job writes goes through (a clone in the caller's signal
    /// handler removes the temporaries of an interrupted write).
    pub outputs: Outputs,
}

impl<'a> Context<'a> {
    /// No memory limit, the widest instruction set the CPU has, progress to `observer`.
    pub fn new(observer: &'a dyn Observer) -> Context<'a> {
        Context {
            memory_limit: u64::MAX,
            isa: Isa::detect(),
            observer,
            outputs: Outputs::new(),
        }
    }

    /// This context with a memory limit of `bytes`.
    pub fn with_memory_limit(self, bytes: u64) -> Context<'a> {
        Context {
            memory_limit: bytes,
            ..self
        }
    }

    /// This context with progress going to `observer`.
    pub fn with_observer<'b>(&self, observer: &'b dyn Observer) -> Context<'b> {
        Context {
            memory_limit: self.memory_limit,
            isa: self.isa,
            observer,
            outputs: self.outputs.clone(),
        }
    }

    /// This context writing through `outputs`.
    pub fn with_outputs(self, outputs: Outputs) -> Context<'a> {
        Context { outputs, ..self }
    }

    /// This context with the instruction set `isa`.
    pub fn with_isa(self, isa: Isa) -> Context<'a> {
        Context { isa, ..self }
    }

    /// Frame options for a `width` x `height` image with the defaults and this context's
    /// instruction set.
    pub fn frame_options(&self, width: u32, height: u32) -> FrameOptions {
        FrameOptions {
            isa: self.isa,
            ..FrameOptions::new(width, height)
        }
    }
}

impl Default for Context<'static> {
    /// [`Context::new`] with no observer ([`base::progress::SILENT`]).
    fn default() -> Context<'static> {
        Context::new(&base::progress::SILENT)
    }
}

/// A job's input, loaded and checked but not solved: the scene, and the solution file if the
/// input was one.
#[derive(Debug, Clone)]
pub struct Input {
    /// The path the user gave.
    pub path: PathBuf,
    /// The scene (from the file itself, or the one the solution file names).
    pub scene: Scene,
    /// The solution file, when the input is one (its envelope is checked already).
    pub solution_file: Option<PathBuf>,
    /// The RRPs' derivative estimator (`--estimator`; default [`Estimator::default`]); the RRPs
    /// are built with it from the samples, whether solved in this run or read from a file.
    pub estimator: Estimator,
    /// How many levels below the solver's leaves the RRPs and the mesh's vertices follow the
    /// edges of the spots' light (`--sharp-levels`; default
    /// [`reconstruction::sharp::DEFAULT_LEVELS`]; 0: the spots' light is reconstructed from the
    /// samples like any other).
    pub sharp_levels: u32,
    /// The largest input file read for it, bytes (its load options'; a solution file is read
    /// whole under the same cap).
    pub input_limit: u64,
}

impl Input {
    /// Loads a scene file, or a solution file's scene (checking the solution file's magic,
    /// version, length and checksum). A file is a solution file by its magic bytes, or by its
    /// `.pfsol` extension (so an empty or damaged one is reported as a bad solution file, not as
    /// a scene that fails to parse). Nothing is solved.
    pub fn load(path: &Path) -> Result<Input> {
        Input::load_with(path, None)
    }

    /// [`Input::load`], a solution file's scene read from `scene` when given (`--scene`: the
    /// scene moved away from where the solution file says; its hash is still checked against
    /// the solution). Errors if `scene` is given for an input that is not a solution file.
    pub fn load_with(path: &Path, scene: Option<&Path>) -> Result<Input> {
        Input::load_opts(path, scene, &LoadOptions::default())
    }

    /// [`Input::load_with`] with the command line's scene options (`-D`, `--camera`,
    /// `--strict`), applied to the scene file or to a solution file's scene.
    pub fn load_opts(path: &Path, scene: Option<&Path>, opts: &LoadOptions) -> Result<Input> {
        let named_solution = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case(SOLUTION_EXTENSION));
        if named_solution || is_solution_file(path) {
            let scene_path = match scene {
                Some(s) => s.to_path_buf(),
                None => solution_file::read_scene_path_up_to(path, opts.input_limit)?,
            };
            Ok(Input {
                path: path.to_path_buf(),
                scene: load_scene_with(&scene_path, opts)?,
                solution_file: Some(path.to_path_buf()),
                estimator: Estimator::default(),
                sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
                input_limit: opts.input_limit,
            })
        } else {
            if let Some(s) = scene {
                return Err(Error::invalid_option(
                    "scene",
                    s.display().to_string(),
                    format!(
                        "names the scene of a solution file, and {} is a scene file",
                        path.display()
                    ),
                ));
            }
            Ok(Input {
                path: path.to_path_buf(),
                scene: load_scene_with(path, opts)?,
                solution_file: None,
                estimator: Estimator::default(),
                sharp_levels: reconstruction::sharp::DEFAULT_LEVELS,
                input_limit: opts.input_limit,
            })
        }
    }
}

/// One line for a scene's notes (repairs that change nothing the image shows), for the commands
/// that do not list them: how many, and the command that does; `None` without notes.
pub fn notes_line(scene: &scene::Scene) -> Option<String> {
    let n = scene.notes.len();
    (n > 0).then(|| {
        format!(
            "{n} repair{} of the scene's input that change nothing the image shows (faces split \
             or triangulated, repeats counted once): `pixelflow-sim check {}` lists them",
            if n == 1 { "" } else { "s" },
            scene.source.display()
        )
    })
}

/// The extension of solution files (`solve -o x.pfsol`).
pub(crate) const SOLUTION_EXTENSION: &str = "pfsol";

/// Whether `path` is a solution file (by its magic bytes) rather than a scene. Only a regular
/// file is probed: reading a pipe's first bytes would take them from the scene read next
/// (`check <(cat scene.toml)`), and a solution names its scene relative to its own folder,
/// which a pipe does not have.
pub(crate) fn is_solution_file(path: &Path) -> bool {
    use std::io::Read;
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return false;
    }
    let mut magic = [0u8; 8];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .map(|_| &magic == solution_file::MAGIC)
        .unwrap_or(false)
}

/// Command-line choices of the texture methods (all optional; the scene's `[render]` gives the
/// defaults).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TextureOptions {
    /// One texture side for every polygon (`--texture-size`, a power of two): the longer side,
    /// the shorter following the polygon's aspect ([`reconstruction::texture::Extent`]).
    pub size: Option<u32>,
    /// A texture memory budget in bytes at 12 bits per channel with mip chains
    /// (`--texture-budget`).
    pub budget: Option<u64>,
    /// The bicubic filter's (B, C) (`--bicubic B,C`; default Mitchell–Netravali 1/3, 1/3).
    pub bicubic: Option<(f32, f32)>,
    /// Where the texels sit, by name (`--texel-placement centre|corner`), checked by
    /// [`TextureOptions::placement`] in the plan.
    pub placement: Option<String>,
    /// Most lookups along a footprint's longer axis (`--anisotropy N`; default 1, isotropic as
    /// the paper's hardware), checked with the frame's options
    /// ([`engine::frame::FrameOptions::anisotropy`]).
    pub anisotropy: Option<u32>,
}

impl TextureOptions {
    /// The size policy these options choose for `scene`, checked against it: a size (a power of
    /// two in range), a budget (at least what 1 x 1 textures of every polygon of the scene take),
    /// or the scene's `scene_texture_policy`. Giving both a size and a budget is an error.
    pub fn policy(&self, scene: &Scene) -> Result<SizePolicy> {
        let policy = match (self.size, self.budget) {
            (Some(n), Some(_)) => {
                return Err(Error::invalid_option(
                    "texture-size",
                    n.to_string(),
                    "excludes `texture-budget`; give one of them",
                ))
            }
            (Some(n), None) => {
                check_texture_side("texture-size", n)?;
                SizePolicy::Fixed(n)
            }
            (None, Some(b)) => SizePolicy::Budget(b),
            (None, None) => scene_texture_policy(scene),
        };
        // Whether a budget can be met depends only on the polygon count (every texture can
        // shrink to 1 x 1), which the scene gives before any solve.
        TextureSet::sizes(&vec![Extent::default(); scene.polygons.len()], policy)?;
        Ok(policy)
    }

    /// The texel placement: `--texel-placement` if given (an unknown name is an
    /// [`Error::InvalidOption`] naming it), else the scene's `[render] texel_placement`.
    pub fn placement(&self, scene: &Scene) -> Result<Placement> {
        match &self.placement {
            Some(name) => Placement::parse_option("texel-placement", name),
            None => Ok(scene.render.texel_placement),
        }
    }

    /// The anisotropy of the texture lookups: `--anisotropy`, else 1 (isotropic).
    pub fn anisotropy(&self) -> u32 {
        self.anisotropy.unwrap_or(1)
    }

    /// `method` with these options' bicubic parameters applied (checked).
    pub fn method(&self, method: Method) -> Result<Method> {
        match self.bicubic {
            Some((b, c)) => method.with_bicubic(b, c),
            None => Ok(method),
        }
    }
}

/// The texture size policy a scene asks for: `[render] texture_size` 0 means per polygon from
/// its quadtree depth, any other value one fixed size.
pub fn scene_texture_policy(scene: &Scene) -> SizePolicy {
    match scene.render.texture_size {
        0 => SizePolicy::FromDepth,
        n => SizePolicy::Fixed(n),
    }
}
