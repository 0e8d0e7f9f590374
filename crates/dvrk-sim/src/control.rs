//! Per-joint actuators, switchable at run time: hold a position directly, PID position control
//! (integral anti-windup, effort limit), or open-loop effort.

use crate::error::{Result, SimError};

/// How a joint is driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    /// Held at the target by a stiff implicit constraint (the paper's "set the joint positions
    /// directly", used for the setup joints). No effort is reported.
    Position,
    /// PID on the position error, output clamped at the effort limit.
    Pid,
    /// The commanded effort is applied as is (clamped at the effort limit).
    Effort,
}

/// PID gains of one joint: `kp` N·m/rad (N/m), `ki` N·m/(rad s) (N/(m s)), `kd` N·m s/rad (N s/m).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Gains {
    pub kp: f64,
    pub ki: f64,
    pub kd: f64,
}

impl Gains {
    /// Reject non-finite or negative gains (`what` names the joint).
    pub fn check(&self, what: &str) -> Result<()> {
        for (name, v) in [("kp", self.kp), ("ki", self.ki), ("kd", self.kd)] {
            if !v.is_finite() || v < 0.0 {
                return Err(SimError::value(format!("{what} gain {name}"), v, "gains must be finite and non-negative"));
            }
        }
        Ok(())
    }
}

/// State of one joint's controller. Plain data: stepping allocates nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct Actuator {
    pub mode: Mode,
    pub gains: Gains,
    /// N·m or N (0: no limit)
    pub effort_limit: f64,
    /// rad or m
    pub target: f64,
    /// rad/s or m/s
    pub target_velocity: f64,
    /// Open-loop effort command (N·m or N).
    pub effort_command: f64,
    /// Integral of the position error (rad s or m s).
    pub integral: f64,
    /// Effort applied at the last step (N·m or N).
    pub effort: f64,
    /// Feed-forward added to the PID output before the effort limit (N·m or N): the gravity
    /// compensation of arms whose scene asks for it.
    pub feedforward: f64,
}

impl Actuator {
    pub fn new(gains: Gains, effort_limit: f64, target: f64) -> Self {
        Actuator { mode: Mode::Pid, gains, effort_limit, target, target_velocity: 0.0, effort_command: 0.0, integral: 0.0, effort: 0.0, feedforward: 0.0 }
    }

    fn clamp(&self, tau: f64) -> f64 {
        if self.effort_limit > 0.0 {
            tau.clamp(-self.effort_limit, self.effort_limit)
        } else {
            tau
        }
    }

    /// Effort for position `q` and velocity `qd` over a step of `dt` s (0 in position mode).
    pub fn update(&mut self, q: f64, qd: f64, dt: f64) -> f64 {
        self.effort = match self.mode {
            Mode::Position => 0.0,
            // The gravity feed-forward (when the arm has it) is added, as the dVRK adds its
            // gravity compensation to an effort command.
            Mode::Effort => self.clamp(self.effort_command + self.feedforward),
            Mode::Pid => {
                let e = self.target - q;
                let ed = self.target_velocity - qd;
                let g = self.gains;
                let unsat = g.kp * e + g.ki * (self.integral + e * dt) + g.kd * ed + self.feedforward;
                let tau = self.clamp(unsat);
                // Conditional integration (anti-windup): stop integrating while the output is
                // saturated and the error would push it further into saturation.
                let saturated = tau != unsat && unsat.signum() == e.signum();
                if !saturated {
                    self.integral += e * dt;
                    // And never let the integral alone exceed the effort limit.
                    if self.effort_limit > 0.0 && g.ki > 0.0 {
                        let cap = self.effort_limit / g.ki;
                        self.integral = self.integral.clamp(-cap, cap);
                    }
                }
                tau
            }
        };
        self.effort
    }
}

/// Table 8 of the paper: PSM PID gains (joints 1-6); the jaw (not in the table) uses the wrist's.
pub const PSM_TABLE8: [Gains; 7] = [
    Gains { kp: 70.0, ki: 0.1, kd: 5.0 },
    Gains { kp: 70.0, ki: 0.1, kd: 5.0 },
    Gains { kp: 400.0, ki: 0.01, kd: 10.0 },
    Gains { kp: 10.0, ki: 0.1, kd: 1.0 },
    Gains { kp: 10.0, ki: 0.1, kd: 1.0 },
    Gains { kp: 10.0, ki: 0.1, kd: 1.0 },
    Gains { kp: 10.0, ki: 0.1, kd: 1.0 },
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pid_saturates_and_does_not_wind_up() {
        let mut a = Actuator::new(Gains { kp: 70.0, ki: 10.0, kd: 5.0 }, 3.316101, 1.0);
        for _ in 0..10_000 {
            assert_eq!(a.update(0.0, 0.0, 0.001), 3.316101);
        }
        // Saturated all along with the error pushing outward: the integral never grew.
        assert_eq!(a.integral, 0.0);
        a.target = 0.0;
        assert!((a.update(0.0, 0.0, 0.001)).abs() < 1e-12);
    }

    #[test]
    fn bad_gains_are_rejected() {
        let e = Gains { kp: f64::NAN, ki: 0.0, kd: 0.0 }.check("joint outer_yaw").unwrap_err().to_string();
        assert!(e.contains("outer_yaw") && e.contains("kp") && e.contains("NaN"), "{e}");
        assert!(Gains { kp: 1.0, ki: f64::INFINITY, kd: 0.0 }.check("j").is_err());
    }
}

/// Stiffness of the position-mode motor (1/s^2, per unit of the joint's effective mass: rapier's
/// acceleration-based motor, and the reduced engine the same way, so both engines hold a joint alike). A held joint sags by load acceleration / stiffness: 1e5 let the
/// cart's SUJ-ECM column (carrying the ECM) sink 0.11 mm under gravity, 1e6 keeps every setup
/// joint within 1.2e-5 m / 4.3e-5 rad (measured, full scene). 1e7 is too stiff for 32 sweeps:
/// the under-converged solve locks the PSM yaw joints carried by the SUJ (0.59 rad error in 1 s).
pub(crate) const POSITION_STIFFNESS: f64 = 1.0e6;
/// Damping of the position-mode motor (1/s): 3x critical (2 sqrt(k) = 2e3).
pub(crate) const POSITION_DAMPING: f64 = 6.0e3;
