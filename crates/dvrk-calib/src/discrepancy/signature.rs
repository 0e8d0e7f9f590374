//! A candidate's signature column: the effort one unit of its parameter adds, per analysed
//! sample and joint (N·m or N per unit), held joint by joint with the joints it leaves at zero
//! left out. Most signatures act on one joint (a joint's friction, spring, offset) or on an
//! actuator's few: as a [`Table`] (a heap row per sample over every joint) a 5-minute recording's
//! candidates took 300 MB; joint by joint a one-joint signature is a seventh of a flat table.
//! A joint's series is shared between copies (an offset's sensitivity is both a drive's load
//! and the offset's candidate).

use super::signals::Table;
use std::sync::Arc;

/// Values per analysed sample and joint: a [`Table`] or a [`Signature`].
pub trait Series {
    /// The value at `sample` on `joint`.
    fn at(&self, sample: usize, joint: usize) -> f64;
}

impl Series for Table {
    fn at(&self, sample: usize, joint: usize) -> f64 {
        self[sample][joint]
    }
}

/// A signature column, each joint's series or nothing where it is zero throughout.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Signature {
    samples: usize,
    joints: Vec<Option<Arc<[f64]>>>,
}

impl Signature {
    /// `series` on joint `j` of `nq`, zero on the others.
    pub fn on_joint(nq: usize, j: usize, series: Vec<f64>) -> Signature {
        let samples = series.len();
        let mut joints = vec![None; nq];
        joints[j] = Some(series.into());
        Signature { samples, joints }
    }

    /// Zero on each of `nq` joints over `samples` samples (joints set by [`Signature::set`]).
    pub fn on_joints(nq: usize, samples: usize) -> Signature {
        Signature { samples, joints: vec![None; nq] }
    }

    /// Joint `j`'s series (one value per sample).
    pub fn set(&mut self, j: usize, series: Vec<f64>) {
        debug_assert_eq!(series.len(), self.samples);
        self.joints[j] = Some(series.into());
    }

    /// Each joint's series in turn (one value per sample over `samples` samples); a joint that
    /// is exactly zero at every sample is left out.
    pub fn from_joints(samples: usize, series: impl IntoIterator<Item = Vec<f64>>) -> Signature {
        let joints = series.into_iter().map(|s| s.iter().any(|x| *x != 0.0).then(|| s.into())).collect();
        Signature { samples, joints }
    }

    /// Each joint's series from a table `[sample][joint]` (`nq` joints; [`Signature::from_joints`]).
    pub fn from_table(t: &Table, nq: usize) -> Signature {
        Signature::from_joints(t.len(), (0..nq).map(|k| t.iter().map(|r| r[k]).collect()))
    }

    /// Analysed samples.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// As a table `[sample][joint]`.
    pub fn to_table(&self) -> Table {
        (0..self.samples).map(|i| (0..self.joints.len()).map(|k| self.at(i, k)).collect()).collect()
    }

    /// Joint `k`'s series, `None` where it is zero throughout.
    pub fn joint(&self, k: usize) -> Option<&[f64]> {
        self.joints.get(k)?.as_deref()
    }

    /// Whether every value is below `tol` in size.
    pub fn is_below(&self, tol: f64) -> bool {
        self.joints.iter().flatten().flat_map(|s| s.iter()).all(|x| x.abs() < tol)
    }

    /// RMS over every sample of joint `k` (0 where it is zero throughout).
    pub fn rms(&self, k: usize) -> f64 {
        self.joint(k).map_or(0.0, |s| (s.iter().map(|x| x * x).sum::<f64>() / s.len().max(1) as f64).sqrt())
    }
}

impl Series for Signature {
    fn at(&self, sample: usize, joint: usize) -> f64 {
        self.joints[joint].as_ref().map_or(0.0, |s| s[sample])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Joint by joint, the same values as the table it was made from, and back.
    #[test]
    fn a_signature_holds_its_table() {
        let t: Table = (0..5).map(|i| vec![0.0, i as f64 * 0.5 - 1.0, 0.0, if i == 3 { -2.0 } else { 0.0 }]).collect();
        let s = Signature::from_table(&t, 4);
        assert_eq!((s.joint(0), s.joint(2)), (None, None));
        assert_eq!(s.joint(3), Some(&[0.0, 0.0, 0.0, -2.0, 0.0][..]));
        for (i, row) in t.iter().enumerate() {
            for (k, v) in row.iter().enumerate() {
                assert_eq!(s.at(i, k), *v);
            }
        }
        assert_eq!(s.to_table(), t);
        assert!((s.rms(3) - (4.0f64 / 5.0).sqrt()).abs() < 1e-15);
        assert!(!s.is_below(1.0) && s.is_below(2.5));
    }
}
