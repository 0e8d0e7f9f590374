//! Errors of model loading and kinematic queries.
//!
//! Every error names what it is about (file, field, value), so a user can fix the input from the
//! one-line message alone.

use std::path::PathBuf;

/// What went wrong, without the file context.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum KinError {
    /// A field is missing, has the wrong type or an invalid value.
    #[error("field `{field}`: {message}")]
    Field { field: String, message: String },
    /// An expression in a model file could not be parsed or is not affine.
    #[error("field `{field}`: cannot read expression `{expr}`: {message}")]
    Expr { field: String, expr: String, message: String },
    /// A file could not be read or parsed at all.
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
    /// Any error, with the file it was found in.
    #[error("{}: {source}", path.display())]
    InFile {
        path: PathBuf,
        #[source]
        source: Box<KinError>,
    },
    /// An argument of the wrong size.
    #[error("wrong argument size for {what}: expected {expected}, got {got}")]
    Size { what: String, expected: usize, got: usize },
    /// A name that is not known; the valid ones are listed.
    #[error("unknown {what} `{name}`; valid: {valid}")]
    Unknown { what: String, name: String, valid: String },
    /// A value that is not finite, or outside its limits.
    #[error("{what} = {}: {message}", fmt_number(*value))]
    Value { what: String, value: f64, message: String },
    /// Inverse kinematics found no solution.
    #[error("inverse kinematics: {0}")]
    Ik(String),
    /// Export to a format that cannot express the model.
    #[error("export: {0}")]
    Export(String),
}

impl KinError {
    /// A field error.
    pub fn field(field: impl Into<String>, message: impl Into<String>) -> Self {
        KinError::Field { field: field.into(), message: message.into() }
    }
    /// Attach the file this error was found in (once: an error already in a file keeps its path).
    pub fn in_file(self, path: impl Into<PathBuf>) -> Self {
        match self {
            e @ (KinError::InFile { .. } | KinError::File { .. }) => e,
            e => KinError::InFile { path: path.into(), source: Box::new(e) },
        }
    }
    /// The list of valid names, joined for messages.
    pub fn unknown(what: &str, name: &str, valid: impl IntoIterator<Item = impl AsRef<str>>) -> Self {
        let valid: Vec<String> = valid.into_iter().map(|s| s.as_ref().to_string()).collect();
        KinError::Unknown { what: what.into(), name: name.into(), valid: valid.join(", ") }
    }
}

/// Result alias of this crate.
pub type Result<T, E = KinError> = std::result::Result<T, E>;

/// A number for an error message: as written when it is of a usual size, in `{:.6e}` form when it
/// is very large or very small (an input of 1e300 is not printed as 301 digits).
pub fn fmt_number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e7).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:.6e}")
    }
}
