//! The kinematic channel's nuisance: where the tracker is (tracker <- arm base, `X`) and where the
//! marker body sits on its link (link frame <- marker, `Y`), so that a tracked pose is
//! `M = X F(q) Y` with `F` the model's forward kinematics of the link. Started by hand-eye
//! calibration (`A X = X B` on relative motions; Park and Martin's rotation from the motions'
//! axes, translation by least squares), refined by Gauss-Newton on every sample.

use crate::error::{CalibError, Result};
use dvrk_kin::Pose;
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Translation3, Vector3, Vector6};

/// The two unknown transforms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Registration {
    /// Tracker frame <- the arm's base frame (m).
    pub tracker_from_base: Pose,
    /// Link frame <- marker body (m).
    pub link_from_marker: Pose,
}

/// Pose from a twist `[v; w]` (m, rad): translation `v`, rotation vector `w`.
pub fn pose_exp(x: &Vector6<f64>) -> Pose {
    Pose::from_parts(Translation3::new(x[0], x[1], x[2]), Rotation3::new(Vector3::new(x[3], x[4], x[5])))
}

/// `[position difference (m); rotation vector of a * b^-1 (rad)]`, both in the outer frame.
pub fn pose_difference(a: &Pose, b: &Pose) -> Vector6<f64> {
    let dp = a.translation.vector - b.translation.vector;
    // so3::log stays accurate for the tiny rotations of finite differences.
    let dr = dvrk_kin::so3::log(&(a.rotation * b.rotation.inverse()));
    Vector6::new(dp.x, dp.y, dp.z, dr.x, dr.y, dr.z)
}

/// A pose difference over the tracker's noise per axis: position over `sigma[0]` (m), rotation
/// over `sigma[1]` (rad).
pub fn whiten(v: Vector6<f64>, sigma: [f64; 2]) -> Vector6<f64> {
    Vector6::new(v[0] / sigma[0], v[1] / sigma[0], v[2] / sigma[0], v[3] / sigma[1], v[4] / sigma[1], v[5] / sigma[1])
}

/// The closest rotation to `m` (Frobenius), through its SVD.
fn project_rotation(m: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let d = (u * vt).determinant().signum();
    Some(Rotation3::from_matrix_unchecked(u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt))
}

impl Registration {
    /// The tracked pose this registration predicts for link pose `f` (in the base frame).
    pub fn predict(&self, f: &Pose) -> Pose {
        self.tracker_from_base * f * self.link_from_marker
    }

    /// The registration moved by `dx` (tracker side) and `dy` (marker side), twists.
    pub fn perturbed(&self, dx: &Vector6<f64>, dy: &Vector6<f64>) -> Registration {
        Registration { tracker_from_base: self.tracker_from_base * pose_exp(dx), link_from_marker: pose_exp(dy) * self.link_from_marker }
    }

    /// Hand-eye start and Gauss-Newton refinement from link poses `f` (base frame) and tracked
    /// poses `m`, weighting position and rotation residuals by `sigma` (m, rad).
    pub fn fit(f: &[Pose], m: &[Pose], sigma: [f64; 2]) -> Result<Registration> {
        let n = f.len().min(m.len());
        if n < 10 {
            return Err(CalibError::data("--marker-topic", format!("{n} tracked poses inside the analysed span (need at least 10)")));
        }
        Self::hand_eye(&f[..n], &m[..n])?.refined(&f[..n], &m[..n], sigma, 8)
    }

    /// At most `passes` Gauss-Newton steps from this registration on link poses `f` and tracked
    /// poses `m` (as [`Registration::fit`]'s).
    pub fn refined(&self, f: &[Pose], m: &[Pose], sigma: [f64; 2], passes: usize) -> Result<Registration> {
        let mut reg = self.clone();
        for _ in 0..passes {
            let (j, r) = reg.linearised(f, m, sigma);
            let step = match (j.transpose() * &j).cholesky() {
                Some(c) => c.solve(&(j.transpose() * &r)),
                None => return Err(CalibError::data("--marker-topic", "the tracker and marker transforms are not determined by this motion")),
            };
            let dx = Vector6::from_iterator(step.iter().take(6).copied());
            let dy = Vector6::from_iterator(step.iter().skip(6).copied());
            reg = reg.perturbed(&dx, &dy);
            if step.norm() < 1e-12 {
                break;
            }
        }
        Ok(reg)
    }

    /// The whitened residual (`6n`: measured minus predicted, position over `sigma[0]`, rotation
    /// over `sigma[1]`) and its Jacobian with respect to the registration's 12 twist parameters
    /// (so that `residual ≈ J dp` is the change a step `dp` explains).
    pub fn linearised(&self, f: &[Pose], m: &[Pose], sigma: [f64; 2]) -> (DMatrix<f64>, DVector<f64>) {
        let n = f.len();
        let w = |v: Vector6<f64>| whiten(v, sigma);
        let mut r = DVector::zeros(6 * n);
        let mut j = DMatrix::zeros(6 * n, 12);
        let h = 1e-7;
        for i in 0..n {
            let p0 = self.predict(&f[i]);
            r.fixed_rows_mut::<6>(6 * i).copy_from(&w(pose_difference(&m[i], &p0)));
            for k in 0..12 {
                let mut d = Vector6::zeros();
                d[k % 6] = h;
                let moved = if k < 6 { self.perturbed(&d, &Vector6::zeros()) } else { self.perturbed(&Vector6::zeros(), &d) };
                j.fixed_view_mut::<6, 1>(6 * i, k).copy_from(&(w(pose_difference(&moved.predict(&f[i]), &p0)) / h));
            }
        }
        (j, r)
    }

