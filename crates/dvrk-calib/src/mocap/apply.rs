//! A model file for one specific robot: the PSM spec with the lengths and angle that its axes
//! gave (`dvrk calib apply`). Edits frames 4, 6, 7, 8 (and 5's partner lengths through the
//! closures), recomputes `beta1`, `beta2` and `insertion_offset` as models/psm.toml's notes 2-4
//! do, so the insertion axis still passes through a fixed RCM, and checks the result compiles
//! with closed loops and a fixed RCM.

use crate::error::{CalibError, Result};
use dvrk_kin::spec::Value;
use dvrk_kin::{FrameRef, Model, ModelSpec};

/// The calibrated quantities (m, rad), from an axes result.
#[derive(Debug, Clone, PartialEq)]
pub struct PsmUpdate {
    /// Frame 4's `a` minus frame 3's (the 3-4 / 6-c1 side).
    pub l34: f64,
    /// Frame 6's `a` (the 3-6 / 4-c1 side).
    pub a6: f64,
    /// Frame 7's `a` (3-7).
    pub a7: f64,
    /// Frame 8's `a` (the 6-8 / 7-c2 side).
    pub a8: f64,
    /// `beta2 - beta1` (rad).
    pub beta_difference: f64,
    /// Where the figures came from (a file), for the sources written beside them.
    pub source: String,
}

/// One edited entry: what, old value, new value.
#[derive(Debug, Clone, PartialEq)]
pub struct Change {
    pub what: String,
    pub old: f64,
    pub new: f64,
}

/// The edited spec and its changes.
#[derive(Debug, Clone)]
pub struct Applied {
    pub spec: ModelSpec,
    pub changes: Vec<Change>,
    /// The compiled model (for its RCM and checks).
    pub model: Model,
}

fn frame_pos(spec: &ModelSpec, index: i64) -> Result<usize> {
    spec.frames
        .iter()
        .position(|f| f.index == Some(index))
        .ok_or_else(|| CalibError::field(format!("frames (index {index})"), format!("model `{}` has no frame {index}; `calib apply` edits the PSM layout (frames 3-9, closures c1 and c2)", spec.name)))
}

fn number(v: &Value, field: &str) -> Result<f64> {
    match v {
        Value::Number(x) => Ok(*x),
        Value::Expr(e) => Err(CalibError::field(field, format!("is the expression `{e}`; calib apply edits numeric DH lengths"))),
    }
}

fn param(spec: &ModelSpec, name: &str) -> Result<f64> {
    spec.parameters
        .get(name)
        .map(|p| p.value)
        .ok_or_else(|| CalibError::field(format!("parameters.{name}"), format!("model `{}` has no parameter {name}", spec.name)))
}

/// The PSM's double parallelogram as models/psm.toml lays it out: pitch frames 3, 4, 5 children
/// of frame 2 (3 and 5 on one axis), 6 on 3, 7 on 5, 8 on 6, 9 on 8, all in one plane
/// (alpha = 0 for 3 to 8). Another layout (the ECM's) would be edited into nonsense.
fn check_psm_layout(spec: &ModelSpec) -> Result<()> {
    let parent = |i: i64| -> Result<Option<i64>> {
        let f = &spec.frames[frame_pos(spec, i)?];
        Ok(match &f.parent {
            FrameRef::Index(p) => Some(*p),
            FrameRef::Name(n) => spec.frames.iter().find(|g| &g.name == n).and_then(|g| g.index),
        })
    };
    let layout = [(3, 2), (4, 2), (5, 2), (6, 3), (7, 5), (8, 6), (9, 8)];
    for (child, want) in layout {
        if parent(child)? != Some(want) {
            return Err(CalibError::field(
                format!("frames (index {child}).parent"),
                format!("model `{}` is not the PSM layout calib apply edits (frame {child} must hang from frame {want}; parents 3, 4, 5 <- 2, 6 <- 3, 7 <- 5, 8 <- 6, 9 <- 8)", spec.name),
            ));
        }
    }
    for i in 3..=8 {
        let f = &spec.frames[frame_pos(spec, i)?];
        if f.alpha != Value::Number(0.0) {
            return Err(CalibError::field(format!("frames (index {i}).alpha"), format!("model `{}`: the PSM's linkage frames 3-8 lie in one plane (alpha = 0)", spec.name)));
        }
    }
    let (a3, a5) = (number(&spec.frames[frame_pos(spec, 3)?].a, "frames (3).a")?, number(&spec.frames[frame_pos(spec, 5)?].a, "frames (5).a")?);
    if a3 != a5 {
        return Err(CalibError::field("frames (index 5).a", format!("{a5} m differs from frame 3's {a3} m: frames 3 and 5 must share the pitch axis")));
    }
    Ok(())
}

