//! The one error type of this crate.
//!
//! Every variant that comes from a file names the file, and the line where there is one,
//! so that a user reading the message can open the file at the right place:
//!
//! ```text
//! data/traverse_3.csv:17: boulders: expected '(x, y, z)' tuples, got '(1.0, 2.0]'
//! map file prior.json has format version 7; this segloc reads versions up to 1: upgrade segloc
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

/// Errors from reading, writing or validating maps, detections, traverses and grids.
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// The file could not be opened, read, created or renamed.
    #[error("cannot {action} {}: {source}", path.display())]
    Io {
        /// What was being done: "read", "write", "create a temporary file beside", ...
        action: &'static str,
        /// The file concerned.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file's text does not follow its format.
    #[error("{}: {message}", Location { path, line: *line })]
    Parse {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number, when the problem is on one line.
        line: Option<usize>,
        /// What is wrong, for a user.
        message: String,
    },
    /// A map file written by a newer segloc than this one.
    #[error(
        "{what} {} has format version {found}; this segloc reads versions up to {supported}: upgrade segloc",
        path.display()
    )]
    UnsupportedVersion {
        /// What kind of file: "map file", "detections file".
        what: &'static str,
        /// The file concerned.
        path: PathBuf,
        /// The version found in the file.
        found: u64,
        /// The newest version this build reads ([`crate::MAP_FORMAT_VERSION`]).
        supported: u32,
    },
    /// The file parsed, but its content is not valid (NaN position, negative variance,
    /// duplicate landmark id, ...).
    #[error("{}: {message}", path.display())]
    Invalid {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong, naming the landmark / row.
        message: String,
    },
    /// An in-memory map, detection set or grid is not valid (no file involved).
    #[error("invalid {what}: {message}")]
    InvalidData {
        /// What was being checked: "map", "detection set", "grid".
        what: &'static str,
        /// What is wrong.
        message: String,
    },
}

impl MapError {
    /// A [`MapError::Parse`] on a given 1-based line.
    pub fn parse_at(path: &Path, line: usize, message: impl Into<String>) -> Self {
        MapError::Parse {
            path: path.to_path_buf(),
            line: Some(line),
            message: message.into(),
        }
    }

    /// A [`MapError::Parse`] about the whole file.
    pub fn parse(path: &Path, message: impl Into<String>) -> Self {
        MapError::Parse {
            path: path.to_path_buf(),
            line: None,
            message: message.into(),
        }
    }

    /// A [`MapError::Io`] on reading `path`.
    pub fn read_io(path: &Path, source: std::io::Error) -> Self {
        MapError::Io {
            action: "read",
            path: path.to_path_buf(),
            source,
        }
    }

    /// Attach a file to an [`MapError::InvalidData`] (turning it into [`MapError::Invalid`]);
    /// other variants are returned unchanged.
    pub fn in_file(self, path: &Path) -> Self {
        match self {
            MapError::InvalidData { message, .. } => MapError::Invalid {
                path: path.to_path_buf(),
                message,
            },
            other => other,
        }
    }

    /// The 1-based line number the error points at, if any.
    pub fn line(&self) -> Option<usize> {
        match self {
            MapError::Parse { line, .. } => *line,
            _ => None,
        }
    }
}

/// `path:line` or `path`, for messages.
/// What is wrong with one line (or one field of a line) of a file, said before the reader
/// knows the file and the line number: the reader wraps it in [`MapError::Parse`] with both.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct LineError {
    /// What is wrong, naming the field, e.g. `frame: expected a non-negative integer, got 'x'`.
    pub message: String,
}

impl From<String> for LineError {
    fn from(message: String) -> Self {
        LineError { message }
    }
}

impl From<&str> for LineError {
    fn from(message: &str) -> Self {
        LineError {
            message: message.to_string(),
        }
    }
}

impl From<LineError> for String {
    fn from(e: LineError) -> Self {
        e.message
    }
}

struct Location<'a> {
    path: &'a Path,
    line: Option<usize>,
}

impl fmt::Display for Location<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{line}", self.path.display()),
            None => write!(f, "{}", self.path.display()),
        }
    }
}

/// Shorten a piece of input for an error message (at most `max` characters, with "...").
pub(crate) fn snippet(text: &str, max: usize) -> String {
    let text = text.trim();
    if text.chars().count() <= max {
        text.to_string()
    } else {
        let cut: String = text.chars().take(max).collect();
        format!("{cut}...")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_error_names_file_and_line() {
        let e = MapError::parse_at(Path::new("data/traverse_3.csv"), 17, "boulders: bad");
        assert_eq!(e.to_string(), "data/traverse_3.csv:17: boulders: bad");
        assert_eq!(e.line(), Some(17));
        let e = MapError::parse(Path::new("m.json"), "not a map");
        assert_eq!(e.to_string(), "m.json: not a map");
    }

    #[test]
    fn version_error_reads_well() {
        let e = MapError::UnsupportedVersion {
            what: "map file",
            path: PathBuf::from("prior.json"),
            found: 7,
            supported: 1,
        };
        assert_eq!(
            e.to_string(),
            "map file prior.json has format version 7; this segloc reads versions up to 1: upgrade segloc"
        );
    }

    #[test]
    fn io_error_names_action_and_file() {
        let e = MapError::read_io(
            Path::new("missing.csv"),
            std::io::Error::new(std::io::ErrorKind::NotFound, "No such file"),
        );
        assert_eq!(e.to_string(), "cannot read missing.csv: No such file");
    }

    #[test]
    fn snippet_shortens() {
        assert_eq!(snippet("  abc  ", 5), "abc");
        assert_eq!(snippet("abcdefgh", 3), "abc...");
    }
}
