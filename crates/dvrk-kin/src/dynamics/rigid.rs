//! The spatial inertia of a rigid body (or of several added together) in world axes about the
//! world origin, in the linear form `(m, h = m c, J)` that sums over bodies.

use super::spatial::Spatial;
use nalgebra::{Matrix3, Vector3};

/// Spatial inertia about the world origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RigidInertia {
    /// kg
    pub m: f64,
    /// First moment `m c` (kg m), `c` the centre of mass.
    pub h: Vector3<f64>,
    /// Inertia matrix about the world origin (kg m^2).
    pub j: Matrix3<f64>,
}

impl RigidInertia {
    pub fn zero() -> Self {
        RigidInertia { m: 0.0, h: Vector3::zeros(), j: Matrix3::zeros() }
    }

    /// From mass (kg), centre of mass `c` (m) and inertia about it `ic` (kg m^2), all in world
    /// axes: the parallel-axis theorem `J = Ic + m (|c|^2 1 - c c^T)`.
    pub fn from_com(m: f64, c: &Vector3<f64>, ic: &Matrix3<f64>) -> Self {
        RigidInertia { m, h: c * m, j: ic + (Matrix3::identity() * c.norm_squared() - c * c.transpose()) * m }
    }

    /// Momentum (or force for an acceleration) `I v`: `(J w + h x v, m v - h x w)`.
    #[inline]
    pub fn apply(&self, v: &Spatial) -> Spatial {
        Spatial { ang: self.j * v.ang + self.h.cross(&v.lin), lin: v.lin * self.m - self.h.cross(&v.ang) }
    }

    pub fn add(&mut self, o: &RigidInertia) {
        self.m += o.m;
        self.h += o.h;
        self.j += o.j;
    }
}
