//! URDF export (tree + mimic joints) and import (urdf-rs). Written by a helper.
use crate::error::{KinError, Result};
use crate::model::Model;
use std::path::Path;
/// Import a URDF file.
pub fn import_urdf_file(path: &Path) -> Result<Model> {
    Err(KinError::File { path: path.into(), message: "URDF import is not built yet".into() })
}
