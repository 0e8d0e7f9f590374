//! What gravity cannot tell apart among payloads: bodies that move with the same outer joints
//! (the PSM's pitch linkage: the parallelogram's back, bottom, top and front links, `pitch_end`,
//! the insertion stage and the counterweight all move with the yaw and the pitch, and no joint
//! beyond the insertion moves them) carry a load with the same gravitational signature up to its
//! placement; what tells them apart is the load's inertia. And a body that only translates
//! against the arm's first moving body (the parallelogram's bottom and top links, whose
//! orientation is fixed while the pitch moves) carries every point of it on one circle, the
//! crank's: gravity fixes the mass times the crank wherever on the link the weight sits.

use crate::error::Result;
use dvrk_kin::{JointType, Model, Pose};
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// A body's family: the revolute joints before the first prismatic one that move it, when no
/// joint from the prismatic one's successor on does (`None` for a body a later joint moves, or
/// that none of those moves). Bodies of one family share their load's gravitational signature.
pub fn family(model: &Model, body: usize, q: &[f64]) -> Result<Option<Vec<usize>>> {
    let frame = model.bodies[body].frames[0];
    let at = |q: &[f64]| -> Result<Pose> { Ok(model.fk(q).map_err(|e| crate::error::CalibError::context("payload family", e))?[frame]) };
    let home = at(q)?;
    let last = model.joints.iter().position(|j| j.kind == JointType::Prismatic).unwrap_or(model.nq());
    let mut moved = Vec::new();
    for j in 0..model.nq() {
        let mut qs = q.to_vec();
        qs[j] += 1e-3;
        let p = at(&qs)?;
        // A real dependency moves it by about the step (1e-4 and up); a closed loop solved numerically
        // moves it by round-off (the rotation compared as matrices: an angle from a cosine near 1
        // carries 1e-8 of round-off).
        let moves = (p.translation.vector - home.translation.vector).norm() > 1e-9 || (p.rotation.matrix() - home.rotation.matrix()).norm() > 1e-9;
        match (moves, j) {
            (true, j) if j > last => return Ok(None),
            (true, j) if j < last && model.joints[j].kind == JointType::Revolute => moved.push(j),
            _ => {}
        }
    }
    Ok((!moved.is_empty()).then_some(moved))
}

/// The axis (unit, in the body's first frame) the body turns about when joint `joint` moves at
/// `q`, `None` where that joint does not turn it: a family's last joint's axis (the PSM's pitch)
/// through its pivot is the line a load's gravity on that joint acts about.
pub fn turning_axis(model: &Model, body: usize, joint: usize, q: &[f64]) -> Result<Option<[f64; 3]>> {
    let frame = model.bodies[body].frames[0];
    let at = |q: &[f64]| -> Result<Pose> { Ok(model.fk(q).map_err(|e| crate::error::CalibError::context("payload axis", e))?[frame]) };
    let mut moved = q.to_vec();
    moved[joint] += 1e-3;
    let turn = at(q)?.rotation.inverse() * at(&moved)?.rotation;
    Ok(turn.axis().filter(|_| turn.angle() > 1e-6).map(|a| [a.x, a.y, a.z]))
}

/// The crank radius (m) of a body that only translates against the arm's first moving body
/// (its orientation there stays within 1 urad over the sampled configurations whose frame poses
/// are `frames`, [`sampled_frames`]; its origin moves): the radius of the circle its origin
/// follows in that body's frame. `None` for a body that turns, or that does not move against it.
pub fn crank(model: &Model, body: usize, frames: &[Vec<Pose>]) -> Option<f64> {
    let first = model.frames.iter().position(|f| f.is_moving())?;
    let reference = model.frames[first].body;
    if reference == body || frames.is_empty() {
        return None;
    }
    let (fr, fb) = (model.bodies[reference].frames[0], model.bodies[body].frames[0]);
    let rel: Vec<Pose> = frames.iter().map(|f| f[fr].inverse() * f[fb]).collect();
    let r0 = rel[0].rotation;
    if rel.iter().any(|p| (r0.inverse() * p.rotation).angle() > 1e-6) {
        return None;
    }
    let pts: Vec<Vector3<f64>> = rel.iter().map(|p| p.translation.vector).collect();
    let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let cov = pts.iter().fold(Matrix3::zeros(), |c, p| c + (p - mean) * (p - mean).transpose()) / pts.len() as f64;
    let eig = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|a, b| eig.eigenvalues[*b].total_cmp(&eig.eigenvalues[*a]));
    if eig.eigenvalues[order[0]].sqrt() < 1e-4 {
        return None;
    }
    // The circle in the plane of the motion (Kasa's algebraic fit: |x|^2 = 2 c.x + k).
    let (u, v) = (eig.eigenvectors.column(order[0]).into_owned(), eig.eigenvectors.column(order[1]).into_owned());
    let mut a = nalgebra::DMatrix::zeros(pts.len(), 3);
    let mut b = nalgebra::DVector::zeros(pts.len());
    for (i, p) in pts.iter().enumerate() {
        let (x, y) = ((p - mean).dot(&u), (p - mean).dot(&v));
        a[(i, 0)] = 2.0 * x;
        a[(i, 1)] = 2.0 * y;
        a[(i, 2)] = 1.0;
        b[i] = x * x + y * y;
    }
    let s = a.svd(true, true).solve(&b, 1e-12).ok()?;
    let r2 = s[2] + s[0] * s[0] + s[1] * s[1];
    (r2 > 0.0).then(|| r2.sqrt())
}

