//! Foxglove's pose messages: foxglove.PoseInFrame (one pose per message),
//! foxglove.FrameTransform and foxglove.FrameTransforms (child frames), in JSON
//! (`message_encoding = "json"`) or in the SDK's protobuf (what `dvrk sim --out` writes).

use ::foxglove::messages::{self as fox, FrameTransform, FrameTransforms, PoseInFrame};
use ::foxglove::Decode;
use serde_json::{json, Value};

/// A decoded pose: time (s), parent frame, child frame (empty for PoseInFrame), position (m),
/// quaternion (x, y, z, w).
#[derive(Debug, Clone, PartialEq)]
pub struct FoxglovePose {
    pub time: f64,
    pub frame_id: String,
    pub child_frame_id: String,
    pub position: [f64; 3],
    pub orientation: [f64; 4],
}

fn num(v: &Value, path: &str) -> Result<f64, String> {
    let mut cur = v;
    for key in path.split('.') {
        cur = cur.get(key).ok_or_else(|| format!("field `{path}` is missing"))?;
    }
    cur.as_f64().ok_or_else(|| format!("field `{path}` = {cur} is not a number"))
}

fn text(v: &Value, key: &str) -> Result<String, String> {
    match v.get(key) {
        None => Ok(String::new()),
        Some(Value::String(s)) => Ok(s.clone()),
        Some(other) => Err(format!("field `{key}` = {other} is not a string")),
    }
}

fn time(v: &Value) -> Result<f64, String> {
    Ok(num(v, "timestamp.sec")? + num(v, "timestamp.nsec")? * 1e-9)
}

/// foxglove.PoseInFrame from JSON bytes.
pub fn decode_pose_in_frame(bytes: &[u8]) -> Result<FoxglovePose, String> {
    let v: Value = serde_json::from_slice(bytes).map_err(|e| format!("not JSON: {e}"))?;
    Ok(FoxglovePose {
        time: time(&v)?,
        frame_id: text(&v, "frame_id")?,
        child_frame_id: String::new(),
        position: [num(&v, "pose.position.x")?, num(&v, "pose.position.y")?, num(&v, "pose.position.z")?],
        orientation: [num(&v, "pose.orientation.x")?, num(&v, "pose.orientation.y")?, num(&v, "pose.orientation.z")?, num(&v, "pose.orientation.w")?],
    })
}

fn frame_transform(v: &Value) -> Result<FoxglovePose, String> {
    Ok(FoxglovePose {
        time: time(v)?,
        frame_id: text(v, "parent_frame_id")?,
        child_frame_id: text(v, "child_frame_id")?,
        position: [num(v, "translation.x")?, num(v, "translation.y")?, num(v, "translation.z")?],
        orientation: [num(v, "rotation.x")?, num(v, "rotation.y")?, num(v, "rotation.z")?, num(v, "rotation.w")?],
    })
}

/// foxglove.FrameTransform (one) or foxglove.FrameTransforms (`transforms: [...]`) from JSON bytes.
pub fn decode_frame_transforms(bytes: &[u8]) -> Result<Vec<FoxglovePose>, String> {
    let v: Value = serde_json::from_slice(bytes).map_err(|e| format!("not JSON: {e}"))?;
    match v.get("transforms") {
        Some(Value::Array(a)) => a.iter().enumerate().map(|(i, t)| frame_transform(t).map_err(|e| format!("transforms[{i}]: {e}"))).collect(),
        Some(other) => Err(format!("field `transforms` = {other} is not an array")),
        None => frame_transform(&v).map(|p| vec![p]),
    }
}

fn required<T>(field: Option<T>, name: &str) -> Result<T, String> {
    field.ok_or_else(|| format!("field `{name}` is missing"))
}

fn proto_time(t: Option<fox::Timestamp>) -> Result<f64, String> {
    let t = required(t, "timestamp")?;
    Ok(t.sec() as f64 + t.nsec() as f64 * 1e-9)
}

fn proto_transform(t: FrameTransform) -> Result<FoxglovePose, String> {
    let (p, q) = (required(t.translation, "translation")?, required(t.rotation, "rotation")?);
    Ok(FoxglovePose { time: proto_time(t.timestamp)?, frame_id: t.parent_frame_id, child_frame_id: t.child_frame_id, position: [p.x, p.y, p.z], orientation: [q.x, q.y, q.z, q.w] })
}

/// foxglove.PoseInFrame in protobuf.
pub fn decode_pose_in_frame_protobuf(bytes: &[u8]) -> Result<FoxglovePose, String> {
    let m = PoseInFrame::decode(bytes).map_err(|e| format!("not a protobuf foxglove.PoseInFrame: {e}"))?;
    let pose = required(m.pose, "pose")?;
    let (p, q) = (required(pose.position, "pose.position")?, required(pose.orientation, "pose.orientation")?);
    Ok(FoxglovePose { time: proto_time(m.timestamp)?, frame_id: m.frame_id, child_frame_id: String::new(), position: [p.x, p.y, p.z], orientation: [q.x, q.y, q.z, q.w] })
}

