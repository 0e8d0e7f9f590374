//! Errors of reading and writing recordings.
//!
//! Each names what it is about (file, topic, row, field) and quotes the value, so a user can fix
//! the input from the one-line message alone. The products above (dvrk-calib) take them into
//! their own error type variant for variant, with the same message.

use std::path::PathBuf;

/// What went wrong reading or writing a recording.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordingError {
    /// A file could not be read, or its content is malformed (the message says where in it).
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    /// A field of a layout or an option is missing or has an invalid value.
    #[error("field `{field}`: {message}")]
    Field { field: String, message: String },
    /// Recorded data that cannot be used: a missing topic or body, too few samples, NaN values.
    #[error("{what}: {message}")]
    Data { what: String, message: String },
    /// A model (the joints a log maps to) could not be used.
    #[error(transparent)]
    Kin(#[from] dvrk_kin::KinError),
    /// The MCAP writer's error.
    #[error(transparent)]
    Sim(#[from] crate::SimError),
}

impl RecordingError {
    /// An error about a file.
    pub fn file(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        RecordingError::File { path: path.into(), message: message.into() }
    }
    /// An error about a field.
    pub fn field(field: impl Into<String>, message: impl Into<String>) -> Self {
        RecordingError::Field { field: field.into(), message: message.into() }
    }
    /// An error about recorded data.
    pub fn data(what: impl Into<String>, message: impl Into<String>) -> Self {
        RecordingError::Data { what: what.into(), message: message.into() }
    }
    /// A name that is not in the recording, answered with the ones that are.
    pub fn unknown(what: &str, name: &str, valid: impl IntoIterator<Item = impl AsRef<str>>) -> Self {
        let valid: Vec<String> = valid.into_iter().map(|s| s.as_ref().to_string()).collect();
        let list = if valid.is_empty() { "none".to_string() } else { valid.join(", ") };
        RecordingError::data(format!("{what} `{name}`"), format!("not in the recording; available: {list}"))
    }
}

/// Result alias of the recording readers and writers.
pub type Result<T, E = RecordingError> = std::result::Result<T, E>;