    /// `A X = X B` on pairs of samples a stride apart: `A = M_i M_k^-1`, `B = F_i F_k^-1`.
    fn hand_eye(f: &[Pose], m: &[Pose]) -> Result<Registration> {
        let n = f.len();
        let stride = (n / 40).max(1);
        let pairs: Vec<(usize, usize)> = (0..n).step_by(stride).flat_map(|i| (0..n).step_by(7 * stride).filter(move |&k| k != i).map(move |k| (i, k))).collect();
        let mut h = Matrix3::zeros();
        let mut used = Vec::new();
        for &(i, k) in &pairs {
            let a = m[i] * m[k].inverse();
            let b = f[i] * f[k].inverse();
            let (wa, wb) = (dvrk_kin::so3::log(&a.rotation), dvrk_kin::so3::log(&b.rotation));
            // Small or near-pi rotations carry no usable axis.
            if wb.norm() > 0.02 && wb.norm() < 3.0 {
                h += wa * wb.transpose();
                used.push((a, b));
            }
        }
        let rx = project_rotation(&h)
            .filter(|_| used.len() >= 3)
            .ok_or_else(|| CalibError::data("--marker-topic", "the link barely rotates: the tracker's registration cannot be found"))?;
        let svd = h.svd(false, false);
        if svd.singular_values.min() < 1e-6 * svd.singular_values.max() {
            return Err(CalibError::data("--marker-topic", "the link rotates about one axis only: the tracker's registration is not determined"));
        }
        let mut lhs = DMatrix::zeros(3 * used.len(), 3);
        let mut rhs = DVector::zeros(3 * used.len());
        for (s, (a, b)) in used.iter().enumerate() {
            lhs.fixed_view_mut::<3, 3>(3 * s, 0).copy_from(&(a.rotation.matrix() - Matrix3::identity()));
            rhs.fixed_rows_mut::<3>(3 * s).copy_from(&(rx * b.translation.vector - a.translation.vector));
        }
        let tx = lhs.clone().svd(true, true).solve(&rhs, 1e-12).map_err(|e| CalibError::data("--marker-topic", e.to_string()))?;
        let x = Pose::from_parts(Translation3::new(tx[0], tx[1], tx[2]), rx);
        // The marker on its link: the mean of F_i^-1 X^-1 M_i.
        let (mut rot, mut t) = (Matrix3::zeros(), Vector3::zeros());
        for i in 0..n {
            let y = f[i].inverse() * x.inverse() * m[i];
            rot += y.rotation.matrix();
            t += y.translation.vector;
        }
        let ry = project_rotation(&rot).ok_or_else(|| CalibError::data("--marker-topic", "no mean marker orientation"))?;
        Ok(Registration { tracker_from_base: x, link_from_marker: Pose::from_parts(Translation3::from(t / n as f64), ry) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Known transforms and link poses rotating about three axes: the fit returns them.
    #[test]
    fn hand_eye_and_refinement_recover_known_transforms() {
        let x = pose_exp(&Vector6::new(0.3, -0.2, 1.1, 0.4, -0.3, 2.0));
        let y = pose_exp(&Vector6::new(0.01, 0.02, -0.03, -1.0, 0.2, 0.1));
        let f: Vec<Pose> = (0..200)
            .map(|i| i as f64 * 0.05)
            .map(|s| pose_exp(&Vector6::new(0.1 * s.sin(), 0.05 * (2.0 * s).cos(), 0.2 + 0.03 * s.sin(), 0.5 * s.sin(), 0.4 * (1.3 * s).cos(), 0.3 * (0.7 * s).sin())))
            .collect();
        let m: Vec<Pose> = f.iter().map(|fi| x * fi * y).collect();
        let reg = Registration::fit(&f, &m, [1e-4, 1e-3]).unwrap();
        let ex = pose_difference(&reg.tracker_from_base, &x);
        let ey = pose_difference(&reg.link_from_marker, &y);
        assert!(ex.norm() < 1e-9 && ey.norm() < 1e-9, "{ex} {ey}");
        // One axis only: refused with a reason.
        let f1: Vec<Pose> = (0..200).map(|i| pose_exp(&Vector6::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.01 * i as f64))).collect();
        let m1: Vec<Pose> = f1.iter().map(|fi| x * fi * y).collect();
        let e = Registration::fit(&f1, &m1, [1e-4, 1e-3]).unwrap_err().to_string();
        assert!(e.contains("one axis"), "{e}");
    }
}
