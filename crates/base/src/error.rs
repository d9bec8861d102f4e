//! Errors of the library, and the exit codes the binary maps them to.
//!
//! Every fallible public function returns [`Result`]. The variants separate three parties:
//! what the *user* got wrong (a scene file, an option, a request over a limit, a solution file:
//! exit code 2), what went wrong while running that is nobody's mistake (an I/O failure writing
//! output, an encoder that fails: exit code 1), and what is a bug of this program
//! ([`Error::Internal`], exit code 1, said as such). Errors carry what a caller needs to act on
//! them (the location, the option, the limit, the path). Input errors carry the file, and where
//! known the line and the key, so a message reads like a compiler's:
//! `scenes/foo.toml:12: materials[2].reflectance: component 0 is 1.2, must be in [0, 1)`.
//!
//! [`Error::Inconsistent`] is the one kind whose party depends on where the data came from:
//! samples or patches that no solve produces (non-finite values, missing vertices, values that
//! overflow f32). Read from a solution file, the file is corrupt (the jobs report it as
//! [`Error::Solution`], exit 2); produced by this run's own solve, it is a bug (the jobs report
//! it as [`Error::Internal`]). Library code never panics on bad input; a panic is a bug.
//!
//! Options and settings are named as the library knows them (`aa`, `width`, `page-size`,
//! `render.aa`), never as one front end spells them: the command line turns the names of its
//! own flags into the flags (`--aa`) with [`Error::name_options`], so flag names live in the
//! binary alone and a library caller reads the setting it passed.

use std::fmt;
use std::path::{Path, PathBuf};

/// Exit code for success.
pub const EXIT_OK: i32 = 0;
/// Exit code for a failure while running (I/O, resources).
pub const EXIT_FAILURE: i32 = 1;
/// Exit code for bad input or usage.
pub const EXIT_BAD_INPUT: i32 = 2;

/// Where in an input file something is: the file, and where known the line and the key path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// The file the input came from.
    pub file: PathBuf,
    /// 1-based line number, when known.
    pub line: Option<usize>,
    /// Dotted key path inside the file (`materials[2].reflectance`), when known.
    pub key: Option<String>,
}

impl Location {
    /// A location naming only a file.
    pub fn file(file: impl AsRef<Path>) -> Self {
        Location {
            file: file.as_ref().to_path_buf(),
            line: None,
            key: None,
        }
    }

    /// This location with a line number.
    pub fn at_line(mut self, line: usize) -> Self {
        self.line = Some(line);
        self
    }

    /// This location with a key path.
    pub fn with_key(mut self, key: impl Into<String>) -> Self {
        self.key = Some(key.into());
        self
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(key) = &self.key {
            write!(f, ": {key}")?;
        }
        Ok(())
    }
}

/// What is wrong with a solution file (`.pfsol`), for [`Error::Solution`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SolutionProblem {
    /// The file cannot be read, or does not start with the solution magic.
    NotASolution,
    /// The file ends before its declared contents.
    Truncated,
    /// The checksum does not match, or the contents are inconsistent.
    Corrupt,
    /// Written by another format version.
    Version {
        /// The version in the file.
        found: u32,
        /// The version this build reads.
        supported: u32,
    },
    /// The solution belongs to another scene (or the scene changed since it was solved).
    SceneMismatch,
}

