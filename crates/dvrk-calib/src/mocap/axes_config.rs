//! The axes configuration file (`markers.toml`): which rigid body of a recording sits on which
//! link, and which pairs of links share a joint axis.
//!
//! ```toml
//! method = "sara"            # or "gamage-lasenby" (optional)
//! reference_time = 12.5      # s, optional: when to express the axes in the tracker frame
//!
//! [[bodies]]
//! name = "back"              # the name the axes use
//! recording = "/mocap/back/pose"   # its topic or rigid-body name in the recording (default: name)
//! link = "pitch_back_link"   # informative
//! frame = 3                  # informative: the paper's frame number
//! markers = [[0.03, 0, 0], [-0.01, 0.03, 0], [-0.02, -0.02, 0]]   # m, optional layout
//!
//! [[axes]]
//! name = "3"                 # Table 6 label
//! reference = "yaw"          # a body, or "tracker" when the link it is fixed in does not move
//! moving = "back"
//! ```

use crate::mocap::axis_fit::AxisMethod;
use crate::error::{CalibError, Result};
use serde::Deserialize;
use std::path::Path;

/// The name that stands for the tracker frame itself in `reference`.
pub const TRACKER: &str = "tracker";

/// A rigid body of the recording.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyConfig {
    pub name: String,
    /// Topic or rigid-body name in the recording (default: `name`).
    #[serde(default)]
    pub recording: Option<String>,
    /// The model link it is fixed to (informative).
    #[serde(default)]
    pub link: Option<String>,
    /// The paper's frame number of that link (informative).
    #[serde(default)]
    pub frame: Option<i64>,
    /// Marker layout in the body frame (m), for recordings with raw markers only.
    #[serde(default)]
    pub markers: Option<Vec<[f64; 3]>>,
}

/// A joint axis between two bodies.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Label (Table 6: 3, 4, 6, 7, 8, c1, c2).
    pub name: String,
    /// The body the axis is expressed in, or `tracker`.
    pub reference: String,
    /// The body that turns about the axis relative to `reference`.
    pub moving: String,
}

/// A whole configuration file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxesConfig {
    /// `sara` (default) or `gamage-lasenby`.
    #[serde(default)]
    pub method: Option<String>,
    /// When to express the axes in the tracker frame (s); default: the sample nearest q1 = q2 =
    /// 0 when joint states were recorded, else the first sample.
    #[serde(default)]
    pub reference_time: Option<f64>,
    #[serde(default)]
    pub bodies: Vec<BodyConfig>,
    pub axes: Vec<AxisConfig>,
}

impl AxesConfig {
    /// Parse and check a configuration; `path` names it in errors.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        let cfg: AxesConfig = toml::from_str(text).map_err(|e| CalibError::file(path, dvrk_kin::spec::toml_message(&e, text)))?;
        cfg.check().map_err(|e| e.in_file(path))?;
        Ok(cfg)
    }

    /// The configured method (default SARA).
    pub fn method(&self) -> Result<AxisMethod> {
        self.method.as_deref().map_or(Ok(AxisMethod::Sara), str::parse)
    }

    /// The recording name of a body (its `recording` entry, or the name itself).
    pub fn recording_name<'a>(&'a self, body: &'a str) -> &'a str {
        self.bodies.iter().find(|b| b.name == body).and_then(|b| b.recording.as_deref()).unwrap_or(body)
    }

    /// The configured body, if listed.
    pub fn body(&self, name: &str) -> Option<&BodyConfig> {
        self.bodies.iter().find(|b| b.name == name)
    }

    fn check(&self) -> Result<()> {
        self.method()?;
        if let Some(t) = self.reference_time {
            if !t.is_finite() {
                return Err(CalibError::field("reference_time", format!("{t} is not finite")));
            }
        }
        if self.axes.is_empty() {
            return Err(CalibError::field("axes", "no [[axes]] entry: name at least one pair of bodies that share an axis"));
        }
        for (i, b) in self.bodies.iter().enumerate() {
            if self.bodies[..i].iter().any(|c| c.name == b.name) {
                return Err(CalibError::field(format!("bodies[{i}].name"), format!("`{}` appears twice", b.name)));
            }
            if b.name == TRACKER {
                return Err(CalibError::field(format!("bodies[{i}].name"), "`tracker` stands for the tracker frame; give the body another name"));
            }
            if let Some(m) = &b.markers {
                if m.len() < dvrk_sim::recording::MIN_MARKERS {
                    return Err(CalibError::field(format!("bodies[{i}].markers"), format!("{} marker(s); a pose needs 3 or more", m.len())));
                }
                if m.iter().flatten().any(|x| !x.is_finite()) {
                    return Err(CalibError::field(format!("bodies[{i}].markers"), "a coordinate is not finite"));
                }
            }
        }
        for (i, a) in self.axes.iter().enumerate() {
            if self.axes[..i].iter().any(|b| b.name == a.name) {
                return Err(CalibError::field(format!("axes[{i}].name"), format!("`{}` appears twice", a.name)));
            }
            if a.moving == TRACKER {
                return Err(CalibError::field(format!("axes[{i}].moving"), "the moving side must be a body (put the tracker as `reference`)"));
            }
            if a.reference == a.moving {
                return Err(CalibError::field(format!("axes[{i}]"), format!("reference and moving are both `{}`", a.moving)));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_file_line_and_field() {
        let p = Path::new("markers.toml");
        let e = AxesConfig::from_toml("[[axes]]\nname = \"3\"\nreference = \"a\"\n", p).unwrap_err().to_string();
        assert!(e.starts_with("markers.toml: ") && e.contains("moving"), "{e}");
        let e = AxesConfig::from_toml("method = \"svd\"\n[[axes]]\nname = \"3\"\nreference = \"a\"\nmoving = \"b\"\n", p).unwrap_err().to_string();
        assert!(e.contains("`svd` is not an axis method"), "{e}");
        let e = AxesConfig::from_toml("[[axes]]\nname = \"3\"\nreference = \"a\"\nmoving = \"a\"\n", p).unwrap_err().to_string();
        assert!(e.contains("axes[0]") && e.contains("both `a`"), "{e}");
        let ok = AxesConfig::from_toml("[[bodies]]\nname = \"a\"\nrecording = \"/m/a/pose\"\n[[axes]]\nname = \"3\"\nreference = \"tracker\"\nmoving = \"a\"\n", p).unwrap();
        assert_eq!(ok.recording_name("a"), "/m/a/pose");
        assert_eq!(ok.recording_name("b"), "b");
    }
}
