//! Reading a recording whatever its format: MCAP or a ROS 1 bag (told by their first bytes,
//! whatever the name), a Motive CSV export (recognised by its `Format Version` first line) or
//! the plain CSV format.

use crate::error::{CalibError, Result};
use crate::mcap_io::McapOptions;
use crate::recording::Recording;
use std::path::Path;

/// Read `path`; `options` select MCAP topics (CSV files name their bodies in columns).
pub fn read_recording(path: &Path, options: &McapOptions) -> Result<Recording> {
    if !path.exists() {
        return Err(CalibError::file(path, "no such file"));
    }
    if crate::message_file::container(path)?.is_some() {
        return crate::mcap_io::read(path, options);
    }
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "mcap" | "bag" => crate::mcap_io::read(path, options),
        "csv" | "txt" => {
            let text = std::fs::read_to_string(path).map_err(|e| CalibError::file(path, format!("cannot read: {e}")))?;
            let rec = if crate::motive_csv::looks_like_motive(&text) { crate::motive_csv::parse(&text, path)? } else { crate::plain_csv::parse(&text, path)? };
            if let Some(t) = &options.joint_topic {
                if rec.joints.is_none() {
                    return Err(CalibError::file(path, format!("joint states `{t}` asked for, but the file has no q1..qN columns")));
                }
            }
            Ok(rec)
        }
        _ => Err(CalibError::file(path, format!("unknown recording format `.{ext}`; valid: .mcap, .bag (ROS 1), .csv (Motive export or plain)"))),
    }
}
