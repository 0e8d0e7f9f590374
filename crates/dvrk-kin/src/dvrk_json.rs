//! The dVRK's own configuration files (sawIntuitiveResearchKit `share/kinematic/*.json` and
//! `share/tool/*.json`, JSON with `//` and `/* */` comments), read into model specs so a user can
//! point `dvrk` at their robot's files.

use crate::error::{KinError, Result};
use crate::spec::{Convention, FrameJoint, FrameRef, FrameSpec, JointSpec, JointType, ModelSpec, ParameterSpec, Value};
use serde_json::Value as Json;
use std::path::Path;

/// Parse a dVRK JSON file (comments allowed).
pub fn read_json(path: &Path) -> Result<Json> {
    let text = crate::text_file::read_text(path)?;
    parse_json(&text, path)
}

/// Parse dVRK JSON text; `path` names it in errors.
pub fn parse_json(text: &str, path: &Path) -> Result<Json> {
    // json5's parser recurses per level: a deep file is refused before it can overflow the stack.
    if let Some(m) = crate::nesting::too_deep(crate::nesting::json_depth(text)) {
        return Err(KinError::File { path: path.into(), message: format!("not a dVRK JSON file: {m}") });
    }
    json5::from_str(text).map_err(|e| KinError::File { path: path.into(), message: format!("not valid JSON: {e}") })
}

fn get<'a>(v: &'a Json, key: &str, field: &str) -> Result<&'a Json> {
    v.get(key).ok_or_else(|| KinError::field(format!("{field}.{key}"), "missing"))
}

fn num(v: &Json, key: &str, field: &str) -> Result<f64> {
    let x = get(v, key, field)?;
    match x.as_f64() {
        Some(f) if f.is_finite() => Ok(f),
        _ => Err(KinError::field(format!("{field}.{key}"), format!("expected a number, got {x}"))),
    }
}

fn num_or(v: &Json, key: &str, field: &str, default: f64) -> Result<f64> {
    if v.get(key).is_some() {
        num(v, key, field)
    } else {
        Ok(default)
    }
}

fn matrix(v: &Json, field: &str) -> Result<Vec<Vec<f64>>> {
    let rows = v.as_array().ok_or_else(|| KinError::field(field, format!("expected a matrix, got {v}")))?;
    rows.iter()
        .enumerate()
        .map(|(i, r)| {
            let r = r.as_array().ok_or_else(|| KinError::field(format!("{field}[{i}]"), format!("expected a row, got {r}")))?;
            r.iter()
                .enumerate()
                .map(|(j, x)| {
                    x.as_f64().filter(|f| f.is_finite()).ok_or_else(|| KinError::field(format!("{field}[{i}][{j}]"), format!("expected a number, got {x}")))
                })
                .collect()
        })
        .collect()
}

fn matrix4(v: &Json, field: &str) -> Result<[[f64; 4]; 4]> {
    let m = matrix(v, field)?;
    if m.len() != 4 || m.iter().any(|r| r.len() != 4) {
        return Err(KinError::field(field, "expected a 4x4 matrix"));
    }
    let mut out = [[0.0; 4]; 4];
    for i in 0..4 {
        out[i].copy_from_slice(&m[i]);
    }
    Ok(out)
}

/// The DH list of a dVRK file: `DH.joints` (newer files) or `DH.links`.
fn dh_entries(v: &Json) -> Result<(Convention, &Vec<Json>, &'static str)> {
    let dh = get(v, "DH", "")?;
    let convention = match dh.get("convention").and_then(|c| c.as_str()) {
        None | Some("modified") => Convention::Modified,
        Some("standard") => Convention::Standard,
        Some(other) => return Err(KinError::field("DH.convention", format!("`{other}` is not one of: modified, standard"))),
    };
    for key in ["joints", "links"] {
        if let Some(list) = dh.get(key) {
            let list = list.as_array().ok_or_else(|| KinError::field(format!("DH.{key}"), "expected a list"))?;
            return Ok((convention, list, key));
        }
    }
    Err(KinError::field("DH.joints", "missing (neither DH.joints nor DH.links)"))
}

