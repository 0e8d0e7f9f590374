//! Errors of reading recordings and fitting them.
//!
//! Every error names what it is about (file, topic, body, row, field) and quotes the value, so a
//! user can fix the input from the one-line message alone. Nothing here panics on user input.

use std::path::PathBuf;

/// What went wrong.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibError {
    /// A file could not be read, or its content is malformed (the message says where in it).
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    /// A field of a configuration or a result file is missing or has an invalid value.
    #[error("field `{field}`: {message}")]
    Field { field: String, message: String },
    /// Recorded data that cannot be used: a missing topic or body, too few samples, NaN values.
    #[error("{what}: {message}")]
    Data { what: String, message: String },
    /// The motion in the recording does not determine the quantity asked for.
    #[error("{what}: {message}")]
    Motion { what: String, message: String },
    /// A model could not be loaded or rebuilt.
    #[error(transparent)]
    Kin(#[from] dvrk_kin::KinError),
    /// A scene, simulation or recorder error.
    #[error(transparent)]
    Sim(#[from] dvrk_sim::SimError),
    /// An error found in file `path` ([`CalibError::in_file`]); the error itself is kept.
    #[error("{}: {source}", path.display())]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<CalibError>,
    },
    /// A layer below (a model, a scene, a solver) failed while doing `what`; its error is kept.
    #[error("{what}: {source}")]
    Context {
        what: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

impl CalibError {
    /// An error about a file.
    pub fn file(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        CalibError::File { path: path.into(), message: message.into() }
    }
    /// An error about a field of a configuration or result file.
    pub fn field(field: impl Into<String>, message: impl Into<String>) -> Self {
        CalibError::Field { field: field.into(), message: message.into() }
    }
    /// An error about recorded data.
    pub fn data(what: impl Into<String>, message: impl Into<String>) -> Self {
        CalibError::Data { what: what.into(), message: message.into() }
    }
    /// The motion does not determine the estimate.
    pub fn motion(what: impl Into<String>, message: impl Into<String>) -> Self {
        CalibError::Motion { what: what.into(), message: message.into() }
    }
    /// Attach the file this error was found in (errors that already name a file keep it).
    pub fn in_file(self, path: impl Into<PathBuf>) -> Self {
        match self {
            e @ (CalibError::File { .. } | CalibError::InFile { .. }) => e,
            e => CalibError::InFile { path: path.into(), source: Box::new(e) },
        }
    }
    /// `source`, met while doing `what`, kept as the cause.
    pub fn context(what: impl Into<String>, source: impl std::error::Error + Send + Sync + 'static) -> Self {
        CalibError::Context { what: what.into(), source: Box::new(source) }
    }
    /// A simulation's error (a sim the analysis runs itself), kept as the cause.
    pub fn simulation(e: dvrk_sim::SimError) -> Self {
        CalibError::context("simulation", e)
    }
}

/// A recording's error, the same message in the same variant.
impl From<dvrk_sim::recording::RecordingError> for CalibError {
    fn from(e: dvrk_sim::recording::RecordingError) -> Self {
        use dvrk_sim::recording::RecordingError as R;
        match e {
            R::File { path, message } => CalibError::File { path, message },
            R::Field { field, message } => CalibError::Field { field, message },
            R::Data { what, message } => CalibError::Data { what, message },
            R::Kin(e) => CalibError::Kin(e),
            R::Sim(e) => CalibError::Sim(e),
            // `RecordingError` is non-exhaustive: a variant added later keeps its message.
            e => CalibError::context("recording", e),
        }
    }
}

/// Result alias of this crate.
pub type Result<T, E = CalibError> = std::result::Result<T, E>;
