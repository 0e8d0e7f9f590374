//! Reading a description file (model, scene, inertials, dVRK JSON, URDF, configuration) whole,
//! with a size bound: below every format's parser.

use crate::error::{KinError, Result};
use std::path::Path;

/// The largest description file (model, scene, inertials, dVRK JSON, URDF, configuration) read
/// (bytes): the dVRK's are a few kB to a few MB; a larger one is a recording or a mistake, read
/// whole into memory otherwise.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// A description file's text, refused past [`MAX_TEXT_BYTES`]; errors name the file.
pub fn read_text(path: &Path) -> Result<String> {
    let file = |message: String| KinError::File { path: path.into(), message };
    let size = std::fs::metadata(path).map_err(|e| file(format!("cannot read: {e}")))?.len();
    if size > MAX_TEXT_BYTES {
        return Err(file(format!("{size} bytes: a model, scene or configuration file is at most {MAX_TEXT_BYTES} bytes (is this a recording?)")));
    }
    std::fs::read_to_string(path).map_err(|e| file(format!("cannot read: {e}")))
}