/// Apply `u` to a PSM spec; `name` becomes the new model's name.
pub fn apply_psm(spec: &ModelSpec, u: &PsmUpdate, name: &str) -> Result<Applied> {
    for (field, v) in [("l34", u.l34), ("a6", u.a6), ("a7", u.a7), ("a8", u.a8), ("beta_difference", u.beta_difference)] {
        if !v.is_finite() {
            return Err(CalibError::field(format!("dh.{field}"), format!("{v} is not finite")));
        }
    }
    for (field, v) in [("l34", u.l34), ("a6", u.a6), ("a7", u.a7), ("a8", u.a8)] {
        if v <= 0.0 {
            return Err(CalibError::field(format!("dh.{field}"), format!("{v} m is not a length")));
        }
    }
    check_psm_layout(spec)?;
    let mut s = spec.clone();
    let mut changes = Vec::new();
    let f3 = frame_pos(&s, 3)?;
    let a3 = number(&s.frames[f3].a, "frames (3).a")?;
    let a9 = number(&s.frames[frame_pos(&s, 9)?].a, "frames (9).a")?;
    if a9 >= u.a6 {
        return Err(CalibError::field("dh.a6", format!("{} m is not longer than the insertion offset a9 = {a9} m, so no beta1 satisfies a6 sin(beta1) = a9", u.a6)));
    }
    let (beta1_old, a6_old, offset_old) = (param(&s, "beta1")?, number(&s.frames[frame_pos(&s, 6)?].a, "frames (6).a")?, param(&s, "insertion_offset")?);
    // The dVRK's frame-3 offset from the RCM that insertion_offset keeps (0.4318 m for the PSM).
    let rcm_to_q3_zero = offset_old + a6_old * beta1_old.cos();
    let beta1 = (a9 / u.a6).asin();
    let beta2 = beta1 + u.beta_difference;
    let offset = rcm_to_q3_zero - u.a6 * beta1.cos();
    for (index, value) in [(4, a3 + u.l34), (6, u.a6), (7, u.a7), (8, u.a8)] {
        let i = frame_pos(&s, index)?;
        let old = number(&s.frames[i].a, &format!("frames ({index}).a"))?;
        s.frames[i].a = Value::Number(value);
        s.frames[i].source = format!("{} | calibrated: a = {value:.6} m from {}", s.frames[i].source, u.source);
        changes.push(Change { what: format!("frame {index} a (m)"), old, new: value });
    }
    for (p, value, how) in [
        ("beta1", beta1, "asin(a9 / a6) (RCM condition)"),
        ("beta2", beta2, "beta1 + measured angle 6-3-7"),
        ("insertion_offset", offset, "0.4318 - a6 cos(beta1)"),
    ] {
        let entry = s.parameters.get_mut(p).ok_or_else(|| CalibError::field(format!("parameters.{p}"), "missing"))?;
        changes.push(Change { what: format!("parameter {p}"), old: entry.value, new: value });
        entry.value = value;
        entry.source = format!("calibrated: {how} from {}", u.source);
    }
    for c in s.closures.iter_mut() {
        match c.name.as_str() {
            "c1" => {
                changes.push(Change { what: "closure c1 point x (m)".into(), old: c.point[0], new: u.a6 });
                c.point = [u.a6, 0.0, 0.0];
                if let Some(pp) = c.partner_point.as_mut() {
                    changes.push(Change { what: "closure c1 partner_point x (m)".into(), old: pp[0], new: u.l34 });
                    *pp = [u.l34, 0.0, 0.0];
                }
            }
            "c2" => {
                changes.push(Change { what: "closure c2 point x (m)".into(), old: c.point[0], new: u.a8 });
                c.point = [u.a8, 0.0, 0.0];
                // The point in frame 8 is recomputed at home from the new lengths.
                c.partner_point = None;
            }
            _ => {}
        }
    }
    s.name = name.to_string();
    s.title = format!("{} (calibrated from {})", spec.title, u.source);
    s.notes = format!(
        "{}\nCalibrated by `dvrk calib apply` from {}: frames 4, 6, 7, 8 lengths, beta1 = asin(a9/a6), beta2 = beta1 + angle 6-3-7, \
         insertion_offset = {rcm_to_q3_zero:.4} - a6 cos(beta1); the serial equivalent still names the nominal dVRK chain.\n",
        spec.notes, u.source
    );
    let model = Model::compile(s.clone())?;
    if let Some(r) = dvrk_kin::rcm::max_pivot_residual(&model, 200) {
        if r > 1e-9 {
            return Err(CalibError::field("dh", format!("the calibrated model's insertion axis misses its RCM by {:.3e} m", r)));
        }
    }
    model.frame_id(&FrameRef::Index(8))?;
    Ok(Applied { spec: s, changes, model })
}