fn push_dh(spec: &mut ModelSpec, entry: &Json, field: &str, name_prefix: &str) -> Result<()> {
    let name = entry.get("name").and_then(|n| n.as_str()).map(|s| s.to_string()).unwrap_or_else(|| format!("joint_{}", spec.joints.len() + 1));
    let kind = match get(entry, "type", field)?.as_str() {
        Some("revolute") => JointType::Revolute,
        Some("prismatic") => JointType::Prismatic,
        other => return Err(KinError::field(format!("{field}.type"), format!("expected revolute or prismatic, got {other:?}"))),
    };
    let (alpha, a, theta, d, offset) =
        (num(entry, "alpha", field)?, num(entry, "A", field)?, num(entry, "theta", field)?, num(entry, "D", field)?, num_or(entry, "offset", field, 0.0)?);
    let (lower, upper) = (num_or(entry, "qmin", field, -std::f64::consts::PI)?, num_or(entry, "qmax", field, std::f64::consts::PI)?);
    let k = spec.joints.len() + 1;
    spec.joints.push(JointSpec {
        name: format!("{name_prefix}{name}"),
        kind,
        lower,
        upper,
        effort_limit: num_or(entry, "ftmax", field, 0.0)?,
        home: None,
        source: field.to_string(),
    });
    let parent = spec.frames.last().map_or(FrameRef::Index(0), |f| FrameRef::Name(f.name.clone()));
    let (joint, theta, d) = match kind {
        JointType::Revolute => (FrameJoint::Revolute, Value::Expr(format!("q{k} + {:?}", theta + offset)), Value::Number(d)),
        JointType::Prismatic => (FrameJoint::Prismatic, Value::Number(theta), Value::Expr(format!("q{k} + {:?}", d + offset))),
    };
    spec.frames.push(FrameSpec {
        index: Some(spec.frames.len() as i64 + 1),
        name: format!("{name_prefix}{name}"),
        parent,
        body: None,
        joint,
        a: Value::Number(a),
        alpha: Value::Number(alpha),
        d,
        theta,
        transform: None,
        source: field.to_string(),
    });
    Ok(())
}

/// A serial model from a dVRK arm file (PSM.json, ECM.json, MTMR.json...) and, for a PSM, a tool
/// file appended (its DH joints, the `jaw` joint and the `tooltip_offset` frame).
pub fn serial_spec(arm: &Path, tool: Option<&Path>) -> Result<ModelSpec> {
    let arm_json = read_json(arm)?;
    let mut spec = serial_spec_from_json(&arm_json, &model_name(arm)).map_err(|e| e.in_file(arm))?;
    if let Some(tool) = tool {
        let tool_json = read_json(tool)?;
        append_tool(&mut spec, &tool_json, &model_name(tool)).map_err(|e| e.in_file(tool))?;
    }
    Ok(spec)
}

fn model_name(p: &Path) -> String {
    p.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| "model".into())
}

/// [`serial_spec`] from parsed JSON.
pub fn serial_spec_from_json(v: &Json, name: &str) -> Result<ModelSpec> {
    let (convention, list, key) = dh_entries(v)?;
    let mut spec = ModelSpec {
        title: format!("{name} (dVRK serial chain)"),
        convention,
        ..ModelSpec::empty(name, "dVRK configuration file")
    };
    for (i, entry) in list.iter().enumerate() {
        push_dh(&mut spec, entry, &format!("DH.{key}[{i}]"), "")?;
    }
    if let Some(c) = v.get("coupling").and_then(|c| c.get("ActuatorToJointPosition")) {
        spec.coupling = Some(matrix(c, "coupling.ActuatorToJointPosition")?);
    }
    Ok(spec)
}

