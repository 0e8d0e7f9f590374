//! The immutable dynamics model (a kinematic model's frame tree with the bodies' inertias) and its
//! reusable workspace.

use super::inertia::BodyInertia;
use super::rigid::RigidInertia;
use super::spatial::Spatial;
use crate::error::{KinError, Result};
use crate::fk::{compute_frame_placements, Data};
use crate::model::{Model, Motion};
use nalgebra::Vector3;

/// How a frame moves on its tree joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    Fixed,
    Revolute,
    Prismatic,
}

/// Inertias of a model's bodies, and the tree data the algorithms need, checked once.
/// Built for one [`Model`]; the algorithms check that the model they get has the same shape.
#[derive(Debug, Clone)]
pub struct DynamicsModel {
    pub(crate) model_name: String,
    pub(crate) nq: usize,
    pub(crate) nframes: usize,
    /// One per body of the model, in [`Model::bodies`] order.
    pub(crate) inertias: Vec<BodyInertia>,
    /// Per frame: the body whose inertial frame it is (its first frame), if any.
    pub(crate) carries: Vec<Option<usize>>,
    /// Per frame: its motion.
    pub(crate) kind: Vec<Kind>,
    /// Per frame: the non-zero coefficients `(joint, c)` of its variable `phi = c . q + b`.
    pub(crate) terms: Vec<Vec<(usize, f64)>>,
    /// The composite-rigid-body pass's frame pairs and where each lands in `M`, flattened once.
    pub(crate) crba: super::crba_plan::Plan,
}

impl DynamicsModel {
    /// Attach `inertias` (one per body, in [`Model::bodies`] order, each in the body's first
    /// frame) to `model`. Every inertia is checked ([`BodyInertia::check`]); a body rigid to the
    /// base needs one too, though it never moves.
    pub fn new(model: &Model, inertias: Vec<BodyInertia>) -> Result<DynamicsModel> {
        if inertias.len() != model.bodies.len() {
            return Err(KinError::Size { what: format!("body inertias of model {}", model.name), expected: model.bodies.len(), got: inertias.len() });
        }
        for (b, ine) in model.bodies.iter().zip(&inertias) {
            ine.check(&format!("body {}", b.name))?;
        }
        let nf = model.frames.len();
        let mut carries = vec![None; nf];
        for (bi, b) in model.bodies.iter().enumerate() {
            let first = *b.frames.first().ok_or_else(|| KinError::field(format!("bodies ({}).frames", b.name), "body has no frame"))?;
            carries[first] = Some(bi);
        }
        let kind = model
            .frames
            .iter()
            .map(|f| match f.motion {
                Motion::Fixed(_) => Kind::Fixed,
                Motion::Revolute { .. } => Kind::Revolute,
                Motion::Prismatic => Kind::Prismatic,
            })
            .collect();
        let terms: Vec<Vec<(usize, f64)>> = model.frames.iter().map(|f| f.variable().map(|v| v.joints().collect()).unwrap_or_default()).collect();
        let crba = super::crba_plan::Plan::new(model, &terms);
        Ok(DynamicsModel { model_name: model.name.clone(), nq: model.nq(), nframes: nf, inertias, carries, kind, terms, crba })
    }

    /// The body inertias, in [`Model::bodies`] order.
    pub fn inertias(&self) -> &[BodyInertia] {
        &self.inertias
    }

    /// The linear-form parameters of every body, concatenated (`10 * nbodies`; the order of
    /// [`BodyInertia::parameters`]): the `pi` of `tau = Y pi`.
    pub fn parameters(&self) -> Vec<f64> {
        self.inertias.iter().flat_map(|b| b.parameters()).collect()
    }

    /// An error unless `model` has the shape this was built for.
    pub(crate) fn check_model(&self, model: &Model) -> Result<()> {
        if model.nq() != self.nq || model.frames.len() != self.nframes {
            return Err(KinError::field(
                "dynamics model",
                format!(
                    "built for model {} ({} joints, {} frames), used with model {} ({} joints, {} frames)",
                    self.model_name,
                    self.nq,
                    self.nframes,
                    model.name,
                    model.nq(),
                    model.frames.len()
                ),
            ));
        }
        Ok(())
    }
}

