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

/// The map a `coupling_error` puts between the joints the controller reads and the true ones:
/// encoders read actuators `m`, the controller takes `q = C m` with the model's coupling `C`,
/// while the mechanism moves by `q_true = (C + dC) m`; so `q_true = B q`, `B = (C + dC) C^-1`.
/// The efforts follow by virtual work: the controller's `tau = B^T tau_true`. `None` without a
/// coupling error; an error names the effect when `C + dC` is singular.
pub(crate) fn error_map(model: &Model, effects: &[crate::vocabulary::Effect]) -> Result<Option<DMatrix<f64>>> {
    let errors: Vec<&crate::vocabulary::Effect> = effects.iter().filter(|e| e.kind == crate::vocabulary::EffectKind::CouplingError).collect();
    let Some(c) = model.coupling_matrix().filter(|_| !errors.is_empty()) else { return Ok(None) };
    let mut truth = c.clone();
    for e in &errors {
        for (name, v) in &e.parameters {
            if let Some((r, col)) = crate::vocabulary::coupling_entry(name) {
                truth[(r - 1, col - 1)] += v;
            }
        }
    }
    let inv = c.try_inverse().ok_or_else(|| KinError::field("coupling", "the model's coupling matrix is singular"))?;
    if truth.clone().try_inverse().is_none() {
        return Err(KinError::field("effects (coupling_error).parameters", "the coupling with these errors is singular: the true joints would not follow from the actuators"));
    }
    Ok(Some(truth * inv))
}

/// Every frame variable re-expressed in new joints `q'` with `q = m q'`: `phi = c q + b = (c m) q' + b`
/// (and the evaluation data that caches the variables rebuilt).
pub(crate) fn remap_joints(model: &mut Model, m: &DMatrix<f64>) {
    for f in &mut model.frames {
        for a in [&mut f.theta, &mut f.d] {
            let row = nalgebra::RowDVector::from_row_slice(&a.coef) * m;
            // Products of the map and its inverse leave 1e-17s where a frame does not depend on
            // a joint: zero them, so a frame driven by one joint stays so.
            let scale = row.amax();
            a.coef = row.iter().map(|c| if c.abs() <= 1e-12 * scale { 0.0 } else { *c }).collect();
        }
    }
    model.eval = crate::model::Eval::build(&model.frames);
}

impl Model {
    /// `B` of [`error_map`] for this model's `coupling_error` (`q_true = B q_read`), if it has one.
    pub fn coupling_error_map(&self) -> Option<DMatrix<f64>> {
        error_map(self, &self.effects).ok().flatten()
    }

    /// This model in the true joints of a `coupling_error` (`q_true = B q_read`), without it: the
    /// mechanism a simulation builds, whose sensors and motors then map through `B`. A clone
    /// when there is none.
    pub fn without_coupling_error(&self) -> Model {
        let mut out = self.clone();
        if let Some(inv) = self.coupling_error_map().and_then(|b| b.try_inverse()) {
            remap_joints(&mut out, &inv);
            out.effects.retain(|e| e.kind != crate::vocabulary::EffectKind::CouplingError);
        }
        out
    }
}