/// Append a tool file's joints and frames to a serial arm spec.
pub fn append_tool(spec: &mut ModelSpec, tool: &Json, tool_name: &str) -> Result<()> {
    let (convention, list, key) = dh_entries(tool)?;
    if convention != spec.convention {
        return Err(KinError::field("DH.convention", "the tool's convention differs from the arm's"));
    }
    for (i, entry) in list.iter().enumerate() {
        push_dh(spec, entry, &format!("DH.{key}[{i}]"), "")?;
    }
    // The tool tip and the jaw blades hang on the last DH frame (the wrist yaw); the tip first,
    // so that its number stays the one after the wrist's.
    let wrist = spec.frames.last().map_or(FrameRef::Index(0), |f| FrameRef::Name(f.name.clone()));
    if let Some(t) = tool.get("tooltip_offset") {
        let parent = wrist.clone();
        spec.frames.push(FrameSpec {
            index: Some(spec.frames.len() as i64 + 1),
            name: "tool_tip".into(),
            parent,
            body: None,
            joint: FrameJoint::Fixed,
            a: Value::Number(0.0),
            alpha: Value::Number(0.0),
            d: Value::Number(0.0),
            theta: Value::Number(0.0),
            transform: Some(matrix4(t, "tooltip_offset")?),
            source: format!("{tool_name} tooltip_offset"),
        });
        spec.tip = Some(FrameRef::Name("tool_tip".into()));
    }
    if let Some(jaw) = tool.get("jaw") {
        spec.joints.push(JointSpec {
            name: "jaw".into(),
            kind: JointType::Revolute,
            lower: num(jaw, "qmin", "jaw")?,
            upper: num(jaw, "qmax", "jaw")?,
            effort_limit: num_or(jaw, "ftmax", "jaw", 0.0)?,
            home: None,
            source: format!("{tool_name} jaw"),
        });
        // As the dVRK defines the jaw angle (and the built-in psm): two blades about the wrist
        // yaw's axis, at +- jaw/2 from it.
        let k = spec.joints.len();
        for (blade, sign) in [("jaw_1", "0.5"), ("jaw_2", "-0.5")] {
            spec.frames.push(FrameSpec {
                index: Some(spec.frames.len() as i64 + 1),
                name: blade.into(),
                parent: wrist.clone(),
                body: None,
                joint: FrameJoint::Revolute,
                a: Value::Number(0.0),
                alpha: Value::Number(0.0),
                d: Value::Number(0.0),
                theta: Value::Expr(format!("{sign}*q{k}")),
                transform: None,
                source: format!("{tool_name} jaw: blade at wrist yaw {} jaw/2", if sign.starts_with('-') { "-" } else { "+" }),
            });
        }
    }
    Ok(())
}

/// Put a dVRK tool file's figures into a model that has a `[tool]` section: tool length and jaw
/// offset parameters, the wrist and jaw limits, the tool-tip rotation and the wrist coupling.
pub fn apply_tool(spec: &mut ModelSpec, tool_path: &Path) -> Result<()> {
    let v = read_json(tool_path)?;
    apply_tool_json(spec, &v, &model_name(tool_path)).map_err(|e| e.in_file(tool_path))
}

/// [`apply_tool`] from parsed JSON.
pub fn apply_tool_json(spec: &mut ModelSpec, v: &Json, tool_name: &str) -> Result<()> {
    let tool = spec.tool.clone().ok_or_else(|| {
        KinError::field("tool", format!("model `{}` has no [tool] section, so it takes no tool file", spec.name))
    })?;
    let (_, list, key) = dh_entries(v)?;
    if list.len() != 3 {
        return Err(KinError::field(format!("DH.{key}"), format!("expected 3 tool joints (roll, wrist pitch, wrist yaw), got {}", list.len())));
    }
    // An arm file (the PSM's own yaw, pitch and insertion) has three joints too: its prismatic
    // insertion tells it (taken as a tool, its yaw's limits became the roll's, its length 0).
    if let Some(i) = list.iter().position(|e| e.get("type").and_then(|t| t.as_str()) == Some("prismatic")) {
        return Err(KinError::field(
            format!("DH.{key}[{i}].type"),
            "`prismatic`: a tool's three joints are revolute (roll, wrist pitch, wrist yaw); this is an arm's file (its insertion), not a tool's",
        ));
    }
    let source = format!("{tool_name} (dVRK tool file)");
    let length = num(&list[0], "D", &format!("DH.{key}[0]"))?;
    let jaw_offset = num(&list[2], "A", &format!("DH.{key}[2]"))?;
    for (param, value) in [(&tool.length_parameter, length), (&tool.jaw_offset_parameter, jaw_offset)] {
        spec.parameters.insert(param.clone(), ParameterSpec { value, unit: "m".into(), source: source.clone() });
    }
    for (i, entry) in list.iter().enumerate() {
        let field = format!("DH.{key}[{i}]");
        let Some(name) = tool.joints.get(i) else { break };
        let j = spec.joints.iter_mut().find(|j| &j.name == name).ok_or_else(|| KinError::field("tool.joints", format!("no joint `{name}` in the model")))?;
        j.lower = num(entry, "qmin", &field)?;
        j.upper = num(entry, "qmax", &field)?;
        j.effort_limit = num_or(entry, "ftmax", &field, j.effort_limit)?;
        j.source = source.clone();
    }
    if let (Some(jaw), Some(name)) = (v.get("jaw"), tool.joints.get(3)) {
        let j = spec.joints.iter_mut().find(|j| &j.name == name).ok_or_else(|| KinError::field("tool.joints", format!("no joint `{name}` in the model")))?;
        j.lower = num(jaw, "qmin", "jaw")?;
        j.upper = num(jaw, "qmax", "jaw")?;
        j.effort_limit = num_or(jaw, "ftmax", "jaw", j.effort_limit)?;
        j.source = source.clone();
    }
    for j in spec.joints.iter_mut() {
        if let Some(h) = j.home {
            j.home = Some(h.clamp(j.lower, j.upper));
        }
    }
    if let Some(t) = v.get("tooltip_offset") {
        let m = matrix4(t, "tooltip_offset")?;
        let f = spec.frames.iter_mut().find(|f| f.name == tool.tooltip_frame).ok_or_else(|| KinError::field("tool.tooltip_frame", format!("no frame `{}`", tool.tooltip_frame)))?;
        f.transform = Some(m);
        f.source = source.clone();
    }
    let mut tool_section = tool;
    if let Some(c) = v.get("coupling").and_then(|c| c.get("ActuatorToJointPosition")) {
        let m = matrix(c, "coupling.ActuatorToJointPosition")?;
        // Another size was dropped without a word when the model's coupling was built.
        let n = tool_section.joints.len();
        if m.len() != n || m.iter().any(|r| r.len() != n) {
            return Err(KinError::field(
                "coupling.ActuatorToJointPosition",
                format!("{}x{}, but the model's tool has {n} joints ({}): the coupling maps their actuators", m.len(), m.first().map_or(0, Vec::len), tool_section.joints.join(", ")),
            ));
        }
        tool_section.coupling = Some(m);
    }
    tool_section.name = tool_name.to_string();
    tool_section.source = source;
    spec.tool = Some(tool_section);
    Ok(())
}

