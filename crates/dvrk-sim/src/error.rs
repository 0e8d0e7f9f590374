//! Errors of the simulator: each names the file, field or joint and the offending value.

use thiserror::Error;

/// Result of simulator calls.
pub type Result<T> = std::result::Result<T, SimError>;

#[derive(Debug, Error)]
pub enum SimError {
    /// A file entry is missing or wrong (`file`: path or built-in name; `field`: dotted path).
    #[error("{file}: {field}: {message}")]
    Field { file: String, field: String, message: String },
    /// A run-time value (command, gain, option) is not acceptable.
    #[error("{what} = {}: {message}", dvrk_kin::fmt_number(*value))]
    Value { what: String, value: f64, message: String },
    /// Reading or writing a file failed.
    #[error("{path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error(transparent)]
    Kin(#[from] dvrk_kin::KinError),
    /// The state went non-finite (a scene or command the integrator cannot carry).
    #[error("the simulation went non-finite at t = {time:.6e} s: {message}")]
    Diverged { time: f64, message: String },
    /// The physics engine refused to build part of the model.
    #[error("building the rapier model: {0}")]
    Build(String),
}

impl SimError {
    pub(crate) fn field(file: impl Into<String>, field: impl Into<String>, message: impl Into<String>) -> Self {
        SimError::Field { file: file.into(), field: field.into(), message: message.into() }
    }
    pub(crate) fn value(what: impl Into<String>, value: f64, message: impl Into<String>) -> Self {
        SimError::Value { what: what.into(), value, message: message.into() }
    }
}
