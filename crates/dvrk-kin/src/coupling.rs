//! Actuator-to-joint coupling (the dVRK's `ActuatorToJointPosition`): the MTM's elbow
//! parallelogram and platform cable, the PSM tool's wrist cables. Joint positions are what the
//! kinematics take; encoders measure actuator positions.

use crate::error::{KinError, Result};
use crate::model::Model;
use nalgebra::{DMatrix, DVector};

impl Model {
    /// The coupling as a full `nq x nq` matrix (joints = C * actuators), if the model has one:
    /// the arm's own (MTM) or its tool's (PSM), identity on the joints it does not couple.
    pub fn coupling_matrix(&self) -> Option<DMatrix<f64>> {
        let n = self.nq();
        if let Some(c) = &self.coupling {
            if c.nrows() == n && c.ncols() == n {
                return Some(c.clone());
            }
        }
        let tool = self.spec.tool.as_ref()?;
        let rows = tool.coupling.as_ref()?;
        let idx: Vec<usize> = tool.joints.iter().map(|j| self.joint_id(j).ok()).collect::<Option<_>>()?;
        if rows.len() != idx.len() || rows.iter().any(|r| r.len() != idx.len()) {
            return None;
        }
        let mut c = DMatrix::identity(n, n);
        for (r, &i) in idx.iter().enumerate() {
            for (k, &j) in idx.iter().enumerate() {
                c[(i, j)] = rows[r][k];
            }
        }
        Some(c)
    }

    /// Joint positions (rad / m) from actuator positions.
    pub fn joints_from_actuators(&self, actuators: &[f64]) -> Result<Vec<f64>> {
        let c = self.coupling_matrix().ok_or_else(|| KinError::field("coupling", format!("model `{}` has no actuator coupling", self.name)))?;
        if actuators.len() != self.nq() {
            return Err(KinError::Size { what: "actuator positions".into(), expected: self.nq(), got: actuators.len() });
        }
        Ok((c * DVector::from_column_slice(actuators)).as_slice().to_vec())
    }

    /// Actuator positions from joint positions (the inverse coupling).
    pub fn actuators_from_joints(&self, q: &[f64]) -> Result<Vec<f64>> {
        let c = self.coupling_matrix().ok_or_else(|| KinError::field("coupling", format!("model `{}` has no actuator coupling", self.name)))?;
        self.check_q_size(q)?;
        let inv = c.try_inverse().ok_or_else(|| KinError::field("coupling", "the coupling matrix is singular"))?;
        Ok((inv * DVector::from_column_slice(q)).as_slice().to_vec())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn mtm_elbow_and_psm_wrist_couplings() {
        let mtm = crate::load("mtmr", None).unwrap();
        // Elbow parallelogram: joint 3 = actuator 3 - actuator 2; platform: + 0.6697 (a2 - a3).
        let q = mtm.joints_from_actuators(&[0.1, 0.2, 0.5, 0.3, 0.0, 0.0, 0.0]).unwrap();
        assert!((q[2] - 0.3).abs() < 1e-15 && (q[3] - (0.3 + 0.6697 * (0.2 - 0.5))).abs() < 1e-15);
        let back = mtm.actuators_from_joints(&q).unwrap();
        assert!((back[2] - 0.5).abs() < 1e-12);
        let psm = crate::load("psm", None).unwrap();
        let q = psm.joints_from_actuators(&[0.1, 0.2, 0.1, 1.0, 0.5, 0.2, 0.4]).unwrap();
        assert_eq!(&q[..3], &[0.1, 0.2, 0.1]);
        assert!((q[3] + 1.5632).abs() < 1e-15, "roll = -1.5632 a4");
        assert!((q[6] - 1.2177 * (0.4 - 0.2)).abs() < 1e-15, "jaw = 1.2177 (a7 - a6)");
        assert!(crate::load("ecm", None).unwrap().joints_from_actuators(&[0.0; 4]).is_err());
    }
}
