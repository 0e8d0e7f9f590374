//! The kinematic channel's input: a tracker's poses of a marker body rigidly fixed on one link
//! (`--marker-topic T --marker-link FRAME`), read from the recording next to the joints, and
//! written by `dvrk synth hidden-effect --marker-link`.

use crate::recording::error::{RecordingError, Result};
use crate::recording::mcap_io::{self, McapOptions};
use dvrk_kin::{FrameRef, Model, Pose};
use std::path::Path;

/// Tracker poses of a marker body on one link.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerLog {
    /// Where the poses came from (topic or body name), for messages.
    pub topic: String,
    /// The link's frame in the model (index into `model.frames`).
    pub frame: usize,
    /// Sample times (s), increasing, on the joint log's clock.
    pub t: Vec<f64>,
    /// Marker body pose in the tracker frame (m).
    pub poses: Vec<Pose>,
}

/// The frame `--marker-link` names: a frame name, or the paper's frame number (PSM, ECM).
pub fn marker_frame(model: &Model, link: &str) -> Result<usize> {
    let r = match link.trim().parse::<i64>() {
        Ok(i) => FrameRef::Index(i),
        Err(_) => FrameRef::Name(link.trim().to_string()),
    };
    model.frame_id(&r).map_err(|e| RecordingError::field("--marker-link", format!("`{link}`: {e}")))
}

/// Read the pose track `topic` of an MCAP recording as the marker on `frame`.
pub fn read_mcap(path: &Path, topic: &str, frame: usize) -> Result<MarkerLog> {
    let options = McapOptions { topics: vec![topic.to_string()], joint_topic: None };
    let rec = mcap_io::read(path, &options)?;
    let body = rec.body(topic).map_err(|e| RecordingError::file(path, format!("--marker-topic {topic}: {e}")))?;
    let mut body = body.clone();
    body.sort_by_time();
    if body.len() < 50 {
        return Err(RecordingError::file(path, format!("--marker-topic {topic}: {} poses (need at least 50)", body.len())));
    }
    Ok(MarkerLog { topic: topic.to_string(), frame, t: body.t, poses: body.poses })
}

/// The topic a synthetic marker body on frame `frame_name` is written on.
pub fn synthetic_topic(frame_name: &str) -> String {
    mcap_io::pose_topic(&format!("marker_{frame_name}"))
}
