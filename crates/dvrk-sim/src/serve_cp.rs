//! `servo_cp` for the served twin ([`crate::serve`]): a tool-tip pose taken to joint setpoints
//! through the model's IK from the current setpoints, as the dVRK console servos in Cartesian
//! space. The pose's `frame_id` says where it is: the arm's base frame (`PSM1_base`), `ECM_view`
//! (the scene's ECM camera, its tool tip as the dVRK defines the camera frame: `ECM-SUJ * DH *
//! tooltip-offset`, followed live as the ECM moves), `world` (the scene's), or empty: the frame
//! `measured_cp` reports in (the camera for a PSM in a scene with an ECM, else the base). A pose the IK cannot reach within
//! the joint limits is refused with the IK's reason, and so is a pose in another frame.

use crate::recording::ros_msgs::PoseStamped;
use crate::recording::writer::VIEW_FRAME;
use crate::{Recorder, Sim};
use dvrk_kin::IkOptions;

/// The IK of a servo command: Newton from the current setpoints only (no restarts: a servo
/// target is near where the arm is, and a miss must not stall the real-time loop).
pub(crate) fn servo_ik() -> IkOptions {
    IkOptions { frame: None, position_tolerance: 1e-7, orientation_tolerance: 1e-6, max_iterations: 50, restarts: 0 }
}

/// The joint setpoints (the arm's model joints, local order) that put arm `a`'s tip at the pose
/// in `bytes` (geometry_msgs/msg/PoseStamped, m, in the base frame), or why not.
pub fn setpoints(sim: &Sim, recorder: &Recorder, a: usize, bytes: &[u8]) -> Result<Vec<f64>, String> {
    let msg = PoseStamped::decode(bytes).map_err(|e| format!("not a geometry_msgs/PoseStamped: {e}"))?;
    // The pose is taken in the frame `measured_cp` reports; another frame is refused, not
    // silently read as this one (an empty frame_id is taken to mean it, as the dVRK does).
    let pose = msg.pose()?;
    let target = frame_pose(sim, recorder, a, &msg.header.frame_id)? * pose;
    let arm = &sim.arms[a];
    let seed: Vec<f64> = arm.actuators.iter().map(|act| act.target).collect();
    let solution = dvrk_kin::inverse_kinematics(&arm.model, &target, &seed, &servo_ik()).map_err(|e| e.to_string())?;
    Ok(solution.q)
}

/// The world pose of the frame a command for arm `a` names in its `frame_id`: `measured_cp`'s
/// frame (also for an empty `frame_id`, as the dVRK reads it: the ECM's camera for a PSM in a
/// scene with an ECM), the arm's base frame, [`VIEW_FRAME`] (the ECM's camera now) or `world`.
pub fn frame_pose(sim: &Sim, recorder: &Recorder, a: usize, frame_id: &str) -> Result<dvrk_kin::Pose, String> {
    let (reported, pose) = recorder.report_frame(sim, a);
    if frame_id.is_empty() || frame_id == reported {
        return Ok(pose);
    }
    let base = recorder.base_frame_id(a);
    if frame_id == base {
        return Ok(recorder.base_pose(sim, a));
    }
    if frame_id == "world" {
        return Ok(dvrk_kin::Pose::identity());
    }
    if frame_id == VIEW_FRAME {
        return recorder.view_pose(sim).ok_or_else(|| format!("the pose is in frame `{VIEW_FRAME}`, but this scene has no arm named ECM"));
    }
    let shown: String = frame_id.chars().take(64).collect();
    Err(format!("the pose is in frame `{shown}`; servo_cp takes poses in `{base}` (the arm's base), `{VIEW_FRAME}` (the ECM's camera), `world`, or with an empty frame_id (measured_cp's frame, `{reported}`)"))
}
