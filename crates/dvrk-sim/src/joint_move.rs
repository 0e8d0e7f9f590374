//! `move_jp`: a joint-space move to a goal, interpolated as the dVRK console does it: every
//! joint under its velocity and acceleration limit, all arriving together. The console uses
//! Reflexxes (type II: velocity and acceleration bounded, no jerk limit); here the joints follow
//! one shared trapezoidal profile along the straight line to the goal (Reflexxes' phase-
//! synchronised case), so the slowest joint sets the pace and the path is a line in joint space.
//!
//! The limits are the console's defaults (sawIntuitiveResearchKit, `mtsIntuitiveResearchKitPSM`
//! and `...ECM`): PSM 180 deg/s and 180 deg/s^2 on yaw and pitch, 0.2 m/s and 0.2 m/s^2 on the
//! insertion, 1080 deg/s and 720 deg/s^2 on the tool's joints; ECM 30 deg/s and 90 deg/s^2, 60
//! mm/s and 60 mm/s^2 on the insertion; other arms the MTM's 90 deg/s and 45 deg/s^2 (60 mm/s
//! and 60 mm/s^2 for a prismatic joint).

use dvrk_kin::Model;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Velocity (rad/s, m/s) and acceleration (rad/s^2, m/s^2) limits of every joint of `model`.
pub fn limits(model: &Model) -> (Vec<f64>, Vec<f64>) {
    let prismatic = |k: usize| model.joints[k].unit() == "m";
    let name = model.name.to_ascii_lowercase();
    (0..model.nq())
        .map(|k| match (name.as_str(), k) {
            ("psm", 0 | 1) => (180.0 * DEG, 180.0 * DEG),
            ("psm", 2) => (0.2, 0.2),
            ("psm", _) => (1080.0 * DEG, 720.0 * DEG),
            ("ecm", 2) => (0.06, 0.06),
            ("ecm", _) => (30.0 * DEG, 90.0 * DEG),
            _ if prismatic(k) => (0.06, 0.06),
            _ => (90.0 * DEG, 45.0 * DEG),
        })
        .unzip()
}

/// A trapezoidal profile of the path parameter `s` from 0 to 1: accelerate at `a`, cruise at
/// `v`, decelerate (a triangle when `v` is never reached).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trapezoid {
    /// Path velocity (1/s) and acceleration (1/s^2) bounds.
    v: f64,
    a: f64,
    /// Time to full speed, and the whole move (s).
    t_accel: f64,
    pub duration: f64,
}

impl Trapezoid {
    /// The fastest profile under `v` and `a` (both positive).
    pub fn new(v: f64, a: f64) -> Trapezoid {
        if v * v / a >= 1.0 {
            // Never at full speed: accelerate over half the way, decelerate over the rest.
            let t = (1.0 / a).sqrt();
            Trapezoid { v: a * t, a, t_accel: t, duration: 2.0 * t }
        } else {
            let t = v / a;
            Trapezoid { v, a, t_accel: t, duration: t + 1.0 / v }
        }
    }

    /// `(s, ds/dt)` at time `t` (s) since the start; `(1, 0)` after the end.
    pub fn at(&self, t: f64) -> (f64, f64) {
        let (v, a, ta, d) = (self.v, self.a, self.t_accel, self.duration);
        if t <= 0.0 {
            (0.0, 0.0)
        } else if t < ta {
            (0.5 * a * t * t, a * t)
        } else if t < d - ta {
            (0.5 * a * ta * ta + v * (t - ta), v)
        } else if t < d {
            let r = d - t;
            (1.0 - 0.5 * a * r * r, a * r)
        } else {
            (1.0, 0.0)
        }
    }
}

/// A move of some joints from where their setpoints are to a goal.
#[derive(Debug, Clone)]
pub struct JointMove {
    /// Scene joint indices.
    pub joints: Vec<usize>,
    start: Vec<f64>,
    delta: Vec<f64>,
    /// Simulated time the move began (s).
    t0: f64,
    profile: Trapezoid,
}

