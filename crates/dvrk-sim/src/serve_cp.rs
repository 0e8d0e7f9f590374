//! `servo_cp` for the served twin ([`crate::serve`]): a tool-tip pose in the arm's base frame
//! (`PSM1_base`, what `measured_cp` reports), taken to joint setpoints through the model's IK
//! from the current setpoints, as the dVRK console servos in Cartesian space. A pose the IK
//! cannot reach within the joint limits is refused with the IK's reason, and so is a pose in
//! another frame.

use crate::recording::ros_msgs::PoseStamped;
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
    let base = recorder.base_frame_id(a);
    if !msg.header.frame_id.is_empty() && msg.header.frame_id != base {
        let shown: String = msg.header.frame_id.chars().take(64).collect();
        return Err(format!("the pose is in frame `{shown}`; servo_cp takes poses in `{base}` (measured_cp's frame) or with an empty frame_id"));
    }
    let in_base = msg.pose()?;
    let target = recorder.base_pose(sim, a) * in_base;
    let arm = &sim.arms[a];
    let seed: Vec<f64> = arm.actuators.iter().map(|act| act.target).collect();
    let solution = dvrk_kin::inverse_kinematics(&arm.model, &target, &seed, &servo_ik()).map_err(|e| e.to_string())?;
    Ok(solution.q)
}
