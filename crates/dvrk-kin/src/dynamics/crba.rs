//! Joint-space mass matrix by the composite-rigid-body algorithm on the frame tree.

use super::rigid::RigidInertia;
use super::rnea::body_world_inertia;
use super::setup::{check_common, placements_and_axes, DynamicsData, DynamicsModel};
use crate::fk::compute_frame_placements;
use crate::error::{KinError, Result};
use crate::model::Model;
use nalgebra::DMatrix;

/// The joint-space mass matrix `M(q)` (nq x nq; kg m^2, kg m, kg by joint types), by the
/// composite-rigid-body algorithm (one backward pass, not nq inverse-dynamics calls): in frame
/// variables `M_phi[i][j] = s_i . (I^c_i s_j)` for `j` an ancestor of `i`, then
/// `M = C^T M_phi C`. `out` must be nq x nq; it is overwritten. Allocates nothing.
pub fn mass_matrix(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, q: &[f64], out: &mut DMatrix<f64>) -> Result<()> {
    check_common(model, dm, data, q)?;
    check_mass(out, model.nq())?;
    placements_and_axes(model, dm, data, q);
    composite_pass(model, dm, data, out);
    Ok(())
}

/// The mass matrix `M(q)` and the bias efforts `h(q, q') = c(q, q') + g(q)` (N·m, N: the
/// efforts that hold the arm at zero acceleration) in one pass over the frame placements: what a
/// forward-dynamics step needs, `M q'' = tau - h`. `bias` has length nq, `mass` is nq x nq; both
/// are overwritten. Allocates nothing.
#[allow(clippy::too_many_arguments)]
pub fn mass_matrix_and_bias(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, q: &[f64], qd: &[f64], gravity: &nalgebra::Vector3<f64>, bias: &mut [f64], mass: &mut DMatrix<f64>) -> Result<()> {
    check_common(model, dm, data, q)?;
    compute_frame_placements(model, &mut data.kin, q);
    mass_matrix_and_bias_placed(model, dm, data, qd, gravity, bias, mass)
}

/// [`mass_matrix_and_bias`] on the placements already in `data.kin`: a stepper that placed the
/// frames at the end of its last step (for the bodies' poses) need not place them again. `data.kin`
/// must hold [`compute_frame_placements`] of `model` at the `q` meant (the caller's contract:
/// stale placements give the dynamics of the configuration they were computed at). `qd`,
/// `bias` and `mass` are checked as there.
pub fn mass_matrix_and_bias_placed(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, qd: &[f64], gravity: &nalgebra::Vector3<f64>, bias: &mut [f64], mass: &mut DMatrix<f64>) -> Result<()> {
    super::setup::check_vector(qd, model.nq(), "qd")?;
    super::setup::check_gravity(gravity)?;
    super::rnea::check_out(bias, model.nq())?;
    if data.kin.frames.len() != model.frames.len() || data.composite.len() != model.frames.len() {
        return Err(KinError::Size { what: "workspace frames (another model's data?)".into(), expected: model.frames.len(), got: data.kin.frames.len() });
    }
    check_mass(mass, model.nq())?;
    // Axes, Newton-Euler (keeping the body inertias), then the composite pass.
    super::setup::axes(model, dm, data);
    super::rnea::bias_pass(model, dm, data, qd, gravity, bias);
    accumulate(model, dm, data, mass);
    Ok(())
}

/// `out` is nq x nq.
fn check_mass(out: &DMatrix<f64>, n: usize) -> Result<()> {
    if out.nrows() != n || out.ncols() != n {
        return Err(KinError::Size { what: "mass matrix rows and columns (nq)".into(), expected: n, got: if out.nrows() != n { out.nrows() } else { out.ncols() } });
    }
    Ok(())
}

/// The composite-rigid-body pass after [`placements_and_axes`].
fn composite_pass(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, out: &mut DMatrix<f64>) {
    for i in 0..model.frames.len() {
        data.composite[i] = match dm.carries[i] {
            Some(b) => body_world_inertia(dm, b, data, i),
            None => RigidInertia::zero(),
        };
    }
    accumulate(model, dm, data, out);
}

/// `M` from each frame's own body inertia in `data.composite` (world axes), summed into subtree
/// composites on the way.
fn accumulate(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, out: &mut DMatrix<f64>) {
    for (i, f) in model.frames.iter().enumerate().rev() {
        if let Some(p) = f.parent {
            let ci = data.composite[i];
            data.composite[p].add(&ci);
        }
    }
    out.fill(0.0);
    let plan = &dm.crba;
    let m = out.as_mut_slice();
    let (mut pair, mut entry) = (0, 0);
    for &(i, pairs_end) in &plan.frames {
        // Force needed to accelerate the subtree of i at a unit rate of phi_i.
        let force = data.composite[i].apply(&data.axis[i]);
        for &(j, scatter_end) in &plan.pairs[pair..pairs_end] {
            let mij = data.axis[j].dot(&force);
            for &(at, c) in &plan.scatter[entry..scatter_end] {
                m[at] += c * mij;
            }
            entry = scatter_end;
        }
        pair = pairs_end;
    }
    // The upper triangle mirrors the lower.
    let n = plan.nq;
    for c in 0..n {
        for r in c + 1..n {
            m[c + r * n] = m[r + c * n];
        }
    }
}
