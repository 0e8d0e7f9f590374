//! Raw markers to a rigid-body pose: the least-squares rotation and translation (Kabsch / Horn)
//! that carries a cluster's layout onto the observed markers, with the per-frame residual; and a
//! whole marker track to a pose track, dropping occluded and outlier frames with counts.

use crate::recording::error::{RecordingError, Result};
use crate::recording::tracks::{BodyTrack, MarkerTrack, Recording};
use dvrk_kin::Pose;
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};

/// Fewest markers that fix a pose (two leave the rotation about their line free).
pub const MIN_MARKERS: usize = 3;

/// Outlier frames: RMS residual above this many times the track's median residual.
pub const OUTLIER_FACTOR: f64 = 5.0;

/// Residuals below this (m) are never outliers: a noise-free recording has a median of ~1e-16 m.
pub const OUTLIER_FLOOR: f64 = 2e-5;

/// Least-squares pose `T` with `T * layout[k] ~ observed[k]` over the pairs present (both
/// `Some`), and the RMS residual (m). `None` with fewer than [`MIN_MARKERS`] pairs or markers
/// in a line. No heap allocation: it runs once per frame per cluster.
pub fn fit_pose(layout: &[Vector3<f64>], observed: &[Option<Vector3<f64>>]) -> Option<(Pose, f64)> {
    let mut n = 0usize;
    let mut cl = Vector3::zeros();
    let mut co = Vector3::zeros();
    for (c, o) in layout.iter().zip(observed) {
        if let Some(o) = o {
            n += 1;
            cl += c;
            co += o;
        }
    }
    if n < MIN_MARKERS {
        return None;
    }
    cl /= n as f64;
    co /= n as f64;
    let mut h = Matrix3::zeros();
    let mut spread = 0.0;
    for (c, o) in layout.iter().zip(observed) {
        if let Some(o) = o {
            let a = c - cl;
            spread += a.norm_squared();
            h += a * (o - co).transpose();
        }
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut s = svd.singular_values;
    s.as_mut_slice().sort_by(|a, b| b.total_cmp(a));
    // Collinear markers: the second singular value vanishes and the rotation about the line is
    // free. Written so that a NaN singular value also refuses the pose.
    if s[1].partial_cmp(&(1e-9 * spread.max(1e-30))) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rot = Rotation3::from_matrix_unchecked(r);
    let p = co - rot * cl;
    let mut ss = 0.0;
    for (c, o) in layout.iter().zip(observed) {
        if let Some(o) = o {
            ss += (rot * c + p - o).norm_squared();
        }
    }
    Some((Pose::from_parts(Translation3::from(p), rot), (ss / n as f64).sqrt()))
}

/// A cluster's layout from a marker track: the first frame with every marker visible, centred,
/// then refined once by averaging every complete frame in the fitted body frame (so one noisy
/// frame does not define the body). Body axes are the tracker's at that first frame; the origin
/// is the marker centroid.
pub fn estimate_layout(track: &MarkerTrack) -> Result<Vec<Vector3<f64>>> {
    let k = track.markers();
    let what = || format!("rigid body `{}`", track.body);
    if k < MIN_MARKERS {
        return Err(RecordingError::data(what(), format!("has {k} marker(s); a pose needs {MIN_MARKERS} or more")));
    }
    let n = track.t.len();
    let complete = |i: usize| (0..k).all(|m| track.get(i, m).is_some());
    let first = (0..n).find(|&i| complete(i)).ok_or_else(|| {
        RecordingError::data(what(), format!("no frame of {n} shows all {k} markers, so the cluster layout is unknown"))
    })?;
    let pts: Vec<Vector3<f64>> = (0..k).map(|m| track.get(first, m).unwrap_or_default()).collect();
    let c = pts.iter().sum::<Vector3<f64>>() / k as f64;
    let mut layout: Vec<Vector3<f64>> = pts.iter().map(|p| p - c).collect();
    let mut obs = vec![None; k];
    let mut sum = vec![Vector3::zeros(); k];
    let mut count = 0usize;
    for i in (0..n).filter(|&i| complete(i)) {
        for (m, o) in obs.iter_mut().enumerate() {
            *o = track.get(i, m);
        }
        if let Some((pose, _)) = fit_pose(&layout, &obs) {
            for (s, o) in sum.iter_mut().zip(&obs) {
                *s += pose.inverse_transform_vector(&(o.unwrap_or_default() - pose.translation.vector));
            }
            count += 1;
        }
    }
    if count == 0 {
        return Err(RecordingError::data(what(), "its markers lie on a line in every frame; a pose needs three not in a line"));
    }
    let mean: Vec<Vector3<f64>> = sum.iter().map(|s| s / count as f64).collect();
    let c = mean.iter().sum::<Vector3<f64>>() / k as f64;
    layout = mean.iter().map(|p| p - c).collect();
    Ok(layout)
}

/// Poses of a cluster from its raw markers. `layout` is the cluster in its body frame (m; from
/// the rigid-body definition, or [`estimate_layout`] when `None`). Frames with fewer than three
/// visible markers count as occluded; frames whose RMS residual exceeds
/// `OUTLIER_FACTOR x median` (and `OUTLIER_FLOOR`) count as outliers; both are left out.
pub fn poses_from_markers(track: &MarkerTrack, layout: Option<&[Vector3<f64>]>) -> Result<BodyTrack> {
    let k = track.markers();
    let what = || format!("rigid body `{}`", track.body);
    let owned;
    let layout = match layout {
        Some(l) => {
            if l.len() != k {
                return Err(RecordingError::data(
                    what(),
                    format!("the recording has {k} markers for it, its definition has {}", l.len()),
                ));
            }
            l
        }
        None => {
            owned = estimate_layout(track)?;
            &owned
        }
    };
    let mut out = BodyTrack::new(track.body.clone(), "");
    let mut obs = vec![None; k];
    for i in 0..track.t.len() {
        for (m, o) in obs.iter_mut().enumerate() {
            *o = track.get(i, m);
        }
        match fit_pose(layout, &obs) {
            Some((pose, rms)) => {
                out.t.push(track.t[i]);
                out.poses.push(pose);
                out.residual.push(rms);
            }
            None => out.occluded += 1,
        }
    }
    drop_outliers(&mut out);
    Ok(out)
}

/// Remove samples whose marker residual is far above the track's median; returns how many.
pub fn drop_outliers(track: &mut BodyTrack) -> usize {
    if track.residual.len() != track.poses.len() || track.residual.is_empty() {
        return 0;
    }
    let mut r = track.residual.clone();
    let mid = r.len() / 2;
    let median = *r.select_nth_unstable_by(mid, f64::total_cmp).1;
    let limit = (OUTLIER_FACTOR * median).max(OUTLIER_FLOOR);
    let keep: Vec<bool> = track.residual.iter().map(|x| *x <= limit).collect();
    let dropped = keep.iter().filter(|k| !**k).count();
    if dropped > 0 {
        let mut it = keep.iter();
        track.t.retain(|_| *it.next().unwrap_or(&true));
        let mut it = keep.iter();
        track.poses.retain(|_| *it.next().unwrap_or(&true));
        let mut it = keep.iter();
        track.residual.retain(|_| *it.next().unwrap_or(&true));
        track.outliers += dropped;
    }
    dropped
}

impl Recording {
    /// The poses of a rigid body: its pose track, or (when it has none, or `from_markers` is set
    /// and it has raw markers) poses fitted to its raw markers with `layout` (estimated when
    /// `None`), occluded and outlier frames left out and counted.
    pub fn poses(&self, name: &str, layout: Option<&[Vector3<f64>]>, from_markers: bool) -> Result<std::borrow::Cow<'_, BodyTrack>> {
        let markers = self.marker_track(name);
        if let (true, Some(m)) = (from_markers, markers) {
            return Ok(std::borrow::Cow::Owned(poses_from_markers(m, layout)?));
        }
        match self.body(name) {
            Ok(b) => Ok(std::borrow::Cow::Borrowed(b)),
            Err(e) => match markers {
                Some(m) => Ok(std::borrow::Cow::Owned(poses_from_markers(m, layout)?)),
                None => {
                    if self.bodies.is_empty() && !self.markers.is_empty() {
                        return Err(RecordingError::unknown("rigid body", name, self.markers.iter().map(|m| m.body.clone())));
                    }
                    Err(e)
                }
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout() -> Vec<Vector3<f64>> {
        let pts = [Vector3::new(0.03, 0.0, 0.0), Vector3::new(-0.012, 0.027, 0.004), Vector3::new(-0.015, -0.02, -0.003)];
        let c = pts.iter().sum::<Vector3<f64>>() / 3.0;
        pts.iter().map(|p| p - c).collect()
    }

    #[test]
    fn exact_markers_give_the_pose_back() {
        let truth = Pose::from_parts(
            Translation3::new(0.4, -1.2, 2.0),
            Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(Vector3::new(0.3, -1.0, 0.5)), 2.5),
        );
        let l = layout();
        let obs: Vec<Option<Vector3<f64>>> = l.iter().map(|c| Some(truth * nalgebra::Point3::from(*c)).map(|p| p.coords)).collect();
        let (pose, rms) = fit_pose(&l, &obs).unwrap();
        assert!((pose.to_homogeneous() - truth.to_homogeneous()).abs().max() < 1e-12);
        assert!(rms < 1e-12);
        // Two markers do not fix a pose.
        let two = [obs[0], obs[1], None];
        assert!(fit_pose(&l, &two).is_none());
    }

    #[test]
    fn a_displaced_marker_leaves_the_closed_form_residual() {
        // A planar triangle (centred), marker 0 pushed radially by e. In the plane, the rigid
        // motions tx, ty and the turn about the normal are orthogonal (sum c = 0); the push
        // projects e/sqrt(3) onto each translation along it and nothing onto the turn, so the
        // squared residual left is e^2 (1 - 1/3) over 3 markers: RMS = e sqrt(2/9).
        let pts = [Vector3::new(0.03, 0.0, 0.0), Vector3::new(-0.012, 0.027, 0.0), Vector3::new(-0.015, -0.02, 0.0)];
        let c = pts.iter().sum::<Vector3<f64>>() / 3.0;
        let l: Vec<Vector3<f64>> = pts.iter().map(|p| p - c).collect();
        let e = 1e-6;
        let mut obs: Vec<Option<Vector3<f64>>> = l.iter().map(|c| Some(*c)).collect();
        obs[0] = Some(l[0] + l[0].normalize() * e);
        let (_, rms) = fit_pose(&l, &obs).unwrap();
        let expected = e * (2.0f64 / 9.0).sqrt();
        assert!((rms / expected - 1.0).abs() < 1e-4, "{rms} vs {expected}");
        // Pushed along the normal instead, three markers always fit a plane: no residual to
        // first order (the tracker cannot see it; only the pivot and axis residuals can).
        obs[0] = Some(l[0] + Vector3::z() * e);
        let (_, rms) = fit_pose(&l, &obs).unwrap();
        assert!(rms < 1e-9, "{rms}");
    }
}