//! A synthetic motion-capture tracker: three-marker rigid bodies on the PSM links of the paper's
//! Figure 5, seen from a tracker frame the fits do not know, with Gaussian marker noise,
//! occlusions and (optionally) ghost-marker outliers. It records what a real tracker would: the
//! raw markers, the rigid-body poses its own least-squares fit makes of them, and the robot's
//! joint states (`measured_js`).
//!
//! The kinematics are computed once per [`Scenario`]; [`Scenario::record`] then draws noise, so
//! Monte Carlo trials cost one marker fit per body and sample.

use crate::error::{CalibError, Result};
use dvrk_sim::recording::{BodyTrack, JointTrack, MarkerTrack, Recording};
use dvrk_sim::recording::{drop_outliers, fit_pose};
use dvrk_kin::{compute_frame_placements, Data, FrameRef, Model, Pose};
use nalgebra::{Point3, Rotation3, Translation3, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, UnitSphere};

/// The joint motion the robot makes during the recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SynthMotion {
    /// q1 and q2 in a Lissajous sweep (periods 10 s and 6.18 s): the pivot motion of section 4.1.
    Q1Q2Sweep,
    /// q2 alone, sinusoidal with a 10 s period, q1 = 0: the axis motion of section 2.4.
    Q2Sweep,
}

impl SynthMotion {
    /// The name used on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            SynthMotion::Q1Q2Sweep => "q1q2-sweep",
            SynthMotion::Q2Sweep => "q2-sweep",
        }
    }
}

impl std::str::FromStr for SynthMotion {
    type Err = CalibError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "q1q2-sweep" => Ok(SynthMotion::Q1Q2Sweep),
            "q2-sweep" => Ok(SynthMotion::Q2Sweep),
            _ => Err(CalibError::field("motion", format!("`{s}` is not a motion; valid: q1q2-sweep, q2-sweep"))),
        }
    }
}

/// Settings of a synthetic recording.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthOptions {
    pub motion: SynthMotion,
    /// Marker noise, standard deviation per coordinate (m).
    pub noise: f64,
    /// Frame rate (Hz).
    pub rate: f64,
    /// Length (s).
    pub duration: f64,
    /// Sweep amplitudes of q1 and q2 (rad).
    pub amplitude: [f64; 2],
    /// Probability that a marker is hidden in a frame (a body with fewer than three visible
    /// markers is lost for that frame).
    pub occlusion: f64,
    /// Probability that a body's frame has one marker displaced by 5 mm (a ghost or swap).
    pub outliers: f64,
    /// Seed of the noise, occlusions and outliers.
    pub seed: u64,
    /// The robot's base frame in the tracker frame (unknown to the fits).
    pub tracker_from_base: Pose,
}

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            motion: SynthMotion::Q1Q2Sweep,
            noise: 1e-4,
            rate: 120.0,
            duration: 20.0,
            amplitude: [0.6, 0.8],
            occlusion: 0.01,
            outliers: 0.0,
            seed: 1,
            tracker_from_base: default_tracker_from_base(),
        }
    }
}

/// A tracker 1.8 m away, turned on all three axes (any pose would do: the fits never see it).
pub fn default_tracker_from_base() -> Pose {
    Pose::from_parts(Translation3::new(0.35, -0.42, 1.83), Rotation3::from_euler_angles(0.41, -0.63, 2.17))
}

/// A rigid body of three markers on a link.
#[derive(Debug, Clone, PartialEq)]
pub struct Cluster {
    /// Rigid-body name (what the tracker calls it).
    pub name: String,
    /// The paper's frame number of the link it sits on.
    pub frame: i64,
    /// The link (body of the model).
    pub link: String,
    /// Cluster frame in the link frame (m); its origin is the marker centroid.
    pub offset: Pose,
    /// Markers in the cluster frame (m), centred.
    pub layout: Vec<Vector3<f64>>,
}

