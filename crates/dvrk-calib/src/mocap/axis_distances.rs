//! The paper's axis-distance step (section 2.4, Table 6): every configured axis fitted, the axes
//! carried into the tracker frame at joint zero (the paper's `g^c`, `h^c`), projected onto the
//! plane normal to their mean direction, and the pairwise distances.
//!
//! A distance between two axes that are fixed in the same link (every Table 6 pair is) is
//! computed in that link's cluster frame, where both axes were fitted over the whole recording;
//! going through the tracker frame would add the noise of the one pose at joint zero (a few
//! tenths of a millimetre for a three-marker cluster). Other pairs use the tracker frame.

use crate::mocap::axes_config::{AxesConfig, TRACKER};
use crate::mocap::axis_fit::{fit_axis, AxisFit, AxisMethod, AxisOptions};
use crate::error::{CalibError, Result};
use dvrk_sim::recording::{common_samples, BodyTrack, Recording};
use dvrk_kin::Pose;
use nalgebra::{Matrix3, Vector3};

/// Options of [`calibrate_axes`] that the command line may set.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AxesOptions {
    /// Overrides the configuration's method.
    pub method: Option<AxisMethod>,
    /// Fit poses from raw markers even where the recording has rigid-body poses.
    pub from_markers: bool,
}

/// One fitted axis.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisResult {
    pub name: String,
    pub reference: String,
    pub moving: String,
    pub fit: AxisFit,
    /// The axis point in the tracker frame at the reference instant (m).
    pub point_tracker: Option<Vector3<f64>>,
    /// The axis direction in the tracker frame at the reference instant (sign: along the mean).
    pub direction_tracker: Option<Vector3<f64>>,
    /// Covariance of `point_tracker` normal to the axis (m^2), rotated with the reference pose.
    pub cov_tracker: Option<Matrix3<f64>>,
    /// `point_tracker` projected onto the plane normal to the mean direction (the paper's `g^h`).
    pub in_plane: Option<Vector3<f64>>,
}

/// A distance between two parallel axes, normal to them.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisDistance {
    pub a: String,
    pub b: String,
    /// m
    pub distance: f64,
    /// Standard deviation (m), from the two axes' point covariances.
    pub std: f64,
    /// The body whose frame it was computed in, or `tracker`.
    pub frame: String,
}

/// A line in some frame: point, unit direction, covariance of the point normal to it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Line {
    pub point: Vector3<f64>,
    pub direction: Vector3<f64>,
    pub cov: Matrix3<f64>,
}

/// Every axis and distance of one recording.
#[derive(Debug, Clone, PartialEq)]
pub struct AxesReport {
    pub source: String,
    pub method: AxisMethod,
    pub axes: Vec<AxisResult>,
    /// The instant the tracker-frame axes are given at (s), when the reference bodies have one.
    pub reference_time: Option<f64>,
    /// The joint values at that instant, when joint states were recorded.
    pub reference_q: Option<Vec<f64>>,
    /// Mean axis direction in the tracker frame (the plane normal `m`).
    pub plane_normal: Option<Vector3<f64>>,
    pub distances: Vec<AxisDistance>,
    pub warnings: Vec<String>,
}

impl AxesReport {
    /// The axis named `name`.
    pub fn axis(&self, name: &str) -> Option<&AxisResult> {
        self.axes.iter().find(|a| a.name == name)
    }
    /// Axis `name` as a line in the frame of `body` (it must be one of its two bodies).
    pub fn line_in(&self, name: &str, body: &str) -> Option<Line> {
        let a = self.axis(name)?;
        if a.reference == body {
            Some(Line { point: a.fit.point, direction: a.fit.direction, cov: a.fit.point_cov })
        } else if a.moving == body {
            Some(Line { point: a.fit.point_moving, direction: a.fit.direction_moving, cov: a.fit.point_moving_cov })
        } else {
            None
        }
    }
    /// A body both axes are fixed in (reference or moving side of each), if any.
    pub fn shared_body(&self, a: &str, b: &str) -> Option<String> {
        let (x, y) = (self.axis(a)?, self.axis(b)?);
        [&x.reference, &x.moving].into_iter().find(|s| *s == &y.reference || *s == &y.moving).cloned()
    }
    /// The distance between axes `a` and `b` (either order).
    pub fn distance(&self, a: &str, b: &str) -> Option<&AxisDistance> {
        self.distances.iter().find(|d| (d.a == a && d.b == b) || (d.a == b && d.b == a))
    }
}

