//! The dynamics dvrk-kin computes, over batches of configurations: `Model.inverse_dynamics`,
//! `mass_matrix`, `gravity`, `regressor` (the methods in lib.rs call these). Conversions and
//! loops only; the inertials are the model file's `[[inertials]]` where it has them for every
//! body, else the model's built-in ones (psm, ecm, the setup joints), with its payload and
//! counterweight effects applied.

use crate::errors::{Error, Result};
use dvrk_kin::dynamics::{DynamicsData, DynamicsModel};
use dvrk_kin::Model;
use nalgebra::{DMatrix, Vector3};

/// Gravity in the model's world frame (m/s^2): the scenes' default.
pub const GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

/// The model's dynamics: its file's inertials for every body, else its built-in ones
/// ([`dvrk_sim::scene::model_inertias`]), with its payload and counterweight effects.
pub fn dynamics_of(model: &Model) -> Result<DynamicsModel> {
    let inertias = dvrk_sim::scene::model_inertias(model)
        .map_err(|e| Error::Input(format!("model `{}` has no [[inertials]] for every body and no built-in ones ({e})", model.name)))?;
    let inertias = dvrk_kin::effects::effect_inertias(model, &model.effects, &inertias)?;
    Ok(DynamicsModel::new(model, inertias)?)
}

/// What to evaluate per configuration, and its size per row.
#[derive(Clone, Copy)]
pub enum Quantity {
    /// The drive efforts for (q, qd, qdd) (N·m, N): rigid bodies, with the friction, spring
    /// and motor-inertia effects when `effects` (presliding at its sliding limit).
    InverseDynamics { effects: bool },
    /// The joint-space inertia (kg m^2, kg), nq x nq, the motors' reflected inertia added when
    /// `effects`.
    MassMatrix { effects: bool },
    /// The gravity torque g(q) (N·m, N).
    Gravity,
    /// The inertial-parameter regressor, nq x 10 nbodies (each body's m, m c, I about its
    /// frame, in [`dvrk_kin::dynamics::PARAMETERS_PER_BODY`] order).
    Regressor,
}

impl Quantity {
    pub fn size(self, model: &Model) -> usize {
        let nq = model.nq();
        match self {
            Quantity::InverseDynamics { .. } | Quantity::Gravity => nq,
            Quantity::MassMatrix { .. } => nq * nq,
            Quantity::Regressor => nq * dvrk_kin::dynamics::PARAMETERS_PER_BODY * model.bodies.len(),
        }
    }
}

/// `what` at each of `n` rows of `q` (and `qd`, `qdd`: row-major, n x nq each) into one
/// row-major vector of `n * what.size()`.
pub fn evaluate(model: &Model, dm: &DynamicsModel, what: Quantity, n: usize, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<Vec<f64>> {
    let nq = model.nq();
    let per = what.size(model);
    let g = Vector3::from(GRAVITY);
    let mut data = DynamicsData::new(model);
    let mut out = vec![0.0; n * per];
    let mut mass = DMatrix::zeros(nq, nq);
    let mut reg = DMatrix::zeros(nq, per / nq.max(1));
    for i in 0..n {
        let r = i * nq..(i + 1) * nq;
        let o = &mut out[i * per..(i + 1) * per];
        match what {
            Quantity::InverseDynamics { effects: true } => dvrk_kin::dynamics::actuator_effort(model, dm, &mut data, &q[r.clone()], &qd[r.clone()], &qdd[r], &g, 0.0, o)?,
            Quantity::InverseDynamics { effects: false } => dvrk_kin::inverse_dynamics(model, dm, &mut data, &q[r.clone()], &qd[r.clone()], &qdd[r], &g, o)?,
            Quantity::Gravity => dvrk_kin::gravity_torque(model, dm, &mut data, &q[r], &g, o)?,
            Quantity::MassMatrix { effects } => {
                dvrk_kin::mass_matrix(model, dm, &mut data, &q[r], &mut mass)?;
                if effects {
                    dvrk_kin::effects::motor_inertia_matrix(&model.effects, &mut mass);
                }
                for (k, x) in o.iter_mut().enumerate() {
                    *x = mass[(k / nq, k % nq)];
                }
            }
            Quantity::Regressor => {
                dvrk_kin::regressor(model, dm, &mut data, &q[r.clone()], &qd[r.clone()], &qdd[r], &g, &mut reg)?;
                let cols = reg.ncols();
                for (k, x) in o.iter_mut().enumerate() {
                    *x = reg[(k / cols, k % cols)];
                }
            }
        }
    }
    Ok(out)
}