/// The clusters of Figure 5: one per moving link of the double parallelogram (frames 3, 4, 6,
/// 7, 8) and one on the yaw link (frame 2), which lets axes 3 and 4 be found while q1 moves.
/// Offsets keep the clusters off the joint axes and out of the mechanism's plane; the triangles
/// differ in size so a tracker can tell them apart.
pub fn figure5_clusters(model: &Model) -> Result<Vec<Cluster>> {
    let base = [Vector3::new(0.030, 0.0, 0.0), Vector3::new(-0.012, 0.027, 0.004), Vector3::new(-0.015, -0.020, -0.003)];
    let places: [(&str, i64, [f64; 3], [f64; 3]); 6] = [
        ("yaw", 2, [0.10, 0.06, 0.08], [0.2, 0.1, 0.0]),
        ("back", 3, [0.08, 0.02, 0.05], [0.0, 0.3, 0.2]),
        ("front", 4, [0.07, -0.02, 0.06], [0.1, 0.0, -0.3]),
        ("bottom", 6, [0.25, 0.03, 0.05], [-0.2, 0.1, 0.4]),
        ("top", 7, [0.25, -0.03, 0.07], [0.3, -0.2, 0.0]),
        ("end", 8, [0.06, 0.10, 0.04], [0.0, 0.2, -0.1]),
    ];
    let mut out = Vec::new();
    for (k, (name, frame, p, rpy)) in places.iter().enumerate() {
        let id = model.frame_id(&FrameRef::Index(*frame)).map_err(|e| CalibError::data(format!("model {}", model.name), format!("the Figure 5 clusters need frame {frame}: {e}")))?;
        let scale = 1.0 + 0.12 * k as f64;
        let pts: Vec<Vector3<f64>> = base.iter().map(|b| b * scale).collect();
        let c = pts.iter().sum::<Vector3<f64>>() / 3.0;
        out.push(Cluster {
            name: (*name).into(),
            frame: *frame,
            link: model.bodies[model.frames[id].body].name.clone(),
            offset: Pose::from_parts(Translation3::new(p[0], p[1], p[2]), Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2])),
            layout: pts.iter().map(|x| x - c).collect(),
        });
    }
    Ok(out)
}

/// The noise-free part of a synthetic recording: times, joint values and cluster poses.
#[derive(Debug, Clone)]
pub struct Scenario {
    pub options: SynthOptions,
    pub clusters: Vec<Cluster>,
    /// Joint names of the model.
    pub joint_names: Vec<String>,
    /// Sample times (s).
    pub t: Vec<f64>,
    /// Joint values per sample.
    pub q: Vec<Vec<f64>>,
    /// True cluster poses in the tracker frame: `clusters x samples`.
    pub poses: Vec<Vec<Pose>>,
    /// The model's RCM in the tracker frame (m), if it has one.
    pub rcm: Option<Vector3<f64>>,
}