/// A gravity-equivalent placement ([`gravity_equivalent`]): mass (kg), place (m, the body's
/// first frame), and how much of the named load's gravity it leaves unmatched (relative RMS).
#[derive(Debug, Clone, Copy)]
pub struct Equivalent {
    pub mass: f64,
    pub place: [f64; 3],
    pub mismatch: f64,
}

/// The poses of every frame at up to 400 of the recorded configurations `q` (evenly strided):
/// what [`gravity_equivalent`] matches over, taken once for all of a family's bodies.
pub fn sampled_frames(model: &Model, q: &[Vec<f64>]) -> Result<Vec<Vec<Pose>>> {
    let stride = (q.len() / 400).max(1);
    q.iter().step_by(stride).map(|qi| model.fk(qi).map_err(|e| crate::error::CalibError::context("payload equivalent", e))).collect()
}

/// Where on `body` a load loads the joints through gravity as `mass` (kg) at `place` (m, in
/// `named`'s first frame) does over the configurations whose frame poses are `frames`
/// ([`sampled_frames`]; `gravity`: m/s^2, base frame): the load's potential energy
/// `m g.t(q) + g.R(q) h` matched up to a constant by least squares in the mass and the first
/// moment `k` about `near` (m, `body`'s frame; its pivot). What gravity leaves free keeps the
/// named load's values: the same mass, where the body turns about `near`, and no first moment
/// about it, where it only translates. `None` without a positive mass.
#[allow(clippy::too_many_arguments)]
pub fn gravity_equivalent(model: &Model, gravity: &Vector3<f64>, named: usize, mass: f64, place: [f64; 3], body: usize, near: [f64; 3], frames: &[Vec<Pose>]) -> Option<Equivalent> {
    let (fa, fb) = (model.bodies[named].frames[0], model.bodies[body].frames[0]);
    let (p, c) = (Vector3::from(place), Vector3::from(near));
    let (mut rows, mut y) = (Vec::with_capacity(frames.len()), Vec::with_capacity(frames.len()));
    for f in frames {
        let (a, b) = (&f[fa], &f[fb]);
        y.push(mass * gravity.dot(&(a * nalgebra::Point3::from(p)).coords));
        // Unknowns (m, k): the point mass m at near + k / m, its potential g.(t + R (m near + k)).
        let gr = b.rotation.inverse() * gravity;
        rows.push([gravity.dot(&(b * nalgebra::Point3::from(c)).coords), gr.x, gr.y, gr.z]);
    }
    let n = y.len();
    if n < 3 {
        return None;
    }
    // The constant dropped by centring; the named load's own values subtracted, so that the
    // least-squares minimum norm keeps them where gravity does not decide.
    let u0 = [mass, 0.0, 0.0, 0.0];
    let mean = |v: &dyn Fn(usize) -> f64| (0..n).map(v).sum::<f64>() / n as f64;
    let ym = mean(&|i| y[i] - (0..4).map(|k| rows[i][k] * u0[k]).sum::<f64>());
    let cm: [f64; 4] = std::array::from_fn(|k| mean(&|i| rows[i][k]));
    let mut a = nalgebra::DMatrix::zeros(n, 4);
    let mut r = nalgebra::DVector::zeros(n);
    for i in 0..n {
        for k in 0..4 {
            a[(i, k)] = rows[i][k] - cm[k];
        }
        r[i] = y[i] - (0..4).map(|k| rows[i][k] * u0[k]).sum::<f64>() - ym;
    }
    let target = nalgebra::DVector::from_fn(n, |i, _| y[i]);
    let spread = (target.add_scalar(-target.mean())).norm();
    if spread <= 0.0 {
        return None;
    }
    // Unit columns; one gravity does not see at all (the mass of a body turning about `near`:
    // its potential is constant) is dropped, not scaled up from round-off.
    let norms: Vec<f64> = (0..4).map(|k| a.column(k).norm()).collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    let scale: Vec<f64> = norms.iter().map(|&v| if v > 1e-9 * largest { 1.0 / v } else { 0.0 }).collect();
    for k in 0..4 {
        a.column_mut(k).scale_mut(scale[k]);
    }
    let d = a.clone().svd(true, true).solve(&r, 1e-6).ok()?;
    let mismatch = (&a * &d - &r).norm() / spread;
    let u: [f64; 4] = std::array::from_fn(|k| u0[k] + d[k] * scale[k]);
    if u[0] <= 0.0 {
        return None;
    }
    let at = c + Vector3::new(u[1], u[2], u[3]) / u[0];
    Some(Equivalent { mass: u[0], place: [at.x, at.y, at.z], mismatch })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PSM's pitch linkage is one family (yaw and pitch), the yaw link and the tool are not
    /// in it; the parallelogram's bottom link translates on its crank, frame 6's a = 0.150 m
    /// (Table 4), and `pitch_end` turns.
    #[test]
    fn the_psms_pitch_linkage_is_one_family_and_its_bottom_link_translates_on_its_crank() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let home = model.home();
        let body = |frame: &str| model.frames[model.frames.iter().position(|f| f.name == frame).unwrap()].body;
        let fam = |frame: &str| family(&model, body(frame), &home).unwrap();
        for f in ["pitch_back", "pitch_bottom", "pitch_end", "main_insertion", "counterweight"] {
            assert_eq!(fam(f), Some(vec![0, 1]), "{f}");
        }
        assert_eq!(fam("yaw"), Some(vec![0]));
        assert_eq!(fam("tool_roll"), None);
        let q: Vec<Vec<f64>> = (0..50).map(|i| { let mut q = home.clone(); q[0] = 0.3 * (0.1 * i as f64).sin(); q[1] = 0.5 * (0.13 * i as f64).cos(); q[2] = 0.1 + 0.05 * (0.07 * i as f64).sin(); q }).collect();
        let frames = sampled_frames(&model, &q).unwrap();
        let r = crank(&model, body("pitch_bottom"), &frames).unwrap();
        assert!((r - 0.150).abs() < 1e-9, "{r}");
        assert_eq!(crank(&model, body("pitch_end"), &frames), None);
    }

    /// A load on the bottom link (which translates on its 0.150 m crank; at its frame's origin,
    /// on the yaw's axis: elsewhere its yaw load differs) has a gravity-equivalent
    /// placement on `pitch_end` (which turns about the remote centre) with the same mass and
    /// the crank's first moment about that centre, and back: the bottom link's placement for
    /// that load is the same mass again. The back link turns as `pitch_end` does: the same
    /// mass at the same first moment. The yaw link carries none (mismatch near 1).
    #[test]
    fn a_load_on_the_pitch_linkage_has_a_gravity_equivalent_on_each_of_its_bodies() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let home = model.home();
        let body = |frame: &str| model.frames[model.frames.iter().position(|f| f.name == frame).unwrap()].body;
        let q: Vec<Vec<f64>> = (0..200).map(|i| { let mut q = home.clone(); q[0] = 0.4 * (0.1 * i as f64).sin(); q[1] = 0.5 * (0.13 * i as f64).cos(); q[2] = 0.1 + 0.05 * (0.07 * i as f64).sin(); q }).collect();
        let g = Vector3::new(0.0, 0.0, -9.81);
        let frames = sampled_frames(&model, &q).unwrap();
        let rcm = crate::discrepancy::payload::pivot(&model, body("pitch_end"), &frames).0;
        let on_end = gravity_equivalent(&model, &g, body("pitch_bottom"), 0.2, [0.0; 3], body("pitch_end"), rcm, &frames).unwrap();
        let moment = on_end.mass * (Vector3::from(on_end.place) - Vector3::from(rcm)).norm();
        assert!(on_end.mismatch < 1e-6 && (on_end.mass - 0.2).abs() < 1e-9 && (moment - 0.2 * 0.150).abs() < 1e-6, "{on_end:?} {moment}");
        let back = gravity_equivalent(&model, &g, body("pitch_end"), 0.2, on_end.place, body("pitch_bottom"), [0.0; 3], &frames).unwrap();
        assert!(back.mismatch < 1e-6 && (back.mass - 0.2).abs() < 1e-6, "{back:?}");
        let pivot = crate::discrepancy::payload::pivot(&model, body("pitch_back"), &frames).0;
        let on_back = gravity_equivalent(&model, &g, body("pitch_end"), 0.2, on_end.place, body("pitch_back"), pivot, &frames).unwrap();
        let back_moment = on_back.mass * (Vector3::from(on_back.place) - Vector3::from(pivot)).norm();
        assert!(on_back.mismatch < 1e-6 && (back_moment - moment).abs() < 1e-9, "{on_back:?}");
        let yaw = gravity_equivalent(&model, &g, body("pitch_end"), 0.2, on_end.place, body("yaw"), [0.0; 3], &frames);
        assert!(yaw.is_none_or(|e| e.mismatch > 0.5), "{yaw:?}");
    }
}