/// foxglove.FrameTransforms (`many`) or one foxglove.FrameTransform in protobuf.
pub fn decode_frame_transforms_protobuf(bytes: &[u8], many: bool) -> Result<Vec<FoxglovePose>, String> {
    if !many {
        let t = FrameTransform::decode(bytes).map_err(|e| format!("not a protobuf foxglove.FrameTransform: {e}"))?;
        return proto_transform(t).map(|p| vec![p]);
    }
    let m = FrameTransforms::decode(bytes).map_err(|e| format!("not a protobuf foxglove.FrameTransforms: {e}"))?;
    m.transforms.into_iter().enumerate().map(|(i, t)| proto_transform(t).map_err(|e| format!("transforms[{i}]: {e}"))).collect()
}

/// foxglove.PoseInFrame in protobuf (the SDK's schema), as the synthetic tracker's `foxglove`
/// layout writes it.
pub fn encode_pose_in_frame_protobuf(p: &FoxglovePose) -> Vec<u8> {
    let [x, y, z] = p.position;
    let [qx, qy, qz, qw] = p.orientation;
    let m = PoseInFrame {
        timestamp: Some(crate::recording::frame_transform::timestamp(p.time)),
        frame_id: p.frame_id.clone(),
        pose: Some(fox::Pose { position: Some(fox::Vector3 { x, y, z }), orientation: Some(fox::Quaternion { x: qx, y: qy, z: qz, w: qw }) }),
    };
    let mut buf = Vec::new();
    ::foxglove::Encode::encode(&m, &mut buf).expect("a Vec grows to any message");
    buf
}

/// foxglove.PoseInFrame as JSON bytes.
pub fn encode_pose_in_frame(p: &FoxglovePose) -> Vec<u8> {
    let sec = p.time.floor();
    let nsec = ((p.time - sec) * 1e9).round().min(999_999_999.0);
    let [x, y, z] = p.position;
    let [qx, qy, qz, qw] = p.orientation;
    json!({
        "timestamp": {"sec": sec as i64, "nsec": nsec as i64},
        "frame_id": p.frame_id,
        "pose": {"position": {"x": x, "y": y, "z": z}, "orientation": {"x": qx, "y": qy, "z": qz, "w": qw}},
    })
    .to_string()
    .into_bytes()
}

/// The JSON schema of foxglove.PoseInFrame (as Foxglove publishes it, trimmed to the fields).
pub const POSE_IN_FRAME_SCHEMA: &str = r#"{"title":"foxglove.PoseInFrame","description":"A timestamped pose for an object or reference frame in 3D space","$comment":"Generated by dvrk-calib","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}},"frame_id":{"type":"string"},"pose":{"type":"object","properties":{"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}}}}"#;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_in_frame_round_trips_and_names_missing_fields() {
        let p = FoxglovePose { time: 3.5, frame_id: "tracker".into(), child_frame_id: String::new(), position: [0.1, 0.2, 0.3], orientation: [0.0, 0.0, 0.0, 1.0] };
        assert_eq!(decode_pose_in_frame(&encode_pose_in_frame(&p)).unwrap(), p);
        let e = decode_pose_in_frame(br#"{"timestamp":{"sec":1,"nsec":0},"pose":{"position":{"x":1,"y":2}}}"#).unwrap_err();
        assert_eq!(e, "field `pose.position.z` is missing");
        let t = decode_frame_transforms(br#"{"transforms":[{"timestamp":{"sec":1,"nsec":500000000},"parent_frame_id":"w","child_frame_id":"b","translation":{"x":1,"y":2,"z":3},"rotation":{"x":0,"y":0,"z":0,"w":1}}]}"#).unwrap();
        assert_eq!((t[0].time, t[0].child_frame_id.as_str(), t[0].position), (1.5, "b", [1.0, 2.0, 3.0]));
    }

    #[test]
    fn protobuf_poses_and_transforms_decode_and_name_missing_fields() {
        let p = FoxglovePose { time: 3.5, frame_id: "tracker".into(), child_frame_id: String::new(), position: [0.1, 0.2, 0.3], orientation: [0.0, 0.0, 0.0, 1.0] };
        assert_eq!(decode_pose_in_frame_protobuf(&encode_pose_in_frame_protobuf(&p)).unwrap(), p);
        // The simulator's /tf writer, read back here (an independent reader: the SDK's decoder).
        let mut buf = Vec::new();
        crate::recording::frame_transform::encode(vec![crate::recording::frame_transform::transform(1.5, "w", "b", [1.0, 2.0, 3.0], [0.0, 0.0, 0.0, 1.0])], &mut buf);
        let t = decode_frame_transforms_protobuf(&buf, true).unwrap();
        assert_eq!((t[0].time, t[0].frame_id.as_str(), t[0].child_frame_id.as_str(), t[0].position), (1.5, "w", "b", [1.0, 2.0, 3.0]));
        let mut one = Vec::new();
        ::foxglove::Encode::encode(&FrameTransform { timestamp: Some(fox::Timestamp::new(2, 0)), child_frame_id: "c".into(), ..Default::default() }, &mut one).unwrap();
        assert_eq!(decode_frame_transforms_protobuf(&one, false).unwrap_err(), "field `translation` is missing");
    }
}
