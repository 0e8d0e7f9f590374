//! Measured joint values against a model's joint limits: counted and reported, not refused.
//! A real arm goes a hair past the limits its configuration file holds (a PSM's wrist 0.001 rad
//! past, say); FK, calibration, identification and the discrepancy workflow evaluate such data
//! as measured and say how much of it was outside. Commands, setpoints and IK still respect the
//! limits ([`Model::check_q`]).

use crate::model::Model;

/// How far measured configurations went past a model's joint limits.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LimitTally {
    /// Configurations seen.
    pub samples: usize,
    /// Configurations with at least one joint outside its limits.
    pub samples_outside: usize,
    /// Per joint (the model's order): configurations outside its limits, and the largest
    /// distance past the nearer limit (rad or m, the joint's unit).
    pub joints: Vec<(usize, f64)>,
}

impl LimitTally {
    /// An empty tally for `model`'s joints.
    pub fn new(model: &Model) -> Self {
        LimitTally { samples: 0, samples_outside: 0, joints: vec![(0, 0.0); model.nq()] }
    }

    /// The tally of every configuration of `configs` (each the model's joints, in order).
    pub fn of<Q: AsRef<[f64]>>(model: &Model, configs: impl IntoIterator<Item = Q>) -> Self {
        let mut t = Self::new(model);
        for q in configs {
            t.add(model, q.as_ref());
        }
        t
    }

    /// Count configuration `q` (the model's joints, in order; extra values are ignored); true
    /// when a joint is outside its limits.
    pub fn add(&mut self, model: &Model, q: &[f64]) -> bool {
        self.samples += 1;
        let mut outside = false;
        for ((j, x), slot) in model.joints.iter().zip(q).zip(&mut self.joints) {
            let past = (j.lower - x).max(x - j.upper);
            if past > 0.0 {
                slot.0 += 1;
                slot.1 = slot.1.max(past);
                outside = true;
            }
        }
        self.samples_outside += outside as usize;
        outside
    }

    /// True when nothing was outside.
    pub fn is_clean(&self) -> bool {
        self.samples_outside == 0
    }

    /// One line per joint that went outside: `outer_wrist_yaw: 3 of 100 sample(s) outside
    /// [-1.39626, 1.39626] rad, at most 0.00097 rad past`.
    pub fn lines(&self, model: &Model) -> Vec<String> {
        model
            .joints
            .iter()
            .zip(&self.joints)
            .filter(|(_, (n, _))| *n > 0)
            .map(|(j, (n, past))| format!("{}: {n} of {} sample(s) outside [{}, {}] {}, at most {past:.3e} {} past", j.name, self.samples, j.lower, j.upper, j.unit(), j.unit()))
            .collect()
    }

    /// One sentence for a report, `None` when nothing was outside.
    pub fn summary(&self, model: &Model) -> Option<String> {
        (!self.is_clean()).then(|| {
            format!(
                "{} of {} measured configuration(s) outside the limits of model {} (evaluated as measured): {}",
                self.samples_outside,
                self.samples,
                model.name,
                self.lines(model).join("; ")
            )
        })
    }
}
