//! The tracking channel: the recording's setpoints replayed through the simulated arm under its
//! PID, the simulated encoder positions against the recorded ones; with the nominal model, then
//! with the named effects added (the gap should shrink).

use super::joint_log::JointLog;
use super::report::TrackingReport;
use crate::error::{CalibError, Result};
use dvrk_sim::trajectory::Trajectory;
use dvrk_sim::{Scene, Sim, SimOptions};

fn sim_error(e: dvrk_sim::SimError) -> CalibError {
    CalibError::data("simulation", e.to_string())
}

/// RMS per joint of recorded minus replayed encoder positions (rad, m), past the first 2 s.
fn replay(scene: &Scene, arm: usize, log: &JointLog) -> Result<Vec<f64>> {
    let nq = log.names.len();
    let traj = Trajectory::samples("recording", &log.t, log.setpoint.clone(), nq).map_err(|e| CalibError::data("replay", e))?;
    let mut scene = scene.clone();
    scene.set_start(arm, &log.setpoint[0]).map_err(sim_error)?;
    let mut sim = Sim::new(&scene, &SimOptions::default()).map_err(sim_error)?;
    let off = sim.arms[arm].q_offset;
    let (mut q, mut qd) = (vec![0.0; nq], vec![0.0; nq]);
    let t0 = log.t[0];
    let mut sum = vec![0.0; nq];
    let mut count = 0usize;
    let mut next = 0usize;
    while next < log.len() {
        let t = sim.time + sim.dt;
        traj.sample(t, &mut q, &mut qd);
        for k in 0..nq {
            sim.set_target(off + k, q[k], qd[k]).map_err(sim_error)?;
        }
        sim.step();
        // Compare at the recorded samples the step reached.
        while next < log.len() && log.t[next] - t0 <= sim.time + 1e-9 {
            if log.t[next] - t0 >= 2.0 {
                for k in 0..nq {
                    sum[k] += (log.position[next][k] - sim.q()[off + k]).powi(2);
                }
                count += 1;
            }
            next += 1;
        }
    }
    Ok(sum.iter().map(|s| (s / count.max(1) as f64).sqrt()).collect())
}

/// Tracking RMS with model `before` on arm `arm` of `scene`, and with `after` if given (each
/// put on the arm's mount).
pub fn compare(scene: &Scene, arm: usize, log: &JointLog, before: &dvrk_kin::Model, after: Option<&dvrk_kin::Model>) -> Result<TrackingReport> {
    let with = |m: &dvrk_kin::Model| -> Result<Vec<f64>> {
        let mut s = scene.clone();
        s.set_model(arm, m.clone()).map_err(sim_error)?;
        replay(&s, arm, log)
    };
    Ok(TrackingReport { joints: log.names.clone(), rms_before: with(before)?, rms_after: after.map(with).transpose()? })
}