/// One arm of the dVRK's SUJ file (`share/arm/suj-*.json`): its DH links as a serial spec, with
/// `world_origin_to_SUJ` and `SUJ_tip_to_tool_origin` (row-major 4x4, m) and the simulated
/// position as home.
pub fn suj_arm_spec(v: &Json, arm: &str) -> Result<(ModelSpec, [[f64; 4]; 4], [[f64; 4]; 4])> {
    let arms = get(v, "arms", "")?.as_array().ok_or_else(|| KinError::field("arms", "expected a list"))?;
    let names: Vec<String> = arms.iter().filter_map(|a| a.get("name").and_then(|n| n.as_str()).map(String::from)).collect();
    let (i, entry) = arms
        .iter()
        .enumerate()
        .find(|(_, a)| a.get("name").and_then(|n| n.as_str()) == Some(arm))
        .ok_or_else(|| KinError::unknown("SUJ arm", arm, &names))?;
    let field = format!("arms[{i}]");
    let mut spec = ModelSpec::empty(&format!("suj-{}", arm.to_lowercase()), "dVRK SUJ file");
    let dh = get(entry, "DH", &field)?;
    let links = get(dh, "links", &format!("{field}.DH"))?.as_array().ok_or_else(|| KinError::field(format!("{field}.DH.links"), "expected a list"))?;
    for (k, link) in links.iter().enumerate() {
        push_dh(&mut spec, link, &format!("{field}.DH.links[{k}]"), "")?;
    }
    if let Some(home) = entry.get("simulated_position").and_then(|h| h.as_array()) {
        for (j, h) in spec.joints.iter_mut().zip(home) {
            let x = h.as_f64().ok_or_else(|| KinError::field(format!("{field}.simulated_position"), format!("expected a number, got {h}")))?;
            j.home = Some(x);
            j.lower = j.lower.min(x);
            j.upper = j.upper.max(x);
        }
    }
    let transform = |key: &str| -> Result<[[f64; 4]; 4]> {
        let t = get(entry, key, &field)?;
        let f = format!("{field}.{key}");
        let tr = matrix(&Json::Array(vec![get(t, "Translation", &f)?.clone()]), &format!("{f}.Translation"))?;
        let rot = matrix(get(t, "Rotation", &f)?, &format!("{f}.Rotation"))?;
        if tr[0].len() != 3 || rot.len() != 3 || rot.iter().any(|r| r.len() != 3) {
            return Err(KinError::field(f, "expected a 3-vector Translation and a 3x3 Rotation"));
        }
        let mut m = [[0.0, 0.0, 0.0, 0.0], [0.0; 4], [0.0; 4], [0.0, 0.0, 0.0, 1.0]];
        for r in 0..3 {
            m[r][..3].copy_from_slice(&rot[r]);
            m[r][3] = tr[0][r];
        }
        Ok(m)
    };
    Ok((spec, transform("world_origin_to_SUJ")?, transform("SUJ_tip_to_tool_origin")?))
}
