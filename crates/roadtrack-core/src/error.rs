//! The library's one error type.

use std::path::PathBuf;

/// Everything that can go wrong in `roadtrack`.
///
/// Variants carry the file, line, column or frame that caused them, so the command line can
/// print a message a user can act on without a backtrace.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A configuration value is outside the range the method supports.
    #[error("invalid {config}.{field}: {reason}")]
    InvalidConfig {
        /// The config struct, e.g. `RelaxationConfig`.
        config: &'static str,
        /// The offending field (`table.field` for a field of a nested table).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A value in a text input file could not be accepted.
    #[error("{}:{line}: column `{column}`: {message}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number (the header is line 1 in CSV files).
        line: u64,
        /// Column name (or 1-based position for header-less formats).
        column: String,
        /// What is wrong.
        message: String,
    },
    /// A file as a whole is malformed (missing header, missing required column, empty).
    #[error("{}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A frame source failed at a given frame.
    #[error("{}: frame {frame}: {message}", path.display())]
    Frame {
        /// The source (file or folder).
        path: PathBuf,
        /// 1-based frame number.
        frame: u32,
        /// What is wrong.
        message: String,
    },
    /// A frame does not have the size of the first frame of its sequence.
    #[error("frame {frame} is {got:?} px, expected {expected:?} px")]
    FrameSize {
        /// 1-based frame number.
        frame: u32,
        /// Width and height found.
        got: (u32, u32),
        /// Width and height of the first frame.
        expected: (u32, u32),
    },
    /// An external program (ffmpeg, ffprobe) is missing or failed.
    #[error("{program}: {message}")]
    External {
        /// The program.
        program: &'static str,
        /// What happened, with the remedy when known.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("cannot access {}", path.display())]
    Io {
        /// The underlying error.
        #[source]
        source: std::io::Error,
        /// The path.
        path: PathBuf,
    },
    /// Encoding or decoding an image failed.
    #[error("image {}", path.display())]
    Image {
        /// The underlying error.
        #[source]
        source: image::ImageError,
        /// The image file.
        path: PathBuf,
    },
    /// A TOML configuration or scenario file could not be read.
    #[error("{}: {message}", path.display())]
    Toml {
        /// The file.
        path: PathBuf,
        /// The TOML parser's message (it names line and column).
        message: String,
    },
    /// Drawing a plot failed (a plotting backend or font error).
    #[error("{}: cannot draw the plot: {message}", path.display())]
    Plot {
        /// The plot file.
        path: PathBuf,
        /// What the plotting library said.
        message: String,
    },
    /// The inputs are consistent individually but cannot be used together.
    #[error("{0}")]
    Invalid(String),
}

/// `Result` with [`Error`] as the default error.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            source,
            path: path.into(),
        }
    }

    /// An [`Error::Parse`] for a value in `path` at `line`, `column`.
    pub fn parse(
        path: impl Into<PathBuf>,
        line: u64,
        column: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::Parse {
            path: path.into(),
            line,
            column: column.into(),
            message: message.into(),
        }
    }

    /// An [`Error::Format`] for `path`.
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            message: message.into(),
        }
    }

    /// An [`Error::InvalidConfig`].
    pub fn config(
        config: &'static str,
        field: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        Error::InvalidConfig {
            config,
            field: field.into(),
            reason: reason.into(),
        }
    }

    /// An [`Error::InvalidConfig`] of a nested table: its field becomes `table.field`, so
    /// that the message names the place in the file (`pf.n_particles`). Other errors pass
    /// through unchanged.
    #[must_use]
    pub fn in_table(self, table: &str) -> Self {
        match self {
            Error::InvalidConfig {
                config,
                field,
                reason,
            } => Error::InvalidConfig {
                config,
                field: format!("{table}.{field}"),
                reason,
            },
            other => other,
        }
    }

    /// An [`Error::InvalidConfig`] found in the values read from `path`, as
    /// `path: field: reason` (the file and the key, not the Rust struct). Other errors pass
    /// through unchanged.
    #[must_use]
    pub fn in_file(self, path: &std::path::Path) -> Self {
        match self {
            Error::InvalidConfig { field, reason, .. } => Error::Format {
                path: path.to_owned(),
                message: format!("{field}: {reason}"),
            },
            Error::Invalid(message) => Error::Format {
                path: path.to_owned(),
                message,
            },
            other => other,
        }
    }
}

/// `Ok` when `value` is finite and within `range`, else an [`Error::InvalidConfig`] for
/// `config.field` saying so (NaN and ±∞ are rejected by name, whatever the range).
///
/// # Errors
/// As above.
pub fn check_range(
    config: &'static str,
    field: &str,
    value: f64,
    range: impl std::ops::RangeBounds<f64>,
) -> Result<()> {
    if !value.is_finite() {
        return Err(Error::config(
            config,
            field,
            format!("must be a finite number, found {value}"),
        ));
    }
    if !range.contains(&value) {
        return Err(Error::config(
            config,
            field,
            format!("must be in {}, found {value}", describe(&range)),
        ));
    }
    Ok(())
}

/// `range` in words: `(0, 1]`, `≥ 0`, `> 0`.
fn describe(range: &impl std::ops::RangeBounds<f64>) -> String {
    use std::ops::Bound::{Excluded, Included, Unbounded};
    match (range.start_bound(), range.end_bound()) {
        (Unbounded, Unbounded) => "any finite value".into(),
        (Included(a), Unbounded) => format!("[{a}, ∞)"),
        (Excluded(a), Unbounded) => format!("({a}, ∞)"),
        (Unbounded, Included(b)) => format!("(−∞, {b}]"),
        (Unbounded, Excluded(b)) => format!("(−∞, {b})"),
        (Included(a), Included(b)) => format!("[{a}, {b}]"),
        (Included(a), Excluded(b)) => format!("[{a}, {b})"),
        (Excluded(a), Included(b)) => format!("({a}, {b}]"),
        (Excluded(a), Excluded(b)) => format!("({a}, {b})"),
    }
}
