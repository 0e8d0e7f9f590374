//! Finding and loading models: built-in names, model files (TOML), systems, dVRK JSON and URDF.

use crate::error::{KinError, Result};
use crate::model::Model;
use crate::spec::ModelSpec;
use std::path::{Path, PathBuf};

pub use crate::text_file::{read_text, MAX_TEXT_BYTES};

/// The built-in models: name, and the text of its file in `models/`.
pub const BUILTIN: &[(&str, &str)] = &[
    ("psm", include_str!("../../../models/psm.toml")),
    ("ecm", include_str!("../../../models/ecm.toml")),
    ("suj-psm1", include_str!("../../../models/suj-psm1.toml")),
    ("suj-psm2", include_str!("../../../models/suj-psm2.toml")),
    ("suj-psm3", include_str!("../../../models/suj-psm3.toml")),
    ("suj-ecm", include_str!("../../../models/suj-ecm.toml")),
    ("cart", include_str!("../../../models/cart.toml")),
    ("mtml", include_str!("../../../models/mtml.toml")),
    ("mtmr", include_str!("../../../models/mtmr.toml")),
    // The MTMR identified on the WPI authors' real MTM (`one`; docs/mtm.md): the `mtm` scene's arm.
    ("mtmr-wpi", include_str!("../../../models/mtmr-wpi.toml")),
    ("psm-serial", include_str!("../../../models/psm-serial.toml")),
    ("ecm-serial", include_str!("../../../models/ecm-serial.toml")),
];

/// Names of the built-in models.
pub fn builtin_names() -> impl Iterator<Item = &'static str> {
    BUILTIN.iter().map(|(n, _)| *n)
}

/// The file text of a built-in model.
pub fn builtin_text(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// Load a model by built-in name or path (`.toml` model or system file, dVRK `.json`, `.urdf`),
/// with an optional dVRK tool file for models that carry a tool (PSM).
pub fn load(name_or_path: &str, tool: Option<&Path>) -> Result<Model> {
    load_relative(name_or_path, tool, None)
}

/// [`load`], resolving relative paths against `dir` (the directory of the referring file).
pub fn load_relative(name_or_path: &str, tool: Option<&Path>, dir: Option<&Path>) -> Result<Model> {
    if let Some(text) = builtin_text(name_or_path) {
        let path = PathBuf::from(format!("models/{name_or_path}.toml"));
        return load_toml_text(text, &path, tool, None);
    }
    let path = match dir {
        Some(d) if Path::new(name_or_path).is_relative() => d.join(name_or_path),
        _ => PathBuf::from(name_or_path),
    };
    if !path.exists() {
        let mut valid: Vec<String> = builtin_names().map(String::from).collect();
        valid.push("a path to a .toml, .json or .urdf file".into());
        return Err(KinError::unknown("model", name_or_path, valid));
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "json" => {
            let spec = crate::dvrk_json::serial_spec(&path, tool)?;
            let mut m = Model::compile(spec).map_err(|e| e.in_file(&path))?;
            m.origin = Some(path.clone());
            m.tool_file = tool.map(Path::to_path_buf);
            Ok(m)
        }
        "urdf" | "xml" => {
            if tool.is_some() {
                return Err(KinError::field("--tool", "a tool file applies to dVRK JSON and model files, not to URDF"));
            }
            crate::urdf::import_urdf_file(&path)
        }
        _ => {
            let text = read_text(&path)?;
            load_toml_text(&text, &path, tool, Some(&path))
        }
    }
}

/// Load a model or system from TOML text; `path` names it in errors, `origin` is the real file.
pub fn load_toml_text(text: &str, path: &Path, tool: Option<&Path>, origin: Option<&Path>) -> Result<Model> {
    let dir = origin.and_then(Path::parent);
    let is_system = toml::from_str::<toml::Table>(text).map(|t| t.contains_key("arms")).unwrap_or(false);
    if is_system {
        if tool.is_some() {
            return Err(KinError::field("--tool", "a system takes its tools from its arm entries, not from --tool"));
        }
        let spec = crate::compose::SystemSpec::from_toml(text, path)?;
        return crate::compose::compose(&spec, dir).map_err(|e| e.in_file(path));
    }
    let mut spec = ModelSpec::from_toml(text, path)?;
    if let Some(t) = tool {
        crate::dvrk_json::apply_tool(&mut spec, t)?;
    }
    let mut m = Model::compile(spec).map_err(|e| e.in_file(path))?;
    m.origin = origin.map(Path::to_path_buf);
    m.tool_file = tool.map(Path::to_path_buf);
    Ok(m)
}

/// The serial dVRK model a closed-loop model names in `[serial_equivalent]`, with the same tool.
pub fn load_serial_equivalent(model: &Model) -> Result<Option<Model>> {
    let Some(s) = &model.spec.serial_equivalent else { return Ok(None) };
    let dir = model.origin.as_deref().and_then(Path::parent);
    load_relative(&s.model, model.tool_file.as_deref(), dir).map(Some)
}
