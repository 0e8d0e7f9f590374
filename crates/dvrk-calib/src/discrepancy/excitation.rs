//! The exciting setpoint of a hidden-effect recording: per joint a sum of sines on distinct
//! harmonics of one base period (so the joints' motions are uncorrelated over a period and every
//! joint reverses often and moves at many speeds), phases drawn from the seed, faded in over the
//! first second so the PID starts without a jump; each joint's swing shrunk until following it
//! needs well under the drive's effort limit.

use dvrk_kin::{JointType, Model};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// Base frequency of the harmonics (Hz): a 20 s period.
const BASE_HZ: f64 = 0.05;
/// Fade-in time (s).
const FADE: f64 = 1.0;
/// Room kept from each joint limit (rad, m).
const MARGIN: f64 = 0.05;
/// Largest share of a joint's effort limit the nominal model may need to follow the setpoint;
/// the rest is the PID's corrections' and the hidden effect's.
pub const EFFORT_SHARE: f64 = 0.85;
/// Passes of [`MultiSine::within_effort_limits`]: the effort is not proportional to the swing
/// (gravity stays), so a pass may leave a joint slightly over.
const EFFORT_PASSES: usize = 6;

/// The multi-sine of every joint (the last joint, the jaw, holds home).
#[derive(Debug, Clone)]
pub struct MultiSine {
    /// Per joint: centre (rad, m) and `(amplitude, frequency Hz, phase rad)` terms.
    pub center: Vec<f64>,
    pub terms: Vec<Vec<(f64, f64, f64)>>,
}

impl MultiSine {
    /// Amplitudes as fractions of each joint's room about its centre; frequencies between 0.1 and
    /// 1.3 Hz: slow enough for Table 8's PID to track, fast enough for friction and inertia.
    pub fn new(model: &Model, seed: u64) -> MultiSine {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed_5e7);
        let n = model.nq();
        let home = model.home();
        let moving = n.min(6);
        let mut center = home.clone();
        let mut terms = vec![Vec::new(); n];
        for k in 0..moving {
            let j = &model.joints[k];
            // Outer joints swing less than the wrist (they carry the arm); the insertion stays
            // inside the cannula's useful range.
            let (c, want): (f64, f64) = match (k, j.kind) {
                (_, JointType::Prismatic) => (0.5 * (j.lower + j.upper), 0.06),
                (0 | 1, _) => (0.0, 0.55),
                _ => (0.0, 0.9),
            };
            let room = ((j.upper - c).min(c - j.lower) - MARGIN).max(0.0);
            let total = want.min(room);
            center[k] = c;
            // Four harmonics per joint, interleaved so no two joints share one: harmonic
            // numbers k+2, k+2+moving, ... (0.1 Hz to ~1.3 Hz at 0.05 Hz base).
            let harmonics: Vec<usize> = (0..4).map(|i| k + 2 + i * (moving + 1)).collect();
            // Equal velocity per term (amplitude ~ 1/f) would push the high harmonics to nothing;
            // 1/sqrt(f) keeps every term visible in both position and velocity.
            let weights: Vec<f64> = harmonics.iter().map(|h| 1.0 / (*h as f64).sqrt()).collect();
            let sum: f64 = weights.iter().sum();
            for (h, w) in harmonics.iter().zip(&weights) {
                terms[k].push((total * w / sum, *h as f64 * BASE_HZ, rng.random_range(0.0..2.0 * PI)));
            }
        }
        MultiSine { center, terms }
    }

    /// The period over which every joint's motion repeats (s).
    pub fn period(&self) -> f64 {
        1.0 / BASE_HZ
    }

    /// Shrink each joint's swing until `peaks` (the largest |effort| per joint, N·m or N, that
    /// following the setpoint over one period needs) stays within [`EFFORT_SHARE`] of its
    /// `limits` (a limit <= 0: none). A drive at its limit cannot track, and the bang-bang
    /// transients of a saturated drive belong in no identification recording (the paper's 0.1
    /// N·m s/rad joint damping alone needs the wrist yaw's whole 0.2 N·m at 2 rad/s).
    pub fn within_effort_limits<E>(&mut self, limits: &[f64], mut peaks: impl FnMut(&MultiSine) -> Result<Vec<f64>, E>) -> Result<(), E> {
        for _ in 0..EFFORT_PASSES {
            let peak = peaks(self)?;
            let mut changed = false;
            for (k, terms) in self.terms.iter_mut().enumerate() {
                let allowed = EFFORT_SHARE * limits.get(k).copied().unwrap_or(0.0);
                if allowed > 0.0 && peak[k] > allowed * 1.01 {
                    let s = allowed / peak[k];
                    terms.iter_mut().for_each(|t| t.0 *= s);
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        Ok(())
    }

    /// Position, velocity and acceleration at `t` (s) past the fade-in into `q`, `qd`, `qdd`.
    pub fn steady(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        for k in 0..q.len() {
            let (x, v, a) = self.swing(k, t);
            (q[k], qd[k], qdd[k]) = (self.center[k] + x, v, a);
        }
    }

    /// Joint `k`'s sum of sines about its centre at `t` (s): position, velocity, acceleration.
    fn swing(&self, k: usize, t: f64) -> (f64, f64, f64) {
        let (mut x, mut v, mut acc) = (0.0, 0.0, 0.0);
        for (a, f, p) in &self.terms[k] {
            let w = 2.0 * PI * f;
            x += a * (w * t + p).sin();
            v += a * w * (w * t + p).cos();
            acc -= a * w * w * (w * t + p).sin();
        }
        (x, v, acc)
    }

    /// Position and velocity at `t` (s) into `q`, `qd`.
    pub fn sample(&self, t: f64, q: &mut [f64], qd: &mut [f64]) {
        // Smooth fade-in: s(t) = sin^2(pi t / 2 FADE) up to FADE, then 1.
        let (s, sd) = if t < FADE {
            let x = PI * t / (2.0 * FADE);
            (x.sin().powi(2), 2.0 * x.sin() * x.cos() * PI / (2.0 * FADE))
        } else {
            (1.0, 0.0)
        };
        for k in 0..q.len() {
            let (x, v, _) = self.swing(k, t);
            q[k] = self.center[k] + s * x;
            qd[k] = s * v + sd * x;
        }
    }
}
