//! Joint trajectories to replay in a simulation (`dvrk sim --trajectory replay:FILE`), read from
//! a recording:
//! - MCAP or ROS 1 bag: for each arm of the scene, `/<ARM>/setpoint_js` (what the arm was
//!   told), else `/<ARM>/measured_js` (what it did), with the jaw's own topic merged
//!   (`/<ARM>/jaw/setpoint_js`: [`dvrk_sim::recording::read_arms`]); arms with neither hold home. Joints
//!   are matched by name; joints the topics lack hold home.
//! - CSV (the plain format of [`dvrk_sim::recording::read_plain_csv`]): `time` and `q1..qN` for the one arm of
//!   the scene that runs the tracking test.

use crate::error::{CalibError, Result};
use dvrk_sim::recording::McapOptions;
use dvrk_sim::recording::read_recording;
use dvrk_sim::recording::JointTrack;
use dvrk_sim::run::Replay;
use dvrk_sim::scene::Tracking;
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::Scene;
use std::path::Path;

/// Read the trajectories in `path` for the arms of `scene`.
pub fn read_replay(path: &Path, scene: &Scene) -> Result<Replay> {
    let mut arms = Vec::new();
    if dvrk_sim::recording::container(path)?.is_some() {
        // One pass over the file for every arm's topics.
        let names: Vec<&str> = scene.arms.iter().map(|a| a.name.as_str()).collect();
        let mut found = dvrk_sim::recording::read_arms(path, &names, &["setpoint_js", "measured_js"])?;
        let mut missing = Vec::new();
        for arm in &scene.arms {
            let mut states = found.remove(&arm.name).unwrap_or_default();
            // The setpoints (what the arm was told), else the measurements (what it did).
            let kind = ["setpoint_js", "measured_js"].into_iter().find(|k| states.kinds.contains_key(*k));
            match kind.and_then(|k| Some((states.sources.remove(k)?, states.kinds.remove(k)?))) {
                Some((source, js)) => {
                    let track = JointTrack { source, names: js.names, t: js.t, q: js.position, ..Default::default() };
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
        // A setpoint cannot be made up: a row without every joint is an error, not a gap.
        if let Some(line) = track.skipped_lines.first() {
            return Err(CalibError::file(path, format!("line {line}: a replay needs every joint's setpoint on every row ({} row(s) lack a finite value)", track.skipped_lines.len())));
        }
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
