//! The model file format (TOML), as written by people: units in comments, sources beside numbers,
//! DH entries as the paper prints them. [`crate::Model::compile`] turns a spec into a model.

use crate::error::{KinError, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// DH convention of a model: where `a` and `alpha` sit relative to the joint motion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Convention {
    /// Craig's modified DH: `T = Rx(alpha) Tx(a) Rz(theta) Tz(d)` (the paper, PSM/ECM/SUJ).
    #[default]
    Modified,
    /// Classic DH: `T = Rz(theta) Tz(d) Tx(a) Rx(alpha)` (the dVRK MTM files).
    Standard,
}

/// A number, or an affine expression of parameters and joints (`"-q2 + beta1 + pi/2"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Value {
    Number(f64),
    Expr(String),
}

impl Default for Value {
    fn default() -> Self {
        Value::Number(0.0)
    }
}

impl From<f64> for Value {
    fn from(x: f64) -> Self {
        Value::Number(x)
    }
}

/// A frame or joint reference: the paper's frame number or a name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum FrameRef {
    Index(i64),
    Name(String),
}

impl std::fmt::Display for FrameRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FrameRef::Index(i) => write!(f, "{i}"),
            FrameRef::Name(s) => write!(f, "{s}"),
        }
    }
}

/// Kind of an actuated joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointType {
    /// Rotation, position in rad.
    Revolute,
    /// Translation, position in m.
    Prismatic,
}

/// Motion type of a frame (the paper's "Joint" column).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FrameJoint {
    /// `theta` varies (R).
    Revolute,
    /// `d` varies (P).
    Prismatic,
    /// Nothing varies (`-`).
    Fixed,
}

/// A named constant with its unit and provenance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    /// Value in SI units (rad, m, or unitless).
    pub value: f64,
    #[serde(default)]
    pub unit: String,
    #[serde(default)]
    pub source: String,
}

/// An actuated joint (a coordinate of `q`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointSpec {
    /// The dVRK's name (`outer_yaw`, ...).
    pub name: String,
    #[serde(rename = "type")]
    pub kind: JointType,
    /// Lower limit (rad or m).
    pub lower: f64,
    /// Upper limit (rad or m).
    pub upper: f64,
    /// Effort limit (N·m or N); 0 when unknown.
    #[serde(default)]
    pub effort_limit: f64,
    /// Home position (rad or m); 0 clamped into the limits when absent.
    #[serde(default)]
    pub home: Option<f64>,
    #[serde(default)]
    pub source: String,
}

/// A frame of the tree: DH entries, or a fixed 4x4 transform.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameSpec {
    /// The paper's frame number (PSM/ECM), or a running number.
    #[serde(default)]
    pub index: Option<i64>,
    pub name: String,
    /// Predecessor: a frame number or name; `0` or `"base"` for the base frame.
    pub parent: FrameRef,
    /// Rigid part this frame belongs to (frames that move as one are one body).
    #[serde(default)]
    pub body: Option<String>,
    /// The paper's "Joint" column: which DH entry varies.
    #[serde(default = "fixed")]
    pub joint: FrameJoint,
    /// m
    #[serde(default)]
    pub a: Value,
    /// rad
    #[serde(default)]
    pub alpha: Value,
    /// m
    #[serde(default)]
    pub d: Value,
    /// rad
    #[serde(default)]
    pub theta: Value,
    /// Fixed transform from the parent (row-major 4x4, m), used instead of DH entries.
    #[serde(default, deserialize_with = "crate::exact::opt_mat4")]
    pub transform: Option<[[f64; 4]; 4]>,
    #[serde(default)]
    pub source: String,
}

fn fixed() -> FrameJoint {
    FrameJoint::Fixed
}

/// A loop-closure point: a point of one link that must coincide with a point of another.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClosureSpec {
    pub name: String,
    /// The link whose end is the closure point.
    pub frame: FrameRef,
    /// The point in `frame` (m).
    #[serde(deserialize_with = "crate::exact::vec3")]
    pub point: [f64; 3],
    /// The link it closes on.
    pub partner: FrameRef,
    /// The same point in `partner` (m); computed at the home configuration when absent.
    #[serde(default, deserialize_with = "crate::exact::opt_vec3")]
    pub partner_point: Option<[f64; 3]>,
    #[serde(default)]
    pub source: String,
}

/// Remote centre of motion: a frame whose z axis always passes through one fixed point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RcmSpec {
    pub frame: FrameRef,
}

