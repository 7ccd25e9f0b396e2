//! Errors of every stage: one `#[non_exhaustive]` enum, so callers match on what went wrong, not on text.

use std::path::PathBuf;

/// Everything that can go wrong in clipsat. Input problems name the file, field or argument at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened, read or written.
    #[error("{}: {action}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("cannot read", "cannot write").
        action: &'static str,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// A terrain file is malformed: empty, truncated, wrong magic, or an unsupported layout.
    #[error("{}: {reason}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A terrain declares more samples than the memory limit allows; refused before allocating.
    #[error(
        "{}: declared size {width} x {height} = {samples} samples is over the limit of {limit} samples \
         (raise it with --max-samples if this is intended)",
        path.display()
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Declared width in samples.
        width: u64,
        /// Declared height in samples.
        height: u64,
        /// width * height.
        samples: u64,
        /// The limit in force.
        limit: u64,
    },
    /// A file's length does not match the size its format or the given dimensions imply.
    #[error("{}: file is {actual} bytes, expected {expected}", path.display())]
    SizeMismatch {
        /// The file.
        path: PathBuf,
        /// The file's length in bytes.
        actual: u64,
        /// What was expected, in words ("2884802 bytes (1201 x 1201 int16)").
        expected: String,
    },
    /// A height sample is NaN or infinite.
    #[error("{}: sample at column {x}, row {y} is {value}; heights must be finite", path.display())]
    NonFinite {
        /// The file (or `<memory>`).
        path: PathBuf,
        /// Column.
        x: u32,
        /// Row.
        y: u32,
        /// The offending value.
        value: f32,
    },
    /// A budget profile or scene field is missing, mistyped or out of range.
    #[error("{source_name}: field `{field}`: {reason}")]
    Config {
        /// The profile or scene (shipped name or path).
        source_name: String,
        /// The field at fault, dotted (`clipmap.n`).
        field: String,
        /// Why it is refused.
        reason: String,
    },
    /// A command-line argument is invalid.
    #[error("argument `{arg}`: {reason}")]
    Arg {
        /// The argument.
        arg: String,
        /// Why it is refused.
        reason: String,
    },
    /// A value handed to the library is refused (an option, a plan for another frame, an index); names
    /// what, in the library's words (the binary maps it to its flags).
    #[error("{what}: {reason}")]
    Invalid {
        /// What was refused.
        what: String,
        /// Why.
        reason: String,
    },
    /// The terrain's heights are finite but too extreme for a stage's arithmetic (its f32 values
    /// overflow): refused with the stage and the place, never a panic or a silent infinity.
    #[error("terrain: {0}")]
    Terrain(String),
    /// A camera is unusable (NaN, zero look direction, ...).
    #[error("camera: {0}")]
    Camera(String),
    /// A fixed-capacity per-frame collection would overflow: the profile's maximum is too small.
    #[error("capacity exceeded: {what} needs more than {capacity}")]
    Capacity {
        /// The collection.
        what: &'static str,
        /// Its capacity.
        capacity: usize,
    },
    /// No GPU adapter could be created.
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// The GPU failed after start-up (device lost, out of memory, validation).
    #[error("GPU: {0}")]
    Gpu(String),
}

/// Result with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An [`Error::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, action: &'static str, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            action,
            source,
        }
    }

    /// An [`Error::Format`] for `path`.
    pub fn format(path: impl Into<PathBuf>, reason: impl Into<String>) -> Self {
        Self::Format {
            path: path.into(),
            reason: reason.into(),
        }
    }

    /// An [`Error::Config`].
    pub fn config(
        source_name: impl Into<String>,
        field: impl Into<String>,
        reason: impl Into<String>,
    ) -> Self {
        Self::Config {
            source_name: source_name.into(),
            field: field.into(),
            reason: reason.into(),
        }
    }
}
