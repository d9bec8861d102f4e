//! Errors of the library, and the exit codes the binary maps them to.
//!
//! Every fallible public function returns [`Result`]. The variants separate what the *user* got
//! wrong (a scene file, an argument, a solution file: exit code 2) from what went wrong while
//! running (an I/O failure writing output, an internal limit: exit code 1). Input errors carry the
//! file, and where known the line and the key, so a message reads like a compiler's:
//! `scenes/foo.toml:12: materials[2].reflectance: component 0 is 1.2, must be in [0, 1)`.
//! Library code never panics on bad input; a panic is a bug.

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

/// The library's error type.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Bad input: a scene, OBJ, solution or image file the user gave is invalid.
    #[error("{location}: {message}")]
    Input {
        /// Where the problem is.
        location: Location,
        /// What is wrong, and what would be right.
        message: String,
    },
    /// Bad usage: an argument value that cannot work (an image size of 0, an unknown method).
    #[error("{0}")]
    Usage(String),
    /// An operating-system I/O failure on a named path.
    #[error("{}: {error}", path.display())]
    Io {
        /// The path that failed.
        path: PathBuf,
        /// The underlying error (shown in the message, deliberately not chained as a `source`:
        /// `anyhow`'s `{:#}` would print it twice).
        error: std::io::Error,
    },
    /// A failure while running that is not the input's fault.
    #[error("{0}")]
    Runtime(String),
}

impl Error {
    /// An input error at `location`.
    pub fn input(location: Location, message: impl Into<String>) -> Self {
        Error::Input {
            location,
            message: message.into(),
        }
    }

    /// An I/O error on `path`.
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            error: source,
        }
    }

    /// The process exit code this error maps to: 2 for bad input or usage, 1 otherwise.
    ///
    /// A missing or unreadable *input* file is reported as [`Error::Input`] by the loaders, so it
    /// maps to 2; [`Error::Io`] is reserved for failures while running (writing output).
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Input { .. } | Error::Usage(_) => EXIT_BAD_INPUT,
            Error::Io { .. } | Error::Runtime(_) => EXIT_FAILURE,
        }
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
}
