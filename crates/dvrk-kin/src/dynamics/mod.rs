//! Rigid-body inverse dynamics of the closed-loop trees.
//!
//! Every passive frame's variable is an affine map of the actuated joints, `phi = C q + b`, so the
//! closed-loop mechanism is a tree in the frame variables whose loop constraints hold identically.
//! The algorithms run on that tree of frames (recursive Newton-Euler, composite rigid bodies) in
//! the coordinates `phi`, `phi' = C q'`, `phi'' = C q''`, with each body's inertia carried by the
//! body's first frame, and map the frame forces to the actuated joints by virtual work,
//! `tau = C^T tau_phi`. This is exact, not an approximation of the loops: the kinetic and
//! potential energies are functions of `q` through `phi`, and `phi` is linear in `q`.
//!
//! Quantities are spatial vectors in world axes referred to the world origin (Featherstone's
//! Plücker coordinates), so forces of different bodies add without transforms.
//!
//! Units: kg, m, s, rad; torques in N·m for revolute joints and N for prismatic ones.
//! Joint-space efforts: to get actuator efforts through the model's actuator coupling
//! (`joints = K actuators`), multiply by `K^T`.

mod crba;
mod crba_plan;
mod file_inertials;
mod inertia;
mod regressor;
mod rigid;
mod rnea;
mod setup;
mod spatial;

pub use crba::{mass_matrix, mass_matrix_and_bias, mass_matrix_and_bias_placed};
pub use inertia::{BodyInertia, PARAMETERS_PER_BODY, PARAMETER_NAMES};
pub use regressor::regressor;
pub use rnea::{actuator_effort, frame_bias_forces, gravity_torque, holding_torque, inverse_dynamics};
pub use setup::{DynamicsData, DynamicsModel};
pub use spatial::Spatial;
