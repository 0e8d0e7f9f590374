//! The inverse-dynamics regressor: `tau = Y(q, q', q'') pi`, linear in the bodies' inertial
//! parameters (for identification).

use super::inertia::PARAMETERS_PER_BODY;
use super::setup::{check_common, check_gravity, check_vector, frame_rate, placements_and_axes, DynamicsData, DynamicsModel};
use super::spatial::Spatial;
use crate::error::{KinError, Result};
use crate::model::Model;
use nalgebra::{DMatrix, Vector3};

/// The regressor `Y` (nq x 10 nbodies) with `inverse_dynamics(q, qd, qdd) = Y pi`, `pi` the
/// bodies' parameters concatenated in [`Model::bodies`] order, each
/// `[m, m cx, m cy, m cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]` about the origin of the body's first
/// frame in its axes ([`super::BodyInertia::parameters`]; kg, kg m, kg m^2). Columns of a
/// body that never moves are zero. `out` must be nq x 10 nbodies; it is overwritten.
/// Allocates nothing.
///
/// Each body's Newton-Euler wrench is written as a 6 x 10 matrix of its velocity and
/// acceleration in body axes, then carried to every tree joint between the body and the base.
#[allow(clippy::too_many_arguments)]
pub fn regressor(
    model: &Model,
    dm: &DynamicsModel,
    data: &mut DynamicsData,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vector3<f64>,
    out: &mut DMatrix<f64>,
) -> Result<()> {
    check_common(model, dm, data, q)?;
    check_vector(qd, model.nq(), "qd")?;
    check_vector(qdd, model.nq(), "qdd")?;
    check_gravity(gravity)?;
    let cols = PARAMETERS_PER_BODY * model.bodies.len();
    if out.nrows() != model.nq() {
        return Err(KinError::Size { what: "regressor rows (nq)".into(), expected: model.nq(), got: out.nrows() });
    }
    if out.ncols() != cols {
        return Err(KinError::Size { what: "regressor columns (10 nbodies)".into(), expected: cols, got: out.ncols() });
    }
    placements_and_axes(model, dm, data, q);
    // Velocities and accelerations only (the forward pass of Newton-Euler).
    let base_a = Spatial { ang: Vector3::zeros(), lin: -gravity };
    for (i, f) in model.frames.iter().enumerate() {
        let (vp, ap) = match f.parent {
            Some(p) => (data.v[p], data.a[p]),
            None => (Spatial::zero(), base_a),
        };
        let s = data.axis[i];
        let vj = s * frame_rate(&dm.terms[i], qd);
        let v = vp + vj;
        data.v[i] = v;
        data.a[i] = ap + s * frame_rate(&dm.terms[i], qdd) + v.cross_motion(&vj);
    }
    out.fill(0.0);
    for (b, body) in model.bodies.iter().enumerate() {
        let frame = body.frames[0];
        let cols = body_columns(data, frame);
        let mut cur = Some(frame);
        while let Some(j) = cur {
            cur = model.frames[j].parent;
            for &(k, ck) in &dm.terms[j] {
                for (c, w) in cols.iter().enumerate() {
                    out[(k, PARAMETERS_PER_BODY * b + c)] += ck * data.axis[j].dot(w);
                }
            }
        }
    }
    Ok(())
}

/// The wrench (world axes, about the world origin) that body `frame`'s motion needs per unit of
/// each of its 10 parameters. In body axes at the body origin, with `w`, `nu` the angular and
/// origin velocity, `alpha`, `eta` the spatial accelerations and `acc = eta + w x nu` the
/// classical acceleration of the origin:
/// `f = m acc + alpha x h + w x (w x h)` and
/// `n = h x acc + J alpha + w x (J w)`.
fn body_columns(data: &DynamicsData, frame: usize) -> [Spatial; PARAMETERS_PER_BODY] {
    let pose = &data.kin.frames[frame];
    let r = pose.rotation.matrix();
    let p = pose.translation.vector;
    let (v, a) = (&data.v[frame], &data.a[frame]);
    // World spatial motion -> body axes at the body origin: v_P = v_O + w x p.
    let w = r.transpose() * v.ang;
    let nu = r.transpose() * (v.lin + v.ang.cross(&p));
    let alpha = r.transpose() * a.ang;
    let eta = r.transpose() * (a.lin + a.ang.cross(&p));
    let acc = eta + w.cross(&nu);
    let mut cols = [Spatial::zero(); PARAMETERS_PER_BODY];
    cols[0] = Spatial { ang: Vector3::zeros(), lin: acc };
    for k in 0..3 {
        let e = Vector3::ith(k, 1.0);
        cols[1 + k] = Spatial { ang: e.cross(&acc), lin: alpha.cross(&e) + w.cross(&w.cross(&e)) };
    }
    // J x for the unit symmetric matrix of each entry Ixx, Ixy, Ixz, Iyy, Iyz, Izz.
    let unit = |idx: usize, x: &Vector3<f64>| -> Vector3<f64> {
        match idx {
            0 => Vector3::new(x.x, 0.0, 0.0),
            1 => Vector3::new(x.y, x.x, 0.0),
            2 => Vector3::new(x.z, 0.0, x.x),
            3 => Vector3::new(0.0, x.y, 0.0),
            4 => Vector3::new(0.0, x.z, x.y),
            _ => Vector3::new(0.0, 0.0, x.z),
        }
    };
    for idx in 0..6 {
        cols[4 + idx] = Spatial { ang: unit(idx, &alpha) + w.cross(&unit(idx, &w)), lin: Vector3::zeros() };
    }
    // Body axes at the body origin -> world axes about the world origin.
    for c in cols.iter_mut() {
        let lin = r * c.lin;
        *c = Spatial { ang: r * c.ang + p.cross(&lin), lin };
    }
    cols
}