/// The serial dVRK chain this closed-loop model must reproduce.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SerialSpec {
    /// Built-in name or path (relative to this file) of the serial model.
    pub model: String,
    /// Pairs `[closed-loop frame, serial frame]` that must agree up to one constant base transform.
    pub pairs: Vec<[FrameRef; 2]>,
}

/// Which model entries a dVRK tool file sets (see [`crate::dvrk_json::apply_tool`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolSpec {
    /// The tool these defaults come from.
    pub name: String,
    #[serde(default)]
    pub source: String,
    /// Parameter set from the tool's roll `D` (m).
    pub length_parameter: String,
    /// Parameter set from the tool's wrist-yaw `A` (m).
    pub jaw_offset_parameter: String,
    /// Joints set from the tool's DH joints and `jaw`, in order (roll, wrist pitch, wrist yaw, jaw).
    pub joints: Vec<String>,
    /// Fixed frame set from `tooltip_offset`.
    pub tooltip_frame: String,
    /// ActuatorToJointPosition of the tool (rows and columns over `joints`).
    #[serde(default)]
    pub coupling: Option<Vec<Vec<f64>>>,
}

/// A mesh file drawn (and available as a collision shape) for one body instead of the solids
/// the simulator builds from the kinematics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// The body it belongs to (a `body` name of the frames).
    pub body: String,
    /// STL (binary or ASCII) or OBJ file, relative to the model file.
    pub file: String,
    /// Metres per file unit (0.001 for a mesh in mm).
    #[serde(default = "unit_scale")]
    pub scale: f64,
    /// Placement of the mesh in the body frame (the body's first frame; row-major 4x4, m);
    /// identity when absent.
    #[serde(default, deserialize_with = "crate::exact::opt_mat4")]
    pub transform: Option<[[f64; 4]; 4]>,
    #[serde(default)]
    pub source: String,
}

fn unit_scale() -> f64 {
    1.0
}

/// The inertial of one body as a model file carries it (`[[inertials]]`), in the body's first DH
/// frame like the `models/inertials/*.toml` files: an identified model (`dvrk identify -o`) holds
/// its bodies here, and a scene arm built from it takes them over its inertials file's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InertialSpec {
    /// Body name ([`crate::Model::bodies`]).
    pub body: String,
    /// kg
    pub mass: f64,
    /// Centre of mass in the body frame (m).
    #[serde(deserialize_with = "crate::exact::vec3")]
    pub com: [f64; 3],
    /// Inertia about the centre of mass, body-frame axes (kg m^2), row-major.
    #[serde(deserialize_with = "crate::exact::mat3")]
    pub inertia: [[f64; 3]; 3],
    /// Where the figures come from.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
}

/// The drive a model's efforts were identified with (`[drive]`): an identified model
/// (`dvrk identify -o`) carries the joint damping and reflected motor inertias its friction and
/// inertials were fitted beside, so that a scene arm built from it does not add its own on top.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriveSpec {
    /// Viscous damping of every tree joint (N·m s/rad, N s/m), as a scene arm's `damping`: it
    /// replaces the scene's.
    pub damping: f64,
    /// Reflected motor inertia per joint (kg m^2, kg for a prismatic joint), as a scene arm's
    /// `armature`.
    pub armature: Vec<f64>,
    /// Where the figures come from.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
}

/// How well a model's inertials are known (`[inertial_covariance]`): the covariance of the
/// inertial parameters an identification fitted them with (`dvrk identify -o`), so that a later
/// analysis holds them as tightly as the recording determined them and no tighter.
///
/// The parameters are each listed body's standard linear form
/// ([`crate::dynamics::PARAMETER_NAMES`]: kg, kg m, kg m^2, about the body's first frame), body
/// after body in the order of `bodies`. The covariance is `L L^T`, with `L` its lower Cholesky
/// factor: `cholesky[i]` holds row `i` of `L` up to its diagonal (`i + 1` numbers). A factor
/// keeps the matrix positive semidefinite whatever the rounding of the numbers written, and a
/// direction the recording did not determine keeps the identification's prior variance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InertialCovarianceSpec {
    /// The bodies whose parameters are covered ([`crate::Model::bodies`] names).
    pub bodies: Vec<String>,
    /// Rows of the lower Cholesky factor of the covariance (units of the parameters' products).
    pub cholesky: Vec<Vec<f64>>,
    /// The recording and method it comes from.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
}

