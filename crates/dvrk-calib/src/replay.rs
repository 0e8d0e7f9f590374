//! Joint trajectories to replay in a simulation (`dvrk sim --trajectory replay:FILE`), read from
//! a recording:
//! - MCAP: for each arm of the scene, `/<ARM>/setpoint_js` (what the arm was told), else
//!   `/<ARM>/measured_js` (what it did); arms with neither hold home. Joints are matched by
//!   name; joints the topic lacks (the dVRK publishes the PSM jaw on its own topic) hold home.
//! - CSV (the plain format of [`crate::plain_csv`]): `time` and `q1..qN` for the one arm of
//!   the scene that runs the tracking test.

use crate::error::{CalibError, Result};
use crate::discrepancy::joint_log::read_joint_states;
use crate::mcap_io::McapOptions;
use crate::read::read_recording;
use crate::recording::JointTrack;
use dvrk_sim::run::Replay;
use dvrk_sim::scene::Tracking;
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::Scene;
use std::path::Path;

/// Read the trajectories in `path` for the arms of `scene`.
pub fn read_replay(path: &Path, scene: &Scene) -> Result<Replay> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    let mut arms = Vec::new();
    if ext == "mcap" {
        if !path.exists() {
            return Err(CalibError::file(path, "no such file"));
        }
        // One pass over the file for every arm's two candidate topics.
        let topic = |arm: &str, kind: &str| format!("/{arm}/{kind}");
        let wanted: Vec<String> = scene.arms.iter().flat_map(|a| [topic(&a.name, "setpoint_js"), topic(&a.name, "measured_js")]).collect();
        let (mut found, _) = read_joint_states(path, &wanted.iter().map(String::as_str).collect::<Vec<_>>())?;
        let mut missing = Vec::new();
        for arm in &scene.arms {
            // The setpoints (what the arm was told), else the measurements (what it did).
            let source = ["setpoint_js", "measured_js"].map(|k| topic(&arm.name, k)).into_iter().find(|t| found.contains_key(t));
            match source.and_then(|t| found.remove(&t).map(|js| (t, js))) {
                Some((source, js)) => {
                    let track = JointTrack { source, names: js.names, t: js.t, q: js.position };
                    arms.push((arm.name.clone(), by_name(path, &track, &arm.model)?));
                }
                None => missing.push(arm.name.as_str()),
            }
        }
        if arms.is_empty() {
            return Err(CalibError::file(path, format!("no /<ARM>/setpoint_js or /<ARM>/measured_js topic for any arm of scene {} ({})", scene.name, missing.join(", "))));
        }
    } else {
        let rec = read_recording(path, &McapOptions::default())?;
        let Some(track) = rec.joints else {
            return Err(CalibError::file(path, "no joint columns (q1..qN) to replay"));
        };
        let tracked: Vec<_> = scene.arms.iter().filter(|a| a.tracking == Tracking::Sine).collect();
        let [arm] = tracked.as_slice() else {
            let names: Vec<&str> = tracked.iter().map(|a| a.name.as_str()).collect();
            return Err(CalibError::file(
                path,
                format!("a CSV holds one arm's joints, but scene {} tracks {} arms ({}); use an MCAP recording with /<ARM>/setpoint_js topics", scene.name, names.len(), names.join(", ")),
            ));
        };
        let nq = arm.model.nq();
        if track.names.len() != nq {
            return Err(CalibError::file(path, format!("{} joint columns, arm {} has {nq} joints", track.names.len(), arm.name)));
        }
        let traj = Trajectory::samples(&path.display().to_string(), &track.t, track.q, nq).map_err(|e| CalibError::data("replay", e))?;
        arms.push((arm.name.clone(), traj));
    }
    Ok(Replay { source: path.display().to_string(), arms })
}

/// The track's joints placed by name into the model's joint vector; joints it lacks hold home.
fn by_name(path: &Path, track: &JointTrack, model: &dvrk_kin::Model) -> Result<Trajectory> {
    let home = model.home();
    let mut index = Vec::with_capacity(track.names.len());
    for name in &track.names {
        let k = model.joints.iter().position(|j| &j.name == name).ok_or_else(|| {
            let valid: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
            CalibError::file(path, format!("{}: joint `{name}` is not a joint of {} (joints: {})", track.source, model.name, valid.join(", ")))
        })?;
        index.push(k);
    }
    let q = track
        .q
        .iter()
        .map(|row| {
            let mut q = home.clone();
            for (k, x) in index.iter().zip(row) {
                q[*k] = *x;
            }
            q
        })
        .collect();
    Trajectory::samples(&format!("{} {}", path.display(), track.source), &track.t, q, model.nq()).map_err(|e| CalibError::data("replay", e))
}