impl Scenario {
    /// Compute the motion and the true cluster poses of `model` (a PSM layout).
    pub fn new(model: &Model, options: &SynthOptions) -> Result<Scenario> {
        for (field, v) in [("noise", options.noise), ("occlusion", options.occlusion), ("outliers", options.outliers)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CalibError::field(field, format!("{v} must be a finite number >= 0")));
            }
        }
        if options.occlusion >= 1.0 || options.outliers >= 1.0 {
            return Err(CalibError::field("occlusion", "occlusion and outlier rates must be below 1"));
        }
        if !(options.rate.is_finite() && options.rate > 0.0) {
            return Err(CalibError::field("rate", format!("{} Hz must be positive", options.rate)));
        }
        if !(options.duration.is_finite() && options.duration > 0.0) {
            return Err(CalibError::field("duration", format!("{} s must be positive", options.duration)));
        }
        // The product in f64: its cast to usize saturates (1e308 Hz read as 18446744073709551615).
        let samples = (options.duration * options.rate).round();
        if samples > 5e7 {
            return Err(CalibError::field(
                "duration",
                format!("{} s at {} Hz is {} samples, more than this tool writes (50 million)", dvrk_kin::fmt_number(options.duration), dvrk_kin::fmt_number(options.rate), dvrk_kin::fmt_number(samples)),
            ));
        }
        let n = samples as usize;
        let clusters = figure5_clusters(model)?;
        let ids: Vec<usize> = clusters.iter().map(|c| model.frame_id(&FrameRef::Index(c.frame))).collect::<std::result::Result<_, _>>()?;
        let (j1, j2) = (0usize, 1usize);
        if model.nq() < 2 {
            return Err(CalibError::data(format!("model {}", model.name), "the sweeps move joints 1 and 2; the model has fewer"));
        }
        for (k, a) in options.amplitude.iter().enumerate() {
            let j = &model.joints[k];
            if !(a.is_finite() && *a >= 0.0 && *a <= j.upper.min(-j.lower)) {
                return Err(CalibError::field(format!("amplitude[{k}]"), format!("{a} rad is outside joint {}'s limits [{}, {}]", j.name, j.lower, j.upper)));
            }
        }
        let mut data = Data::new(model);
        let home = model.home();
        let mut t = Vec::with_capacity(n);
        let mut qs = Vec::with_capacity(n);
        let mut poses = vec![Vec::with_capacity(n); clusters.len()];
        let tau = std::f64::consts::TAU;
        for i in 0..n {
            let ti = i as f64 / options.rate;
            let mut q = home.clone();
            match options.motion {
                SynthMotion::Q2Sweep => {
                    q[j1] = 0.0;
                    q[j2] = options.amplitude[1] * (tau * ti / 10.0).sin();
                }
                SynthMotion::Q1Q2Sweep => {
                    q[j1] = options.amplitude[0] * (tau * ti / 10.0).sin();
                    q[j2] = options.amplitude[1] * (tau * ti / 6.18).sin();
                }
            }
            compute_frame_placements(model, &mut data, &q);
            for ((c, id), out) in clusters.iter().zip(&ids).zip(poses.iter_mut()) {
                out.push(options.tracker_from_base * model.base.inverse() * data.frames[*id] * c.offset);
            }
            t.push(ti);
            qs.push(q);
        }
        let rcm = model.rcm.as_ref().map(|r| (options.tracker_from_base * Point3::from(r.point)).coords);
        Ok(Scenario {
            options: options.clone(),
            clusters,
            joint_names: model.joints.iter().map(|j| j.name.clone()).collect(),
            t,
            q: qs,
            poses,
            rcm,
        })
    }

    /// Draw one recording: noisy markers, occlusions, outliers, the tracker's pose fits and the
    /// joint states. `seed` overrides the options' seed (for Monte Carlo trials).
    pub fn record(&self, seed: u64) -> Recording {
        let o = &self.options;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, o.noise.max(0.0)).unwrap_or_else(|_| Normal::new(0.0, 0.0).expect("zero std is valid"));
        let mut rec = Recording { source: format!("synthetic ({}, seed {seed})", o.motion.name()), ..Default::default() };
        for (c, truth) in self.clusters.iter().zip(&self.poses) {
            let k = c.layout.len();
            let mut body = BodyTrack::new(c.name.clone(), "tracker");
            let mut markers = MarkerTrack {
                body: c.name.clone(),
                names: (1..=k).map(|m| format!("{}:Marker{m}", c.name)).collect(),
                t: self.t.clone(),
                xyz: Vec::with_capacity(self.t.len() * k * 3),
            };
            let mut obs = vec![None; k];
            for (i, pose) in truth.iter().enumerate() {
                let ghost = o.outliers > 0.0 && rng.random::<f64>() < o.outliers;
                let ghost_marker = if ghost { rng.random_range(0..k) } else { usize::MAX };
                for (m, (l, ob)) in c.layout.iter().zip(obs.iter_mut()).enumerate() {
                    let mut p = (pose * Point3::from(*l)).coords;
                    p += Vector3::new(normal.sample(&mut rng), normal.sample(&mut rng), normal.sample(&mut rng));
                    if m == ghost_marker {
                        let d: [f64; 3] = UnitSphere.sample(&mut rng);
                        p += Vector3::from(d) * 5e-3;
                    }
                    let hidden = o.occlusion > 0.0 && rng.random::<f64>() < o.occlusion;
                    *ob = (!hidden).then_some(p);
                    let v = ob.unwrap_or(Vector3::repeat(f64::NAN));
                    markers.xyz.extend_from_slice(v.as_slice());
                }
                match fit_pose(&c.layout, &obs) {
                    Some((p, rms)) => {
                        body.t.push(self.t[i]);
                        body.poses.push(p);
                        body.residual.push(rms);
                    }
                    None => body.occluded += 1,
                }
            }
            drop_outliers(&mut body);
            rec.bodies.push(body);
            rec.markers.push(markers);
        }
        rec.joints = Some(JointTrack { source: "/PSM1/measured_js".into(), names: self.joint_names.clone(), t: self.t.clone(), q: self.q.clone(), ..Default::default() });
        rec
    }

    /// The axes configuration (`markers.toml`) matching these clusters: the seven axes of Table 6
    /// with the clusters that share each.
    pub fn axes_config_toml(&self) -> String {
        let mut s = String::from(
            "# Which rigid body sits on which link, and which pairs of links share an axis (dvrk calib axes).\n\
             # Written by `dvrk synth mocap` for its Figure 5 clusters.\nmethod = \"sara\"\n\n",
        );
        for c in &self.clusters {
            s += &format!("[[bodies]]\nname = \"{}\"\nlink = \"{}\"\nframe = {}\n\n", c.name, c.link, c.frame);
        }
        for (axis, a, b) in FIGURE5_AXES {
            s += &format!("[[axes]]\nname = \"{axis}\"\nreference = \"{a}\"\nmoving = \"{b}\"\n\n");
        }
        s
    }
}

