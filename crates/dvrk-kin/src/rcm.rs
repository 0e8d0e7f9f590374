//! The remote centre of motion (RCM): the fixed point an insertion axis always passes through.

use crate::fk::{compute_frame_placements, Data};
use crate::model::{sample_configurations, Model, Pose};
use nalgebra::{Matrix3, Vector3};

/// Least-squares point closest to the z axes of `frame` over spread configurations
/// (minimises the sum of squared distances to the lines), in the model's base frame (m).
pub(crate) fn locate_rcm(model: &Model, frame: usize) -> Vector3<f64> {
    let mut data = Data::new(model);
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for q in sample_configurations(&model.joints, 24) {
        compute_frame_placements(model, &mut data, &q);
        let p = model.base.inverse() * data.frames[frame];
        let z = p.rotation.matrix().column(2).into_owned();
        let proj = Matrix3::identity() - z * z.transpose();
        a += proj;
        b += proj * p.translation.vector;
    }
    a.try_inverse().map(|inv| inv * b).unwrap_or_else(|| Vector3::repeat(f64::NAN))
}

/// Distance (m) from `point` (world) to the z axis of `pose`.
pub fn distance_to_axis(pose: &Pose, point: &Vector3<f64>) -> f64 {
    let z = pose.rotation.matrix().column(2);
    let v = point - pose.translation.vector;
    (v - z * z.dot(&v)).norm()
}

/// Distance (m) between the model's RCM and its insertion axis for the placements in `data`
/// (the pivot residual); `None` for a model without an RCM.
pub fn pivot_residual(model: &Model, data: &Data) -> Option<f64> {
    let rcm = model.rcm.as_ref()?;
    Some(distance_to_axis(&data.frames[rcm.frame], &(model.base * nalgebra::Point3::from(rcm.point)).coords))
}

/// Largest pivot residual (m) over `count` spread configurations.
pub fn max_pivot_residual(model: &Model, count: usize) -> Option<f64> {
    model.rcm.as_ref()?;
    let mut data = Data::new(model);
    let mut worst: f64 = 0.0;
    for q in sample_configurations(&model.joints, count) {
        compute_frame_placements(model, &mut data, &q);
        worst = worst.max(pivot_residual(model, &data)?);
    }
    Some(worst)
}
