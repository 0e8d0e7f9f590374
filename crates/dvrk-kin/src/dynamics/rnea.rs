//! Recursive Newton-Euler inverse dynamics on the frame tree, mapped to the actuated joints.

use super::rigid::RigidInertia;
use super::setup::{check_common, check_gravity, check_vector, frame_rate, placements_and_axes, DynamicsData, DynamicsModel};
use super::spatial::Spatial;
use crate::error::Result;
use crate::model::Model;
use crate::KinError;
use nalgebra::Vector3;

/// Joint efforts `tau = M(q) q'' + c(q, q') + g(q)` (N·m revolute, N prismatic, one per actuated
/// joint) that produce accelerations `qdd` at positions `q` (rad, m) and velocities `qd`
/// (rad/s, m/s) under `gravity` (world axes, m/s^2, e.g. `[0, 0, -9.81]`). No friction, damping
/// or drive inertia. Written into `tau` (length nq); allocates nothing.
#[allow(clippy::too_many_arguments)]
pub fn inverse_dynamics(
    model: &Model,
    dm: &DynamicsModel,
    data: &mut DynamicsData,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vector3<f64>,
    tau: &mut [f64],
) -> Result<()> {
    check_common(model, dm, data, q)?;
    check_vector(qd, model.nq(), "qd")?;
    check_vector(qdd, model.nq(), "qdd")?;
    check_gravity(gravity)?;
    check_out(tau, model.nq())?;
    placements_and_axes(model, dm, data, q);
    rnea(model, dm, data, Rates::Joints(qd), Rates::Joints(qdd), gravity);
    project(dm, &data.tau_phi, tau);
    Ok(())
}

/// The effort the drives must supply (N·m, N): [`inverse_dynamics`] plus what the model's
/// friction and spring effects take ([`crate::effects::effort`], `velocity_scale` smoothing the
/// Coulomb sign, 0 for a hard sign) and its motors' reflected inertias
/// ([`crate::effects::inertial_effort`]). Payload masses enter through `dm`'s inertias (build it
/// from [`crate::effects::effect_inertias`]). Allocates nothing.
#[allow(clippy::too_many_arguments)]
pub fn actuator_effort(
    model: &Model,
    dm: &DynamicsModel,
    data: &mut DynamicsData,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    gravity: &Vector3<f64>,
    velocity_scale: f64,
    tau: &mut [f64],
) -> Result<()> {
    inverse_dynamics(model, dm, data, q, qd, qdd, gravity, tau)?;
    // The effects' forces act on the joints; the drive supplies their opposite.
    for t in tau.iter_mut() {
        *t = -*t;
    }
    crate::effects::effort(&model.effects, q, qd, velocity_scale, tau);
    crate::effects::inertial_effort(&model.effects, qdd, tau);
    for t in tau.iter_mut() {
        *t = -*t;
    }
    Ok(())
}

/// Gravity torques `g(q)`: the efforts that hold the arm still at `q` (N·m, N), i.e. the
/// gradient of the potential energy. Written into `tau` (length nq); allocates nothing.
pub fn gravity_torque(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, q: &[f64], gravity: &Vector3<f64>, tau: &mut [f64]) -> Result<()> {
    check_common(model, dm, data, q)?;
    check_gravity(gravity)?;
    check_out(tau, model.nq())?;
    placements_and_axes(model, dm, data, q);
    // At rest every body accelerates as the base does (-g): its force is the opposite of its
    // weight at its centre of mass, so no inertia tensor enters. A controller's feed-forward runs
    // this every step: the ECM's gravity feed-forward took half its reduced-engine step through
    // Newton-Euler with zero rates, a quarter this way.
    for (i, f) in data.f.iter_mut().enumerate() {
        *f = match dm.carries[i] {
            Some(b) => {
                let ine = &dm.inertias[b];
                let pose = &data.kin.frames[i];
                let lin = -gravity * ine.mass;
                Spatial { ang: (pose.translation.vector + pose.rotation * ine.com).cross(&lin), lin }
            }
            None => Spatial::zero(),
        };
    }
    transmit(model, data);
    project(dm, &data.tau_phi, tau);
    Ok(())
}

/// The efforts (N·m, N) that hold the arm still at `q`: its gravity torque ([`gravity_torque`])
/// plus what the model's configuration-dependent effects ask of the drives there (springs,
/// `cable_spring`s, actuator springs, effort offsets: the negative of their force at rest). What a
/// gravity compensation feeds forward: the dVRK's MTM compensation takes the platform's cable
/// and the motors' offsets in with the weight. Allocates nothing.
pub fn holding_torque(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, q: &[f64], gravity: &Vector3<f64>, tau: &mut [f64]) -> Result<()> {
    gravity_torque(model, dm, data, q, gravity, tau)?;
    // Velocities are zero: the sign of Coulomb friction is 0, only offsets and springs act. The
    // joint velocities here are `data`'s scratch vector, zeroed.
    data.scratch_qd.iter_mut().for_each(|v| *v = 0.0);
    data.scratch_force.iter_mut().for_each(|v| *v = 0.0);
    crate::effects::effort(&model.effects, q, &data.scratch_qd, 0.0, &mut data.scratch_force);
    for (t, f) in tau.iter_mut().zip(&data.scratch_force) {
        *t -= f;
    }
    Ok(())
}

