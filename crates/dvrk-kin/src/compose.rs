//! Systems: several models mounted on each other (the cart: SUJ arms carrying a PSM or the ECM),
//! merged into one tree so that one FK pass places every link of every arm.

use crate::error::{KinError, Result};
use crate::expr::Affine;
use crate::model::{pose_from_rows, Frame, Model, Motion, Part, Pose, Rcm};
use crate::spec::{FrameJoint, ModelSpec};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// How an arm's mount transform is meant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Attach {
    /// The mount places the arm's base frame (frame 0).
    #[default]
    Base,
    /// The mount places the base frame of the arm's serial dVRK equivalent (the RCM frame of a
    /// PSM or ECM, as the dVRK's `SUJ_tip_to_tool_origin` does).
    SerialBase,
}

/// One arm of a system file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmSpec {
    /// Prefix of the arm's frame and joint names (`PSM1`).
    pub name: String,
    /// Built-in model name or path relative to the system file.
    pub model: String,
    /// dVRK tool file for the arm (path relative to the system file).
    #[serde(default)]
    pub tool: Option<String>,
    /// `"base"` (the world) or the name of an arm listed before this one.
    #[serde(default = "base")]
    pub parent: String,
    /// Frame of the parent arm the mount is relative to (name or number).
    #[serde(default)]
    pub parent_frame: Option<crate::spec::FrameRef>,
    /// Row-major 4x4 transform from the parent frame (m).
    pub mount: [[f64; 4]; 4],
    #[serde(default)]
    pub attach: Attach,
    /// Home configuration of the arm's joints (rad / m).
    #[serde(default)]
    pub home: Option<Vec<f64>>,
    #[serde(default)]
    pub source: String,
}

fn base() -> String {
    "base".into()
}

/// A system file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SystemSpec {
    pub name: String,
    #[serde(default)]
    pub title: String,
    #[serde(default)]
    pub source: String,
    #[serde(default)]
    pub notes: String,
    pub arms: Vec<ArmSpec>,
}

impl SystemSpec {
    /// Parse a system file's text.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        toml::from_str(text).map_err(|e| crate::spec::toml_error(&e, text, path))
    }
}

/// The constant transform from a closed-loop model's base frame to the base of its serial dVRK
/// equivalent (`T_closed(q) = B * T_serial(q)` on the paired frames).
pub fn serial_base_transform(model: &Model) -> Result<Pose> {
    let serial = crate::load::load_serial_equivalent(model)?
        .ok_or_else(|| KinError::field("serial_equivalent", format!("model `{}` names no serial equivalent", model.name)))?;
    let pairs = &model.spec.serial_equivalent.as_ref().expect("checked").pairs;
    let first = pairs.first().ok_or_else(|| KinError::field("serial_equivalent.pairs", "empty"))?;
    let (a, b) = (model.frame_id(&first[0])?, serial.frame_id(&first[1])?);
    let q = model.home();
    let qs: Vec<f64> = q.iter().copied().take(serial.nq()).collect();
    if qs.len() != serial.nq() {
        return Err(KinError::Size { what: "serial equivalent joints".into(), expected: q.len(), got: serial.nq() });
    }
    Ok(model.fk(&q)?[a] * serial.fk(&qs)?[b].inverse())
}

/// Merge the arms of `spec` into one model.
pub fn compose(spec: &SystemSpec, dir: Option<&Path>) -> Result<Model> {
    let mut arms: Vec<Mounted> = Vec::with_capacity(spec.arms.len());
    for (ai, arm_spec) in spec.arms.iter().enumerate() {
        let field = |f: &str| format!("arms[{ai}] ({}).{f}", arm_spec.name);
        let tool = arm_spec.tool.as_ref().map(|t| match dir {
            Some(d) => d.join(t),
            None => t.into(),
        });
        let mut arm = crate::load::load_relative(&arm_spec.model, tool.as_deref(), dir)
            .map_err(|e| KinError::field(field("model"), e.to_string()))?;
        if let Some(h) = &arm_spec.home {
            if h.len() != arm.nq() {
                return Err(KinError::field(field("home"), format!("expected {} values, got {}", arm.nq(), h.len())));
            }
            arm.check_q(h).map_err(|e| KinError::field(field("home"), e.to_string()))?;
            for (j, x) in arm.joints.iter_mut().zip(h) {
                j.home = *x;
            }
        }
        let mut mount = pose_from_rows(&arm_spec.mount, &field("mount"))?;
        if arm_spec.attach == Attach::SerialBase {
            mount *= serial_base_transform(&arm).map_err(|e| KinError::field(field("attach"), e.to_string()))?.inverse();
        }
        let parent = if arm_spec.parent == "base" {
            None
        } else {
            let pi = arms.iter().position(|p| p.name == arm_spec.parent).ok_or_else(|| {
                KinError::field(field("parent"), KinError::unknown("arm", &arm_spec.parent, std::iter::once("base".to_string()).chain(arms.iter().map(|p| p.name.clone()))).to_string())
            })?;
            let fr = arm_spec.parent_frame.as_ref().ok_or_else(|| KinError::field(field("parent_frame"), "missing (needed when parent is an arm)"))?;
            let local = arms[pi].model.frame_id(fr).map_err(|e| KinError::field(field("parent_frame"), e.to_string()))?;
            Some((pi, local))
        };
        // An arm on the base stands on the cart: its mount frame is the cart body.
        let mount_body = parent.is_none().then(|| "cart".to_string());
        arms.push(Mounted { name: arm_spec.name.clone(), source: arm_spec.model.clone(), model: arm, parent, mount, mount_body });
    }
    let mut model = merge(&spec.name, &arms)?;
    model.title = spec.title.clone();
    model.spec = ModelSpec { title: spec.title.clone(), notes: spec.notes.clone(), ..ModelSpec::empty(&spec.name, &spec.source) };
    Ok(model)
}

