//! # dvrk-kin
//!
//! Closed-loop kinematic trees of the da Vinci Research Kit manipulators in modified (or
//! standard) DH: frames with several successors, passive frames driven by affine maps of the
//! actuated joints, loop-closure points, the remote centre of motion, serial dVRK equivalents,
//! Jacobians, inverse kinematics, rigid-body inverse dynamics (RNEA, CRBA, the regressor) of the
//! closed-loop trees, and URDF/SDF interchange. No physics-engine dependency.
//!
//! The design follows Pinocchio: an immutable [`Model`] (flat arrays, parents before children)
//! and a reusable [`Data`] workspace; algorithms are free functions that fill `Data`.
//!
//! ```
//! use dvrk_kin::prelude::*;
//! let model = dvrk_kin::load("psm", None).unwrap();
//! let mut data = Data::new(&model);
//! let q = model.home();
//! forward_kinematics(&model, &mut data, &q).unwrap();
//! assert!(max_closure_residual(&model, &data) < 1e-12);
//! ```
//!
//! Units: metres, radians, seconds, newtons everywhere.

mod bodies;
mod coupling;
pub mod atomic;
pub mod check;
pub mod closure;
pub mod compose;
pub mod dvrk_json;
pub mod dynamics;
pub mod effects;
mod error;
pub mod expr;
mod fk;
pub mod ik;
mod jacobian;
pub mod limits;
pub mod load;
mod model;
mod play;
pub mod presliding;
mod vocabulary;
mod compile;
pub mod nesting;
pub mod rcm;
pub mod sdf;
pub mod so3;
pub mod exact;
pub mod spec;
pub mod text_file;
pub mod urdf;

pub use dynamics::{frame_bias_forces, gravity_torque, holding_torque, inverse_dynamics, mass_matrix, mass_matrix_and_bias, mass_matrix_and_bias_placed, regressor, BodyInertia, DynamicsData, DynamicsModel};
pub use closure::{closure_conditioning, closure_gap, closure_jacobian, max_closure_residual};
pub use error::{fmt_number, KinError, Result};
pub use fk::{compute_frame_placements, forward_kinematics, Data};
pub use ik::{inverse_kinematics, IkOptions, IkSolution};
pub use jacobian::frame_jacobian;
pub use limits::LimitTally;
pub use load::{builtin_names, load};
pub use model::{pose_from_rows, pose_to_rows, sample_configurations, Body, Closure, Frame, Joint, Model, Part, Pose, Rcm};
pub use spec::{DriveSpec, FrameJoint, FrameRef, InertialCovarianceSpec, InertialSpec, JointType, MeshSpec, ModelSpec};

/// The names most programs need.
pub mod prelude {
    pub use crate::{
        forward_kinematics, frame_jacobian, inverse_kinematics, max_closure_residual, Data, IkOptions, KinError, Model,
        Pose,
    };
}
