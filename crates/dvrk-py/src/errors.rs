//! The exceptions of `dvrk_twin` and the one mapping from [`KinError`] to them.
//!
//! ```text
//! Exception
//! └── DvrkError                                  every error of this package
//!     ├── ModelError(DvrkError, ValueError)      a model or tool file is invalid (names the file)
//!     ├── ModelNotFoundError(DvrkError, FileNotFoundError, ValueError)
//!     │                                          unknown built-in name or missing file (lists the valid names)
//!     ├── InputError(DvrkError, ValueError)      wrong argument size or shape, non-finite value, unknown frame
//!     └── IkError(DvrkError, ValueError)         target out of reach, or reached only outside the joint limits
//! ```
//!
//! The message of every exception is the `Display` of the Rust error, the same line the `dvrk`
//! CLI prints. The classes are built at import with `type()` because two of them have several
//! bases (as `io.UnsupportedOperation(OSError, ValueError)` does), which `create_exception!`
//! cannot express.

use dvrk_kin::KinError;
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

/// The exception classes, created once per interpreter.
pub struct Exceptions {
    pub base: Py<PyType>,
    pub model: Py<PyType>,
    pub not_found: Py<PyType>,
    pub input: Py<PyType>,
    pub ik: Py<PyType>,
}

static EXCEPTIONS: PyOnceLock<Exceptions> = PyOnceLock::new();

fn new_class(
    py: Python<'_>,
    name: &str,
    doc: &str,
    bases: Vec<Bound<'_, PyType>>,
) -> PyResult<Py<PyType>> {
    let dict = PyDict::new(py);
    dict.set_item("__doc__", doc)?;
    dict.set_item("__module__", "dvrk_twin")?;
    let bases = PyTuple::new(py, bases)?;
    let ty = py.get_type::<PyType>().call1((name, bases, dict))?;
    Ok(ty.cast_into::<PyType>()?.unbind())
}

/// The exception classes (created on first use).
pub fn exceptions(py: Python<'_>) -> PyResult<&Exceptions> {
    EXCEPTIONS.get_or_try_init(py, || {
        let value = py.get_type::<PyValueError>();
        let base = new_class(
            py,
            "DvrkError",
            "Base class of every error raised by dvrk_twin. The message is the same line the `dvrk` CLI prints.",
            vec![py.get_type::<PyException>()],
        )?;
        let b = base.bind(py).clone();
        let model = new_class(
            py,
            "ModelError",
            "A model or tool file is invalid; the message names the file, the field and the value.",
            vec![b.clone(), value.clone()],
        )?;
        let not_found = new_class(
            py,
            "ModelNotFoundError",
            "Model.load was given neither a built-in model name nor an existing file (the message lists the valid \
             names), or a tool file that does not exist. Also a FileNotFoundError and a ValueError.",
            vec![b.clone(), py.get_type::<PyFileNotFoundError>(), value.clone()],
        )?;
        let input = new_class(
            py,
            "InputError",
            "An argument of the wrong size or shape, a non-finite value, or an unknown frame name or number.",
            vec![b.clone(), value.clone()],
        )?;
        let ik = new_class(
            py,
            "IkError",
            "Inverse kinematics found no solution: the target is out of reach, or reached only outside the joint limits.",
            vec![b, value],
        )?;
        Ok(Exceptions { base, model, not_found, input, ik })
    })
}

/// Every error of the binding: a kinematics error, a bad argument found by the binding itself,
/// or a Python error passed through.
pub enum Error {
    Kin(KinError),
    /// A simulation error (bad scene file, bad command): raised by its kind.
    Sim(dvrk_sim::SimError),
    /// A calibration error (bad recording, too little motion).
    Calib(dvrk_calib::CalibError),
    /// An argument error found in the binding (raised as `InputError`).
    Input(String),
    Py(PyErr),
}

impl From<KinError> for Error {
    fn from(e: KinError) -> Self {
        Error::Kin(e)
    }
}

impl From<dvrk_sim::SimError> for Error {
    fn from(e: dvrk_sim::SimError) -> Self {
        match e {
            dvrk_sim::SimError::Kin(k) => Error::Kin(k),
            e => Error::Sim(e),
        }
    }
}

impl From<dvrk_calib::CalibError> for Error {
    fn from(e: dvrk_calib::CalibError) -> Self {
        match e {
            dvrk_calib::CalibError::Kin(k) => Error::Kin(k),
            e => Error::Calib(e),
        }
    }
}

/// A recording's error raises what the same error of a calibration does (its variants are
/// taken into `CalibError`'s one for one).
impl From<dvrk_sim::recording::RecordingError> for Error {
    fn from(e: dvrk_sim::recording::RecordingError) -> Self {
        Error::from(dvrk_calib::CalibError::from(e))
    }
}

impl From<PyErr> for Error {
    fn from(e: PyErr) -> Self {
        Error::Py(e)
    }
}

/// Which `dvrk_twin` exception a kinematics error is raised as.
fn class_of<'a>(ex: &'a Exceptions, e: &KinError) -> &'a Py<PyType> {
    match e {
        KinError::Unknown { what, .. } if what == "model" => &ex.not_found,
        // A file that cannot be read because it is not there (a tool file, a referenced model).
        KinError::File { path, message }
            if (message.starts_with("cannot read") || message.starts_with("no such file")) && !path.exists() =>
        {
            &ex.not_found
        }
        KinError::Size { .. } | KinError::Value { .. } | KinError::Unknown { .. } => &ex.input,
        KinError::Ik(_) => &ex.ik,
        KinError::Field { .. }
        | KinError::Expr { .. }
        | KinError::File { .. }
        | KinError::InFile { .. }
        | KinError::Export(_) => &ex.model,
        // KinError is #[non_exhaustive]: a future variant is still a DvrkError.
        _ => &ex.base,
    }
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        Python::attach(|py| {
            let ex = match exceptions(py) {
                Ok(ex) => ex,
                Err(err) => return err,
            };
            match e {
                Error::Py(err) => err,
                Error::Input(msg) => PyErr::from_type(ex.input.bind(py).clone(), msg),
                Error::Kin(k) => PyErr::from_type(class_of(ex, &k).bind(py).clone(), k.to_string()),
                Error::Sim(e) => {
                    let class = match &e {
                        dvrk_sim::SimError::Value { .. } => &ex.input,
                        dvrk_sim::SimError::Field { .. } => &ex.model,
                        _ => &ex.base,
                    };
                    PyErr::from_type(class.bind(py).clone(), e.to_string())
                }
                Error::Calib(e) => {
                    let class = match &e {
                        dvrk_calib::CalibError::File { path, .. } | dvrk_calib::CalibError::InFile { path, .. } if !path.exists() => &ex.not_found,
                        dvrk_calib::CalibError::Field { .. } | dvrk_calib::CalibError::File { .. } | dvrk_calib::CalibError::InFile { .. } => &ex.model,
                        _ => &ex.input,
                    };
                    PyErr::from_type(class.bind(py).clone(), e.to_string())
                }
            }
        })
    }
}

/// Result of the binding's functions.
pub type Result<T, E = Error> = std::result::Result<T, E>;