/// The library's error type. Each variant is a failure a caller can act on; all of them
/// display as one line in the `file:line: key: what` form the command line prints.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad input: a scene, OBJ, MTL or image file the user gave does not parse or holds an
    /// invalid value, at a location (file, and where known line and key).
    #[error("{location}: {message}")]
    Input {
        /// Where the problem is.
        location: Location,
        /// What is wrong, and what would be right.
        message: String,
    },
    /// An option or setting that cannot work: an unknown method, an antialiasing count without a
    /// sample pattern, a texture size that is not a power of two, two options that exclude each
    /// other. Displayed as `option value: reason`.
    #[error("{option}{}: {reason}", spaced(value))]
    InvalidOption {
        /// The option or setting by its library name (`aa`, `method`, `render.aa`); a front
        /// end shows it as the user wrote it ([`Error::name_options`]).
        option: String,
        /// The value given.
        value: String,
        /// Why it cannot work, and what would.
        reason: String,
    },
    /// A request larger than a limit of the tool (image side, renderers, texture memory).
    #[error("{what}: {requested} exceeds the limit of {limit}")]
    ResourceLimit {
        /// What was asked for (`width`, `texture-budget`), named as an option is.
        what: String,
        /// The amount asked for.
        requested: u64,
        /// The largest amount accepted.
        limit: u64,
    },
    /// A job whose estimated memory is over the memory limit (`--memory-limit`), refused before
    /// the allocation. Displayed with both amounts in binary units and what the estimate is made
    /// of, so the user sees which setting to lower.
    #[error("{what} needs an estimated {} ({detail}), over the memory limit of {}; {hint}", human_bytes(*.estimate), human_bytes(*.limit))]
    Memory {
        /// The job or stage (`solve of scenes/x.toml`, `textures`, `frame 4096 x 4096`).
        what: String,
        /// Estimated bytes.
        estimate: u64,
        /// The limit in bytes.
        limit: u64,
        /// What the estimate is made of (`quadtrees 1.2 GiB + pair tables 300 MiB`).
        detail: String,
        /// What to change (`lower radiosity.max_depth`); options in backticks, as [`Error::name_options`] spells them.
        hint: String,
    },
    /// A solution file that cannot be used: not a solution, truncated, corrupt, another format
    /// version, or solved for another scene.
    #[error("{}: {message}", path.display())]
    Solution {
        /// The solution file.
        path: PathBuf,
        /// What is wrong, for a caller to act on.
        problem: SolutionProblem,
        /// The same, for a person.
        message: String,
    },
    /// An operating-system I/O failure on a named path.
    #[error("{}: {error}", path.display())]
    Io {
        /// The path that failed.
        path: PathBuf,
        /// The underlying error (shown in the message, deliberately not chained as a `source`:
        /// `anyhow`'s `{:#}` would print it twice).
        error: std::io::Error,
    },
    /// A failure while running that is neither the input's fault nor a bug: a thread that could
    /// not start, an encoder or plotting backend that failed, a check that found a difference.
    #[error("{0}")]
    Runtime(String),
    /// Data that no valid solve produces (see the module documentation): a corrupt solution file
    /// when read from one, a bug when computed in this run.
    #[error("{0}")]
    Inconsistent(String),
    /// A broken invariant of this program: a bug, never the user's input.
    #[error("internal error: {0} (this is a bug in pixelflow-sim; please report it with the command that caused it)")]
    Internal(String),
}

impl Error {
    /// An input error at `location`.
    pub fn input(location: Location, message: impl Into<String>) -> Self {
        Error::Input {
            location,
            message: message.into(),
        }
    }

    /// An invalid value `value` of option `option`, with the reason.
    pub fn invalid_option(
        option: impl Into<String>,
        value: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        Error::InvalidOption {
            option: option.into(),
            value: value.into(),
            reason: reason.into(),
        }
    }

    /// A request of `requested` for `what` over the `limit`.
    pub fn limit(what: impl Into<String>, requested: u64, limit: u64) -> Self {
        Error::ResourceLimit {
            what: what.into(),
            requested,
            limit,
        }
    }

    /// Renames the option of an [`Error::InvalidOption`] or the quantity of an
    /// [`Error::ResourceLimit`] through `spell` (the command line maps `aa` to `--aa`); names
    /// `spell` returns `None` for, and every other variant, are left as they are.
    /// An option's reason and a memory error's hint may name options in backticks
    /// (`` `memory-limit` ``): those are spelt too, without the backticks.
    pub fn name_options(&mut self, spell: impl Fn(&str) -> Option<String>) {
        let (name, reason) = match self {
            Error::InvalidOption { option, reason, .. } => (option, Some(reason)),
            Error::ResourceLimit { what, .. } => (what, None),
            Error::Memory { hint, .. } => {
                *hint = spell_quoted(hint, &spell);
                return;
            }
            _ => return,
        };
        if let Some(spelt) = spell(name) {
            *name = spelt;
        }
        if let Some(reason) = reason {
            *reason = spell_quoted(reason, &spell);
        }
    }

    /// A solution file error on `path`.
    pub fn solution(
        path: impl AsRef<Path>,
        problem: SolutionProblem,
        message: impl Into<String>,
    ) -> Self {
        Error::Solution {
            path: path.as_ref().to_path_buf(),
            problem,
            message: message.into(),
        }
    }

    /// A broken invariant of this program (a bug).
    pub fn internal(message: impl Into<String>) -> Self {
        Error::Internal(message.into())
    }

    /// Data that no valid solve produces ([`Error::Inconsistent`]).
    pub fn inconsistent(message: impl Into<String>) -> Self {
        Error::Inconsistent(message.into())
    }

    /// An I/O error on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            error: source,
        }
    }

    /// The process exit code this error maps to: 2 for bad input (a file, an option, a request
    /// over a limit, an unusable solution file), 1 for a failure while running.
    ///
    /// A missing or unreadable *input* file is reported as [`Error::Input`] (or
    /// [`Error::Solution`]) by the loaders, so it maps to 2; [`Error::Io`] is reserved for
    /// failures while running (writing output).
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. }
            | Error::InvalidOption { .. }
            | Error::ResourceLimit { .. }
            | Error::Memory { .. }
            | Error::Solution { .. } => EXIT_BAD_INPUT,
            Error::Io { .. } | Error::Runtime(_) | Error::Inconsistent(_) | Error::Internal(_) => {
                EXIT_FAILURE
            }
        }
    }
}