impl JointMove {
    /// From `start` to `goal` (per joint), beginning at simulated time `t0`, under the joints'
    /// `v_max` and `a_max`.
    pub fn new(joints: Vec<usize>, start: Vec<f64>, goal: &[f64], v_max: &[f64], a_max: &[f64], t0: f64) -> JointMove {
        let delta: Vec<f64> = goal.iter().zip(&start).map(|(g, s)| g - s).collect();
        // The path speed each joint allows; the slowest joint sets it.
        let bound = |limit: &[f64]| delta.iter().zip(limit).filter(|(d, _)| d.abs() > 1e-12).map(|(d, l)| l / d.abs()).fold(f64::INFINITY, f64::min);
        let (v, a) = (bound(v_max), bound(a_max));
        let profile = if v.is_finite() && a.is_finite() { Trapezoid::new(v, a) } else { Trapezoid { v: 1.0, a: 1.0, t_accel: 0.0, duration: 0.0 } };
        JointMove { joints, start, delta, t0, profile }
    }

    /// The move's length (s).
    pub fn duration(&self) -> f64 {
        self.profile.duration
    }

    /// Setpoint position and velocity of joint `i` of the move at simulated time `t`.
    pub fn at(&self, i: usize, t: f64) -> (f64, f64) {
        let (s, sd) = self.profile.at(t - self.t0);
        (self.start[i] + self.delta[i] * s, self.delta[i] * sd)
    }

    /// Whether the move is over at simulated time `t`.
    pub fn done(&self, t: f64) -> bool {
        t - self.t0 >= self.profile.duration
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_profile_reaches_the_goal_within_its_bounds_in_the_least_time() {
        for (v, a) in [(0.5, 1.0), (2.0, 1.0), (1.0, 1.0)] {
            let p = Trapezoid::new(v, a);
            let n = 100_000;
            let mut s_prev = 0.0;
            for k in 1..=n {
                let t = p.duration * k as f64 / n as f64;
                let (s, sd) = p.at(t);
                assert!(sd <= v + 1e-12 && s >= s_prev - 1e-12, "{v} {a} at {t}");
                // The velocity is the position's derivative.
                let dt = p.duration / n as f64;
                assert!(((s - s_prev) / dt - sd).abs() < 2.0 * a * dt + 1e-9);
                s_prev = s;
            }
            assert!((p.at(p.duration).0 - 1.0).abs() < 1e-12);
            // Closed form: a triangle when v^2/a >= 1, else t_a + 1/v.
            let want = if v * v / a >= 1.0 { 2.0 / a.sqrt() } else { v / a + 1.0 / v };
            assert!((p.duration - want).abs() < 1e-12);
        }
    }

    #[test]
    fn the_slowest_joint_sets_the_pace_and_all_arrive_together() {
        let psm = dvrk_kin::load("psm", None).unwrap();
        let (v, a) = limits(&psm);
        assert!((v[0] - std::f64::consts::PI).abs() < 1e-12 && v[2] == 0.2 && a[2] == 0.2);
        // 0.5 rad of yaw and 0.1 m of insertion: the insertion (0.2 m/s, 0.2 m/s^2) is slower.
        let m = JointMove::new(vec![0, 2], vec![0.0, 0.05], &[0.5, 0.15], &[v[0], v[2]], &[a[0], a[2]], 1.0);
        // Path bounds 2 /s and 2 /s^2: v^2/a = 2 >= 1, a triangle of 2/sqrt(2) s.
        assert!((m.duration() - 2.0f64.sqrt()).abs() < 1e-12);
        let half = 1.0 + m.duration() / 2.0;
        assert!((m.at(0, half).0 - 0.25).abs() < 1e-12 && (m.at(1, half).0 - 0.10).abs() < 1e-12);
        assert!(m.done(1.0 + m.duration()) && !m.done(half));
        assert_eq!(m.at(1, 10.0), (0.15, 0.0));
    }
}