/// Distance between two nearly parallel lines normal to their mean direction, with its
/// standard deviation from the point covariances.
pub fn line_distance(l1: &Line, l2: &Line) -> (f64, f64) {
    let s = l1.direction.dot(&l2.direction).signum();
    let m = (l1.direction + l2.direction * s).normalize();
    let d = l1.point - l2.point;
    let d = d - m * m.dot(&d);
    let dist = d.norm();
    let u = if dist > 0.0 { d / dist } else { Vector3::zeros() };
    (dist, (u.transpose() * (l1.cov + l2.cov) * u)[(0, 0)].max(0.0).sqrt())
}

/// Fit every axis of `cfg` in `rec` and compute the Table 6 step.
pub fn calibrate_axes(rec: &Recording, cfg: &AxesConfig, options: &AxesOptions) -> Result<AxesReport> {
    let method = match options.method {
        Some(m) => m,
        None => cfg.method()?,
    };
    let layout = |body: &str| -> Option<Vec<Vector3<f64>>> { cfg.body(body)?.markers.as_ref().map(|m| m.iter().map(|p| Vector3::from(*p)).collect()) };
    // Every body's poses, once (fitting raw markers can be the costly part).
    let mut names: Vec<&str> = Vec::new();
    for a in &cfg.axes {
        for b in [&a.reference, &a.moving] {
            if b != TRACKER && !names.contains(&b.as_str()) {
                names.push(b);
            }
        }
    }
    let mut tracks: Vec<(String, std::borrow::Cow<'_, BodyTrack>)> = Vec::new();
    let mut warnings = rec.warnings.clone();
    for name in &names {
        let l = layout(name);
        let track = rec.poses(cfg.recording_name(name), l.as_deref(), options.from_markers).map_err(|e| match e {
            dvrk_sim::recording::RecordingError::Data { what, message } => CalibError::data(format!("body `{name}` ({what})"), message),
            e => e.into(),
        })?;
        if track.occluded > 0 || track.outliers > 0 {
            warnings.push(format!(
                "body `{name}`: {} occluded and {} outlier frame(s) dropped, {} used",
                track.occluded,
                track.outliers,
                track.len()
            ));
        }
        tracks.push((name.to_string(), track));
    }
    let track = |name: &str| tracks.iter().find(|(n, _)| n == name).map(|(_, t)| t.as_ref());
    let mut axes = Vec::new();
    for a in &cfg.axes {
        let what = format!("axis {} ({} / {})", a.name, a.reference, a.moving);
        let moving = track(&a.moving).ok_or_else(|| CalibError::data(&what, "moving body has no poses"))?;
        let (ref_poses, mov_poses): (Vec<Pose>, Vec<Pose>) = if a.reference == TRACKER {
            (vec![Pose::identity(); moving.len()], moving.poses.clone())
        } else {
            let reference = track(&a.reference).ok_or_else(|| CalibError::data(&what, "reference body has no poses"))?;
            common_samples(&[reference, moving]).iter().map(|ix| (reference.poses[ix[0]], moving.poses[ix[1]])).unzip()
        };
        let opts = AxisOptions { method, points: layout(&a.moving), ..Default::default() };
        let fit = fit_axis(&ref_poses, &mov_poses, &opts, &what)?;
        warnings.extend(fit.warnings.iter().cloned());
        axes.push(AxisResult {
            name: a.name.clone(),
            reference: a.reference.clone(),
            moving: a.moving.clone(),
            fit,
            point_tracker: None,
            direction_tracker: None,
            cov_tracker: None,
            in_plane: None,
        });
    }
    let mut report = AxesReport {
        source: rec.source.clone(),
        method,
        axes,
        reference_time: None,
        reference_q: None,
        plane_normal: None,
        distances: Vec::new(),
        warnings,
    };
    // The reference instant: one sample at which every reference body is seen.
    let ref_names: Vec<&str> = {
        let mut v: Vec<&str> = cfg.axes.iter().map(|a| a.reference.as_str()).filter(|r| *r != TRACKER).collect();
        v.sort();
        v.dedup();
        v
    };
    let ref_tracks: Vec<&BodyTrack> = ref_names.iter().filter_map(|n| track(n)).collect();
    let candidates: Vec<Vec<usize>> = if ref_tracks.is_empty() {
        (0..tracks.first().map_or(0, |t| t.1.len())).map(|i| vec![i]).collect()
    } else {
        common_samples(&ref_tracks)
    };
    let time_of = |c: &[usize]| -> f64 { ref_tracks.first().map_or_else(|| tracks[0].1.t[c[0]], |t| t.t[c[0]]) };
    let joint_at = |t: f64| -> Option<Vec<f64>> {
        let j = rec.joints.as_ref()?;
        let i = j.t.partition_point(|x| *x < t);
        let best = [i.saturating_sub(1), i.min(j.t.len().saturating_sub(1))].into_iter().min_by(|&a, &b| (j.t[a] - t).abs().total_cmp(&(j.t[b] - t).abs()))?;
        j.q.get(best).cloned()
    };
    let chosen = if let Some(t) = cfg.reference_time {
        candidates.iter().min_by(|a, b| (time_of(a) - t).abs().total_cmp(&(time_of(b) - t).abs()))
    } else if rec.joints.is_some() {
        candidates.iter().min_by(|a, b| {
            let score = |c: &[usize]| joint_at(time_of(c)).map_or(f64::INFINITY, |q| q.iter().take(2).map(|x| x * x).sum::<f64>());
            score(a).total_cmp(&score(b))
        })
    } else {
        candidates.first()
    };
    if let Some(c) = chosen {
        let t0 = time_of(c);
        report.reference_time = Some(t0);
        report.reference_q = joint_at(t0);
        let pose_of = |name: &str| -> Option<Pose> {
            if name == TRACKER {
                return Some(Pose::identity());
            }
            let k = ref_names.iter().position(|n| *n == name)?;
            let tr = ref_tracks.get(k)?;
            Some(tr.poses[c[k]])
        };
        for a in report.axes.iter_mut() {
            if let Some(p) = pose_of(&a.reference) {
                a.point_tracker = Some(p.transform_point(&a.fit.point.into()).coords);
                a.direction_tracker = Some(p.transform_vector(&a.fit.direction));
                let r = p.rotation.matrix();
                a.cov_tracker = Some(r * a.fit.point_cov * r.transpose());
            }
        }
        let dirs: Vec<Vector3<f64>> = report.axes.iter().filter_map(|a| a.direction_tracker).collect();
        if let Some(first) = dirs.first() {
            let m = dirs.iter().fold(Vector3::zeros(), |acc, d| acc + d * d.dot(first).signum()).normalize();
            report.plane_normal = Some(m);
            for a in report.axes.iter_mut() {
                if let (Some(d), Some(g)) = (a.direction_tracker, a.point_tracker) {
                    a.direction_tracker = Some(d * d.dot(&m).signum());
                    a.in_plane = Some(g - m * m.dot(&g));
                }
            }
        }
    } else if !ref_tracks.is_empty() {
        report.warnings.push(format!(
            "no sample shows every reference body ({}) at once: the axes are not given in the tracker frame",
            ref_names.join(", ")
        ));
    }
    // Distances: in a shared body's frame when there is one, else in the tracker frame.
    let n = report.axes.len();
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (report.axes[i].name.clone(), report.axes[j].name.clone());
            let found = match report.shared_body(&a, &b) {
                Some(body) => match (report.line_in(&a, &body), report.line_in(&b, &body)) {
                    (Some(l1), Some(l2)) => Some((line_distance(&l1, &l2), body)),
                    _ => None,
                },
                None => tracker_line(&report, i).zip(tracker_line(&report, j)).map(|(l1, l2)| (line_distance(&l1, &l2), TRACKER.to_string())),
            };
            if let Some(((distance, std), frame)) = found {
                report.distances.push(AxisDistance { a, b, distance, std, frame });
            }
        }
    }
    Ok(report)
}

/// Axis `i` as a line in the tracker frame at the reference instant.
fn tracker_line(report: &AxesReport, i: usize) -> Option<Line> {
    let a = &report.axes[i];
    Some(Line { point: a.point_tracker?, direction: a.direction_tracker?, cov: a.cov_tracker? })
}