/// One arm of a merged model: `model` placed by `mount` on frame `parent.1` (a frame of
/// `model`'s own numbering) of arm `parent.0` (listed before it), or on the merged model's base.
#[derive(Debug, Clone)]
pub struct Mounted {
    /// Prefix of its frame, joint and body names.
    pub name: String,
    /// Where the model came from (a built-in name or a path), for [`Part::model`].
    pub source: String,
    pub model: Model,
    pub parent: Option<(usize, usize)>,
    /// The arm's base in its parent frame (m). The model's own `base` is not used.
    pub mount: Pose,
    /// The body the mount frame is declared part of (`None`: the body it is rigid to).
    pub mount_body: Option<String>,
}

/// One tree of `arms`: each arm's frames under a fixed mount frame, its joints after the
/// previous arms' (the [`Part`]s say where), its bodies named `ARM/body`. The merged model's
/// base is the identity and it has no effects, coupling or RCM of its own.
pub fn merge(name: &str, arms: &[Mounted]) -> Result<Model> {
    let mut frames: Vec<Frame> = Vec::new();
    let mut joints = Vec::new();
    let mut closures = Vec::new();
    let mut parts: Vec<Part> = Vec::new();
    let mut declared: Vec<Option<String>> = Vec::new();
    for (ai, m) in arms.iter().enumerate() {
        let arm = &m.model;
        let parent = match m.parent {
            None => None,
            Some((pi, local)) => {
                let p = parts.get(pi).filter(|_| pi < ai).ok_or_else(|| KinError::field(format!("arms[{ai}] ({}).parent", m.name), format!("arm {pi} is not listed before it")))?;
                if local >= p.frames.len() - 1 {
                    return Err(KinError::field(format!("arms[{ai}] ({}).parent_frame", m.name), format!("frame {local} is not a frame of {}", p.name)));
                }
                Some(p.frames.start + 1 + local)
            }
        };
        let nq_before = joints.len();
        let frame_start = frames.len();
        frames.push(Frame {
            index: frames.len() as i64 + 1,
            name: format!("{}/mount", m.name),
            parent,
            body: 0,
            joint: FrameJoint::Fixed,
            a: f64::NAN,
            alpha: f64::NAN,
            theta: Affine::constant(0, 0.0),
            d: Affine::constant(0, 0.0),
            pre: Pose::identity(),
            post: None,
            motion: Motion::Fixed(m.mount),
        });
        declared.push(m.mount_body.clone());
        for f in &arm.frames {
            let mut g = f.clone();
            g.index = frames.len() as i64 + 1;
            g.name = format!("{}/{}", m.name, f.name);
            g.parent = Some(match f.parent {
                Some(p) => frame_start + 1 + p,
                None => frame_start,
            });
            declared.push(Some(format!("{}/{}", m.name, arm.bodies[f.body].name)));
            frames.push(g);
        }
        for j in &arm.joints {
            let mut j = j.clone();
            j.name = format!("{}/{}", m.name, j.name);
            joints.push(j);
        }
        for c in &arm.closures {
            let mut c = c.clone();
            c.name = format!("{}/{}", m.name, c.name);
            c.frame += frame_start + 1;
            c.partner += frame_start + 1;
            closures.push(c);
        }
        let rcm = arm.rcm.as_ref().map(|r| Rcm { frame: r.frame + frame_start + 1, point: r.point });
        parts.push(Part { name: m.name.clone(), model: m.source.clone(), joints: nq_before..nq_before + arm.nq(), frames: frame_start..frames.len(), rcm });
    }
    // Re-index every affine map over the merged joints.
    let nq = joints.len();
    for part in &parts {
        for f in &mut frames[part.frames.clone()] {
            for aff in [&mut f.theta, &mut f.d] {
                let mut coef = vec![0.0; nq];
                for (k, c) in aff.joints() {
                    coef[part.joints.start + k] = c;
                }
                aff.coef = coef;
            }
        }
    }
    let tip = parts.last().map_or(0, |p| p.frames.start + 1 + arms.last().map_or(0, |a| a.model.tip));
    let mut model = Model {
        name: name.to_string(),
        title: name.to_string(),
        joints,
        frames,
        bodies: Vec::new(),
        closures,
        rcm: None,
        tip,
        base: Pose::identity(),
        coupling: None,
        spec: ModelSpec::empty(name, ""),
        origin: None,
        tool_file: None,
        effects: Vec::new(),
        parts,
        eval: Default::default(),
    };
    model.finalize(&declared)?;
    Ok(model)
}
