//! Inertial parameters of one rigid body, in the body's inertial frame (its first DH frame), and
//! their standard linear form for identification.

use crate::error::{KinError, Result};
use nalgebra::{Matrix3, Vector3};

/// Number of inertial parameters per body in the linear form.
pub const PARAMETERS_PER_BODY: usize = 10;

/// Names of the linear-form parameters, in order (see [`BodyInertia::parameters`]).
pub const PARAMETER_NAMES: [&str; PARAMETERS_PER_BODY] = ["m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz"];

/// Mass, centre of mass and inertia of one rigid body, in the axes of the body's first frame
/// (the frame `Model::bodies[b].frames[0]`, as the inertials files give them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyInertia {
    /// kg
    pub mass: f64,
    /// Centre of mass in the body frame (m).
    pub com: Vector3<f64>,
    /// Inertia matrix about the centre of mass, body-frame axes (kg m^2).
    pub inertia: Matrix3<f64>,
}

impl BodyInertia {
    /// From row-major figures as the inertials files write them.
    pub fn new(mass: f64, com: [f64; 3], inertia: [[f64; 3]; 3]) -> Self {
        BodyInertia { mass, com: Vector3::from(com), inertia: Matrix3::from_fn(|i, j| inertia[i][j]) }
    }

    /// Physical consistency, or an error naming `what`'s field and value: finite positive mass,
    /// finite centre of mass, symmetric inertia whose principal moments are non-negative and obey
    /// the triangle inequality `I1 <= I2 + I3` (the moments of some real mass distribution).
    /// A zero moment is accepted: point masses and thin rods are the limits the closed-form
    /// checks use.
    pub fn check(&self, what: &str) -> Result<()> {
        if !(self.mass.is_finite() && self.mass > 0.0) {
            return Err(KinError::Value { what: format!("{what}.mass"), value: self.mass, message: "must be a positive finite mass (kg)".into() });
        }
        if let Some(x) = self.com.iter().find(|x| !x.is_finite()) {
            return Err(KinError::Value { what: format!("{what}.com"), value: *x, message: "centre of mass must be finite (m)".into() });
        }
        let i = &self.inertia;
        if let Some(x) = i.iter().find(|x| !x.is_finite()) {
            return Err(KinError::Value { what: format!("{what}.inertia"), value: *x, message: "inertia must be finite (kg m^2)".into() });
        }
        let scale = i.abs().max();
        let asym = (i - i.transpose()).abs().max();
        if asym > 1e-12 * scale {
            return Err(KinError::Value { what: format!("{what}.inertia"), value: asym, message: "inertia matrix is not symmetric (largest |I - I^T|, kg m^2)".into() });
        }
        let e = i.symmetric_eigenvalues();
        // Round-off of the eigen solver: relative to the largest moment.
        let tol = 1e-12 * scale;
        if let Some(x) = e.iter().find(|x| **x < -tol) {
            return Err(KinError::Value { what: format!("{what}.inertia"), value: *x, message: format!("principal moment is negative (moments {:?} kg m^2)", e.as_slice()) });
        }
        for k in 0..3 {
            let excess = e[k] - e[(k + 1) % 3] - e[(k + 2) % 3];
            if excess > tol {
                return Err(KinError::Value {
                    what: format!("{what}.inertia"),
                    value: e[k],
                    message: format!("principal moment exceeds the sum of the other two by {excess:.3e} kg m^2 (triangle inequality; moments {:?})", e.as_slice()),
                });
            }
        }
        Ok(())
    }

    /// This body with a point mass `mass` (kg) added at `at` (m, body frame): the combined mass,
    /// centre of mass and inertia about it (parallel-axis theorem).
    pub fn with_point_mass(&self, mass: f64, at: &Vector3<f64>) -> BodyInertia {
        if mass <= 0.0 {
            return self.clone();
        }
        let m = self.mass + mass;
        let c = (self.com * self.mass + at * mass) / m;
        let shift = |mk: f64, r: Vector3<f64>| (Matrix3::identity() * r.norm_squared() - r * r.transpose()) * mk;
        let inertia = self.inertia + shift(self.mass, self.com - c) + shift(mass, at - c);
        BodyInertia { mass: m, com: c, inertia }
    }

    /// The standard linear form, about the body-frame origin in body-frame axes:
    /// `[m, m cx, m cy, m cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]` (kg, kg m, kg m^2), where the `I`
    /// are entries of the inertia matrix about the origin, `J = Ic + m (|c|^2 1 - c c^T)`
    /// (entries, not products of inertia: `Ixy = -sum m x y`). Inverse dynamics is linear in
    /// these ([`crate::dynamics::regressor`]).
    pub fn parameters(&self) -> [f64; PARAMETERS_PER_BODY] {
        let c = self.com;
        let j = self.inertia + (Matrix3::identity() * c.norm_squared() - c * c.transpose()) * self.mass;
        let h = c * self.mass;
        [self.mass, h.x, h.y, h.z, j[(0, 0)], j[(0, 1)], j[(0, 2)], j[(1, 1)], j[(1, 2)], j[(2, 2)]]
    }

    /// Back from the linear form (the inverse of [`BodyInertia::parameters`]), checked for
    /// physical consistency (`what` names the body in errors).
    pub fn from_parameters(p: &[f64; PARAMETERS_PER_BODY], what: &str) -> Result<BodyInertia> {
        let b = BodyInertia::from_parameters_unchecked(p)
            .ok_or_else(|| KinError::Value { what: format!("{what} parameter m"), value: p[0], message: "must be a positive finite mass (kg)".into() })?;
        b.check(what)?;
        Ok(b)
    }

    /// Back from the linear form without the consistency check (a fit's raw output, to be
    /// projected onto the physical set); `None` unless the mass is positive and finite.
    pub fn from_parameters_unchecked(p: &[f64; PARAMETERS_PER_BODY]) -> Option<BodyInertia> {
        let m = p[0];
        if !(m.is_finite() && m > 0.0) {
            return None;
        }
        let c = Vector3::new(p[1], p[2], p[3]) / m;
        let j = Matrix3::new(p[4], p[5], p[6], p[5], p[7], p[8], p[6], p[8], p[9]);
        let inertia = j - (Matrix3::identity() * c.norm_squared() - c * c.transpose()) * m;
        Some(BodyInertia { mass: m, com: c, inertia })
    }
}
