//! Spatial (6D) motion and force vectors: world axes, referred to the world origin.

use nalgebra::Vector3;
use std::ops::{Add, AddAssign, Mul};

/// A spatial vector in Plücker coordinates at the world origin.
///
/// As a motion (velocity, acceleration): `ang` is the angular velocity (rad/s) and `lin` the
/// velocity (m/s) of the body-fixed point that coincides with the world origin.
/// As a force: `ang` is the moment about the world origin (N·m) and `lin` the force (N).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spatial {
    pub ang: Vector3<f64>,
    pub lin: Vector3<f64>,
}

impl Spatial {
    /// The zero vector.
    #[inline]
    pub fn zero() -> Self {
        Spatial { ang: Vector3::zeros(), lin: Vector3::zeros() }
    }

    /// `self x m` for two motions (the derivative of `m` carried by a frame moving with `self`).
    #[inline]
    pub fn cross_motion(&self, m: &Spatial) -> Spatial {
        Spatial { ang: self.ang.cross(&m.ang), lin: self.ang.cross(&m.lin) + self.lin.cross(&m.ang) }
    }

    /// `self x* f` for a motion `self` and a force `f`.
    #[inline]
    pub fn cross_force(&self, f: &Spatial) -> Spatial {
        Spatial { ang: self.ang.cross(&f.ang) + self.lin.cross(&f.lin), lin: self.ang.cross(&f.lin) }
    }

    /// The power pairing of a motion and a force (W per unit), or of an axis and a force.
    #[inline]
    pub fn dot(&self, f: &Spatial) -> f64 {
        self.ang.dot(&f.ang) + self.lin.dot(&f.lin)
    }
}

impl Add for Spatial {
    type Output = Spatial;
    #[inline]
    fn add(self, o: Spatial) -> Spatial {
        Spatial { ang: self.ang + o.ang, lin: self.lin + o.lin }
    }
}

impl AddAssign for Spatial {
    #[inline]
    fn add_assign(&mut self, o: Spatial) {
        self.ang += o.ang;
        self.lin += o.lin;
    }
}

impl Mul<f64> for Spatial {
    type Output = Spatial;
    #[inline]
    fn mul(self, s: f64) -> Spatial {
        Spatial { ang: self.ang * s, lin: self.lin * s }
    }
}