/// Reusable workspace of the dynamics algorithms: every buffer sized once.
#[derive(Debug, Clone)]
pub struct DynamicsData {
    /// Frame placements at the last evaluated `q` (world poses).
    pub kin: Data,
    /// Per frame: the unit motion of its tree joint (world axes), zero for fixed frames.
    pub(crate) axis: Vec<Spatial>,
    /// Per frame: spatial velocity and acceleration (the latter offset by `-g`).
    pub(crate) v: Vec<Spatial>,
    pub(crate) a: Vec<Spatial>,
    /// Per frame: the force its tree joint transmits to the subtree (about the world origin).
    pub(crate) f: Vec<Spatial>,
    /// Per frame: the generalized force on its variable (N·m or N).
    pub(crate) tau_phi: Vec<f64>,
    /// Per frame: composite inertia of its subtree (mass matrix).
    pub(crate) composite: Vec<RigidInertia>,
    /// Per joint: zero velocities and the effects' forces ([`super::holding_torque`]).
    pub(crate) scratch_qd: Vec<f64>,
    pub(crate) scratch_force: Vec<f64>,
}

impl DynamicsData {
    /// Allocate the workspace of `model`.
    pub fn new(model: &Model) -> Self {
        let nf = model.frames.len();
        DynamicsData {
            kin: Data::new(model),
            axis: vec![Spatial::zero(); nf],
            v: vec![Spatial::zero(); nf],
            a: vec![Spatial::zero(); nf],
            f: vec![Spatial::zero(); nf],
            tau_phi: vec![0.0; nf],
            composite: vec![RigidInertia::zero(); nf],
            scratch_qd: vec![0.0; model.nq()],
            scratch_force: vec![0.0; model.nq()],
        }
    }
}

/// An error unless `x` (named `what`) has `n` finite entries.
pub(crate) fn check_vector(x: &[f64], n: usize, what: &str) -> Result<()> {
    if x.len() != n {
        return Err(KinError::Size { what: what.into(), expected: n, got: x.len() });
    }
    if let Some((k, v)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(KinError::Value { what: format!("{what}[{k}]"), value: *v, message: "not finite".into() });
    }
    Ok(())
}

/// Checks shared by all algorithms: shapes of the model, data and `q`.
pub(crate) fn check_common(model: &Model, dm: &DynamicsModel, data: &DynamicsData, q: &[f64]) -> Result<()> {
    dm.check_model(model)?;
    if data.v.len() != model.frames.len() || data.kin.frames.len() != model.frames.len() {
        return Err(KinError::Size { what: "dynamics data frames".into(), expected: model.frames.len(), got: data.v.len() });
    }
    model.check_q_size(q)
}

/// An error unless `g` is finite.
pub(crate) fn check_gravity(g: &Vector3<f64>) -> Result<()> {
    if let Some(x) = g.iter().find(|x| !x.is_finite()) {
        return Err(KinError::Value { what: "gravity".into(), value: *x, message: "must be finite (m/s^2)".into() });
    }
    Ok(())
}

/// Frame placements at `q` and each frame's joint axis as a unit spatial motion: a revolute
/// axis `z` through `o` is `(z, o x z)`, a prismatic one `(0, z)`. The axis is the z axis of
/// `parent * pre`, fixed in both the parent and the frame.
pub(crate) fn placements_and_axes(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData, q: &[f64]) {
    compute_frame_placements(model, &mut data.kin, q);
    axes(model, dm, data);
}

/// Each frame's joint axis from the placements in `data.kin` (see [`placements_and_axes`]).
pub(crate) fn axes(model: &Model, dm: &DynamicsModel, data: &mut DynamicsData) {
    for (i, f) in model.frames.iter().enumerate() {
        data.axis[i] = match dm.kind[i] {
            Kind::Fixed => Spatial::zero(),
            kind => {
                let parent = match f.parent {
                    Some(p) => &data.kin.frames[p],
                    None => &model.base,
                };
                let joint = parent * f.pre();
                let z: Vector3<f64> = joint.rotation.matrix().column(2).into();
                if kind == Kind::Revolute {
                    Spatial { ang: z, lin: joint.translation.vector.cross(&z) }
                } else {
                    Spatial { ang: Vector3::zeros(), lin: z }
                }
            }
        };
    }
}

/// `sum_k c_k x_k` over a frame's variable's terms: its rate for `x = q'`.
#[inline]
pub(crate) fn frame_rate(terms: &[(usize, f64)], x: &[f64]) -> f64 {
    terms.iter().map(|(k, c)| c * x[*k]).sum()
}
