//! Joint trajectories: the paper's tracking test (section 4.3), hold.

use dvrk_kin::{JointType, Model};

/// A joint-space reference: position (rad, m) and velocity of every joint at time t (s).
#[derive(Debug, Clone, PartialEq)]
pub enum Trajectory {
    /// `center + amplitude sin(2 pi f t)` per joint.
    Sine { center: Vec<f64>, amplitude: Vec<f64>, frequency: f64 },
    /// Constant positions.
    Hold { q: Vec<f64> },
}

/// Room kept between a sine's extreme and the joint limit (rad or m), so PID overshoot does not
/// ride on the limit.
const LIMIT_MARGIN: f64 = 0.02;

impl Trajectory {
    /// The section 4.3 test: 0.1 Hz sines of 1 rad (0.1 m for prismatic joints) about home on the
    /// first six joints (the jaw holds); amplitudes the limits do not allow are scaled down.
    /// Returns the trajectory and one note per scaled joint.
    pub fn tracking_test(model: &Model) -> (Trajectory, Vec<String>) {
        let home = model.home();
        let mut amplitude = vec![0.0; model.nq()];
        let mut notes = Vec::new();
        for (k, j) in model.joints.iter().enumerate().take(6) {
            let want: f64 = match j.kind {
                JointType::Revolute => 1.0,
                JointType::Prismatic => 0.1,
            };
            let room = ((j.upper - home[k]).min(home[k] - j.lower) - LIMIT_MARGIN).max(0.0);
            amplitude[k] = want.min(room);
            if amplitude[k] < want - 1e-9 {
                notes.push(format!(
                    "{}: amplitude {:.4} {} instead of {want} (limits [{}, {}] about home {})",
                    j.name, amplitude[k], j.unit(), j.lower, j.upper, home[k]
                ));
            }
        }
        (Trajectory::Sine { center: home, amplitude, frequency: 0.1 }, notes)
    }

    /// Position and velocity at `t` into `q`, `qd` (both nq long).
    pub fn sample(&self, t: f64, q: &mut [f64], qd: &mut [f64]) {
        match self {
            Trajectory::Sine { center, amplitude, frequency } => {
                let w = 2.0 * std::f64::consts::PI * frequency;
                let (s, c) = (w * t).sin_cos();
                for k in 0..q.len() {
                    q[k] = center[k] + amplitude[k] * s;
                    qd[k] = amplitude[k] * w * c;
                }
            }
            Trajectory::Hold { q: h } => {
                q.copy_from_slice(h);
                qd.fill(0.0);
            }
        }
    }
}