/// Velocity-product forces on the frame tree's own joints, as if the loops were cut: the
/// Coriolis, centrifugal and gyroscopic part of each frame's generalised force (N·m about a
/// revolute frame's z, N along a prismatic one's) at the placements of actuated positions `q`
/// (rad, m) and independent frame rates `phi_rates` (one per frame, rad/s or m/s; a frame without
/// a variable moves with its parent whatever its entry). A simulator that integrates the tree
/// (rapier's multibody) needs these where the actuated map `phi' = C q'` does not hold: between
/// its loop constraints' solves. Written into `out` (one per frame, 0 for a frame without a
/// variable); allocates nothing.
pub fn frame_bias_forces(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, q: &[f64], phi_rates: &[f64], out: &mut [f64]) -> Result<()> {
    check_common(model, dm, data, q)?;
    let nf = model.frames.len();
    for (what, x) in [("frame rates", phi_rates.len()), ("output (frames)", out.len())] {
        if x != nf {
            return Err(KinError::Size { what: what.into(), expected: nf, got: x });
        }
    }
    if let Some(x) = phi_rates.iter().find(|x| !x.is_finite()) {
        return Err(KinError::Value { what: "frame rate".into(), value: *x, message: "must be finite (rad/s, m/s)".into() });
    }
    placements_and_axes(model, dm, data, q);
    rnea(model, dm, data, Rates::Frames(phi_rates), Rates::Zero, &Vector3::zeros());
    for ((o, t), terms) in out.iter_mut().zip(&data.tau_phi).zip(&dm.terms) {
        *o = if terms.is_empty() { 0.0 } else { *t };
    }
    Ok(())
}

/// The bias efforts `c(q, q') + g(q)` into `bias` (length nq), after [`placements_and_axes`].
/// Leaves each frame's body inertia in `data.composite` ([`rnea_keeping`]).
pub(crate) fn bias_pass(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, qd: &[f64], gravity: &Vector3<f64>, bias: &mut [f64]) {
    rnea_keeping(model, dm, data, Rates::Joints(qd), Rates::Zero, gravity, true);
    project(dm, &data.tau_phi, bias);
}

pub(crate) fn check_out(tau: &[f64], nq: usize) -> Result<()> {
    if tau.len() != nq {
        return Err(KinError::Size { what: "output tau (nq)".into(), expected: nq, got: tau.len() });
    }
    Ok(())
}

/// The frames' rates (or their derivatives) in [`rnea`].
#[derive(Clone, Copy)]
enum Rates<'a> {
    /// Through the actuated joints' (`phi' = C q'`).
    Joints(&'a [f64]),
    /// One per frame; a frame without a variable has none.
    Frames(&'a [f64]),
    Zero,
}

impl Rates<'_> {
    fn of(&self, terms: &[(usize, f64)], frame: usize) -> f64 {
        match self {
            Rates::Joints(x) => frame_rate(terms, x),
            Rates::Frames(x) if !terms.is_empty() => x[frame],
            _ => 0.0,
        }
    }
}

/// The two passes, after [`placements_and_axes`]: each frame's generalised force into
/// `data.tau_phi`. Gravity enters as an upward acceleration `-g` of the base, which every body
/// inherits.
fn rnea(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, qd: Rates, qdd: Rates, gravity: &Vector3<f64>) {
    rnea_keeping(model, dm, data, qd, qdd, gravity, false)
}

/// [`rnea`]; with `keep`, each frame's body inertia in world axes is left in `data.composite`
/// for the composite-rigid-body pass that follows (computed once for both).
fn rnea_keeping(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, qd: Rates, qdd: Rates, gravity: &Vector3<f64>, keep: bool) {
    let base_a = Spatial { ang: Vector3::zeros(), lin: -gravity };
    for (i, f) in model.frames.iter().enumerate() {
        let (vp, ap) = match f.parent {
            Some(p) => (data.v[p], data.a[p]),
            None => (Spatial::zero(), base_a),
        };
        let s = data.axis[i];
        let terms = &dm.terms[i];
        let vj = s * qd.of(terms, i);
        let v = vp + vj;
        // The axis is fixed in the moving frame: d/dt (s phi') = s phi'' + v x (s phi').
        let a = ap + s * qdd.of(terms, i) + v.cross_motion(&vj);
        data.v[i] = v;
        data.a[i] = a;
        data.f[i] = match dm.carries[i] {
            Some(b) => {
                let ine = body_world_inertia(dm, b, data, i);
                if keep {
                    data.composite[i] = ine;
                }
                ine.apply(&a) + v.cross_force(&ine.apply(&v))
            }
            None => {
                if keep {
                    data.composite[i] = RigidInertia::zero();
                }
                Spatial::zero()
            }
        };
    }
    transmit(model, data);
}

/// The backward pass: each frame's force summed over its subtree, and its generalised force
/// `s_i . f_i` into `data.tau_phi`.
fn transmit(model: &Model, data: &mut DynamicsData) {
    for (i, f) in model.frames.iter().enumerate().rev() {
        data.tau_phi[i] = data.axis[i].dot(&data.f[i]);
        if let Some(p) = f.parent {
            let fi = data.f[i];
            data.f[p] += fi;
        }
    }
}

/// Body `b`'s inertia in world axes about the world origin; `frame` is its inertial frame.
pub(crate) fn body_world_inertia(dm: &DynamicsModel, b: usize, data: &DynamicsData, frame: usize) -> RigidInertia {
    let ine = &dm.inertias[b];
    let pose = &data.kin.frames[frame];
    let r = pose.rotation.matrix();
    let c = pose.translation.vector + r * ine.com;
    RigidInertia::from_com(ine.mass, &c, &(r * ine.inertia * r.transpose()))
}

/// `tau = C^T tau_phi`: virtual work of the frame forces through `phi = C q + b`.
pub(crate) fn project(dm: &DynamicsModel, tau_phi: &[f64], tau: &mut [f64]) {
    tau.fill(0.0);
    for (terms, t) in dm.terms.iter().zip(tau_phi) {
        for (k, c) in terms {
            tau[*k] += c * t;
        }
    }
}