/// `text` with every backticked name that `spell` knows replaced by its spelling.
fn spell_quoted(text: &str, spell: &impl Fn(&str) -> Option<String>) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(open) = rest.find('`') {
        let Some(len) = rest[open + 1..].find('`') else {
            break;
        };
        let name = &rest[open + 1..open + 1 + len];
        out.push_str(&rest[..open]);
        match spell(name) {
            Some(spelt) => out.push_str(&spelt),
            None => out.push_str(&rest[open..open + len + 2]),
        }
        rest = &rest[open + len + 2..];
    }
    out.push_str(rest);
    out
}

/// `1.5 MiB` style: bytes in binary units with one decimal (whole bytes below 1 KiB).
pub fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut x = b as f64;
    let mut u = 0;
    while x >= 1024.0 && u + 1 < UNITS.len() {
        x /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{x:.1} {}", UNITS[u])
    }
}

/// `" value"`, or nothing for an empty value (an option that takes none, like `--walkthrough`).
fn spaced(value: &str) -> String {
    if value.is_empty() {
        String::new()
    } else {
        format!(" {value}")
    }
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn location_formats_like_a_compiler() {
        let loc = Location::file("scenes/a.toml")
            .at_line(12)
            .with_key("materials[2].reflectance");
        let e = Error::input(loc, "component 0 is 1.2, must be in [0, 1)");
        assert_eq!(
            e.to_string(),
            "scenes/a.toml:12: materials[2].reflectance: component 0 is 1.2, must be in [0, 1)"
        );
        assert_eq!(e.exit_code(), EXIT_BAD_INPUT);
        assert_eq!(Error::Runtime("x".into()).exit_code(), EXIT_FAILURE);
    }

    #[test]
    fn a_front_end_spells_only_the_names_it_knows() {
        let flag = |name: &str| (name == "aa" || name == "width").then(|| format!("--{name}"));
        let mut e = Error::invalid_option("aa", "3", "takes 1, 4 or 16");
        e.name_options(flag);
        assert_eq!(e.to_string(), "--aa 3: takes 1, 4 or 16");
        let mut e = Error::limit("width", 70000, 65536);
        e.name_options(flag);
        assert_eq!(e.to_string(), "--width: 70000 exceeds the limit of 65536");
        let mut e = Error::invalid_option("render.aa", "3", "takes 1, 4 or 16");
        e.name_options(flag);
        assert_eq!(e.to_string(), "render.aa 3: takes 1, 4 or 16");
        let mut e = Error::invalid_option("exr", "a.png", "is also `output`, not `render.aa`");
        e.name_options(|n| (n == "output").then(|| "-o".to_string()));
        assert_eq!(e.to_string(), "exr a.png: is also -o, not `render.aa`");
        let mut e = Error::Runtime("aa".into());
        e.name_options(flag);
        assert_eq!(e.to_string(), Error::Runtime("aa".into()).to_string());
    }

    #[test]
    fn an_internal_error_says_it_is_a_bug_and_exits_1() {
        let e = Error::internal("mesh missing after build");
        assert_eq!(e.exit_code(), EXIT_FAILURE);
        let text = e.to_string();
        assert!(
            text.starts_with("internal error: mesh missing after build"),
            "{text}"
        );
        assert!(text.contains("this is a bug"), "{text}");
        assert_eq!(
            Error::inconsistent("a NaN sample").exit_code(),
            EXIT_FAILURE
        );
    }

    #[test]
    fn every_variant_displays_one_line_with_its_exit_code() {
        let cases = [
            (
                Error::invalid_option("aa", "3", "antialiasing takes 1, 4 or 16 samples"),
                "aa 3: antialiasing takes 1, 4 or 16 samples",
                EXIT_BAD_INPUT,
            ),
            (
                Error::limit("width", 70000, 65536),
                "width: 70000 exceeds the limit of 65536",
                EXIT_BAD_INPUT,
            ),
            (
                Error::Memory {
                    what: "solve of a.toml".into(),
                    estimate: 3 << 30,
                    limit: 1 << 30,
                    detail: "quadtrees 3.0 GiB".into(),
                    hint: "lower radiosity.min_depth".into(),
                },
                "solve of a.toml needs an estimated 3.0 GiB (quadtrees 3.0 GiB), over the memory \
                 limit of 1.0 GiB; lower radiosity.min_depth",
                EXIT_BAD_INPUT,
            ),
            (
                Error::solution("a.pfsol", SolutionProblem::Truncated, "truncated"),
                "a.pfsol: truncated",
                EXIT_BAD_INPUT,
            ),
            (
                Error::io("out/x.png", std::io::Error::other("disk full")),
                "out/x.png: disk full",
                EXIT_FAILURE,
            ),
        ];
        for (e, text, code) in cases {
            assert_eq!(e.to_string(), text);
            assert_eq!(e.exit_code(), code);
        }
    }
}
