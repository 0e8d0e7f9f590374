//! Joint trajectories: the paper's tracking test (section 4.3), hold, replay of recorded samples.

use dvrk_kin::{JointType, Model};

/// A joint-space reference: position (rad, m) and velocity of every joint at time t (s).
#[derive(Debug, Clone, PartialEq)]
pub enum Trajectory {
    /// `center + amplitude sin(2 pi f t)` per joint.
    Sine { center: Vec<f64>, amplitude: Vec<f64>, frequency: f64 },
    /// Constant positions.
    Hold { q: Vec<f64> },
    /// Recorded samples (times `t` in s from the start, increasing; `q[i]` the positions at
    /// `t[i]`, nq long), linearly interpolated, velocity the slope of the segment; held at the
    /// first and last sample outside their span.
    Samples { t: Vec<f64>, q: Vec<Vec<f64>> },
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
            Trajectory::Samples { t: ts, q: qs } => {
                // First sample after t; the segment [i-1, i] holds t.
                let i = ts.partition_point(|&x| x <= t);
                if i == 0 || i == ts.len() {
                    q.copy_from_slice(&qs[if i == 0 { 0 } else { ts.len() - 1 }]);
                    qd.fill(0.0);
                    return;
                }
                let (t0, t1) = (ts[i - 1], ts[i]);
                let s = (t - t0) / (t1 - t0);
                for k in 0..q.len() {
                    let (a, b) = (qs[i - 1][k], qs[i][k]);
                    q[k] = a + s * (b - a);
                    qd[k] = (b - a) / (t1 - t0);
                }
            }
        }
    }

    /// Recorded samples as a trajectory: times shifted to start at 0, each row `nq` long, times
    /// strictly increasing and every value finite. `what` names the source in errors.
    pub fn samples(what: &str, t: &[f64], q: Vec<Vec<f64>>, nq: usize) -> Result<Trajectory, String> {
        if t.len() != q.len() {
            return Err(format!("{what}: {} times for {} samples", t.len(), q.len()));
        }
        if t.is_empty() {
            return Err(format!("{what}: no samples"));
        }
        for (i, (ti, qi)) in t.iter().zip(&q).enumerate() {
            if qi.len() != nq {
                return Err(format!("{what}: sample {i} has {} positions, the arm has {nq} joints", qi.len()));
            }
            if !ti.is_finite() || qi.iter().any(|x| !x.is_finite()) {
                return Err(format!("{what}: sample {i} (t = {ti} s) is not finite"));
            }
            if i > 0 && *ti <= t[i - 1] {
                return Err(format!("{what}: time {ti} s of sample {i} does not increase (previous {} s)", t[i - 1]));
            }
        }
        let t0 = t[0];
        Ok(Trajectory::Samples { t: t.iter().map(|x| x - t0).collect(), q })
    }
}