/// An effect as a model file writes it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EffectSpec {
    /// A name of the vocabulary ([`crate::effects::EffectKind::ALL`]).
    pub name: String,
    /// The joint it acts on (joint effects).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<String>,
    /// The link (frame number or name) it acts on (link effects).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link: Option<FrameRef>,
    /// The actuator (1-based: a column of the model's coupling) it acts on (actuator effects).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actuator: Option<usize>,
    /// Parameter values in the units of [`crate::effects::EffectKind::parameters`].
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
    /// Where the figures come from.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
}

/// A whole model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    pub name: String,
    #[serde(default)]
    pub title: String,
    #[serde(default)]
    pub convention: Convention,
    #[serde(default)]
    pub source: String,
    #[serde(default)]
    pub notes: String,
    /// Named constants used in expressions.
    #[serde(default)]
    pub parameters: BTreeMap<String, ParameterSpec>,
    pub joints: Vec<JointSpec>,
    pub frames: Vec<FrameSpec>,
    #[serde(default)]
    pub closures: Vec<ClosureSpec>,
    #[serde(default)]
    pub rcm: Option<RcmSpec>,
    /// The tool-tip frame (default: the last frame).
    #[serde(default)]
    pub tip: Option<FrameRef>,
    #[serde(default)]
    pub serial_equivalent: Option<SerialSpec>,
    #[serde(default)]
    pub tool: Option<ToolSpec>,
    /// ActuatorToJointPosition (rows: joints, columns: actuators), as in dVRK files.
    #[serde(default)]
    pub coupling: Option<Vec<Vec<f64>>>,
    /// The drive the model's efforts were identified with ([`DriveSpec`]); none: the scene's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive: Option<DriveSpec>,
    /// Physical effects: friction, springs, offsets, compliance... ([`crate::effects`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<EffectSpec>,
    /// Inertials of some or all bodies (`[[inertials]]`); bodies without one take the scene's.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inertials: Vec<InertialSpec>,
    /// The covariance of the inertials' parameters ([`InertialCovarianceSpec`]); none: unknown
    /// (CAD figures).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertial_covariance: Option<InertialCovarianceSpec>,
    /// Mesh files of bodies (`[[meshes]]`); bodies without one get solids from the kinematics.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub meshes: Vec<MeshSpec>,
}

impl ModelSpec {
    /// The spec of a model that was not compiled from a model file (a system, a URDF).
    pub fn empty(name: &str, source: &str) -> Self {
        ModelSpec {
            name: name.into(),
            title: String::new(),
            convention: Convention::default(),
            source: source.into(),
            notes: String::new(),
            parameters: BTreeMap::new(),
            joints: vec![],
            frames: vec![],
            closures: vec![],
            rcm: None,
            tip: None,
            serial_equivalent: None,
            tool: None,
            coupling: None,
            drive: None,
            effects: vec![],
            inertials: vec![],
            inertial_covariance: None,
            meshes: vec![],
        }
    }

    /// Parse a TOML model file's text; `path` names it in errors.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        toml::from_str(text).map_err(|e| toml_error(&e, text, path))
    }

    /// Write as TOML.
    pub fn to_toml(&self) -> Result<String> {
        toml::to_string_pretty(self).map_err(|e| KinError::field("model", e.to_string()))
    }
}

/// A one-line error from a TOML error: file, line, field and the value as written.
pub(crate) fn toml_error(e: &toml::de::Error, text: &str, path: &Path) -> KinError {
    KinError::File { path: path.into(), message: toml_message(e, text) }
}

/// The longest part of a value a TOML error echoes (characters): a 30,000-deep array is one
/// 60 kB line, and an error names the place, not the whole value.
const ECHOED_VALUE: usize = 80;

/// A TOML parse error of `text` on one line: `line N: field `key` = value: message`, the value
/// cut to [`ECHOED_VALUE`] characters (every reader of a TOML file words its errors with this).
pub fn toml_message(e: &toml::de::Error, text: &str) -> String {
    let message = e.message().trim().replace('\n', " ");
    let Some(span) = e.span() else { return message };
    let line_no = text[..span.start.min(text.len())].matches('\n').count() + 1;
    let line = text.lines().nth(line_no - 1).unwrap_or("").trim();
    let cut = |v: &str| {
        let n = v.chars().count();
        if n > ECHOED_VALUE {
            format!("{}... ({n} characters)", v.chars().take(ECHOED_VALUE).collect::<String>())
        } else {
            v.to_string()
        }
    };
    let detail = match line.split_once('=') {
        Some((key, value)) => format!("field `{}` = {}: {message}", cut(key.trim()), cut(value.trim())),
        None => format!("`{}`: {message}", cut(line)),
    };
    format!("line {line_no}: {detail}")
}