/// The seven axes of the PSM's double parallelogram (Table 6 labels) and the clusters of
/// [`figure5_clusters`] on either side: axis 3 (yaw link / back link), 4 (yaw / front), 6 (back /
/// bottom), 7 (back / top), 8 (bottom / end), c1 (front / bottom), c2 (top / end).
pub const FIGURE5_AXES: [(&str, &str, &str); 7] = [
    ("3", "yaw", "back"),
    ("4", "yaw", "front"),
    ("6", "back", "bottom"),
    ("7", "back", "top"),
    ("8", "bottom", "end"),
    ("c1", "front", "bottom"),
    ("c2", "top", "end"),
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_free_poses_are_the_true_ones_and_occlusions_are_counted() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let o = SynthOptions { noise: 0.0, duration: 2.0, occlusion: 0.2, ..Default::default() };
        let s = Scenario::new(&model, &o).unwrap();
        let rec = s.record(3);
        assert_eq!(rec.bodies.len(), 6);
        for (b, truth) in rec.bodies.iter().zip(&s.poses) {
            // A three-marker body is lost when any marker is hidden: 1 - (1 - p)^3.
            let p = 0.2f64;
            let expected = 240.0 * (1.0 - (1.0 - p).powi(3));
            assert!(((b.occluded as f64) - expected).abs() < 4.0 * expected.sqrt(), "{} vs {expected}", b.occluded);
            assert_eq!(b.len() + b.occluded, 240);
            for (t, pose) in b.t.iter().zip(&b.poses) {
                let i = (t * 120.0).round() as usize;
                assert!((pose.to_homogeneous() - truth[i].to_homogeneous()).abs().max() < 1e-12);
            }
        }
    }
}
