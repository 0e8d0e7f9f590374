//! A motion-capture recording in memory, whatever file it came from: rigid-body pose tracks,
//! raw marker tracks and joint states, in SI units (m, rad, s) and the tracker's own frame.

use crate::recording::error::{RecordingError, Result};
use dvrk_kin::Pose;
use nalgebra::Vector3;

/// The poses of one rigid body (a marker cluster) over time. Occluded samples are absent.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BodyTrack {
    /// Rigid-body name (Motive, CSV) or topic (PoseStamped, PoseInFrame) or child frame (TF).
    pub name: String,
    /// The frame the poses are given in, as recorded (`""` when the source does not say).
    pub frame_id: String,
    /// Sample times (s), increasing.
    pub t: Vec<f64>,
    /// Pose of the body in `frame_id` at each time (m).
    pub poses: Vec<Pose>,
    /// Per-sample RMS marker residual of the pose (m); empty when the source gives none.
    pub residual: Vec<f64>,
    /// Samples the source marked as occluded (empty cells, missing markers).
    pub occluded: usize,
    /// Samples dropped as outliers (marker residual far above the track's median).
    pub outliers: usize,
}

impl BodyTrack {
    /// An empty track.
    pub fn new(name: impl Into<String>, frame_id: impl Into<String>) -> Self {
        BodyTrack { name: name.into(), frame_id: frame_id.into(), ..Default::default() }
    }
    /// Number of valid samples.
    pub fn len(&self) -> usize {
        self.poses.len()
    }
    /// True when the track holds no valid sample.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }
    /// Sort by time (stable), for sources that interleave or reorder messages.
    pub fn sort_by_time(&mut self) {
        if self.t.windows(2).all(|w| w[0] <= w[1]) {
            return;
        }
        let mut idx: Vec<usize> = (0..self.t.len()).collect();
        idx.sort_by(|&a, &b| self.t[a].total_cmp(&self.t[b]));
        self.t = idx.iter().map(|&i| self.t[i]).collect();
        self.poses = idx.iter().map(|&i| self.poses[i]).collect();
        if self.residual.len() == idx.len() {
            self.residual = idx.iter().map(|&i| self.residual[i]).collect();
        }
    }
}

/// The raw markers of one cluster over time: `xyz` is `samples x markers x 3` (m), NaN where a
/// marker was occluded.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MarkerTrack {
    /// The rigid body these markers belong to.
    pub body: String,
    /// Marker names (Motive labels), in column order.
    pub names: Vec<String>,
    /// Sample times (s).
    pub t: Vec<f64>,
    /// Positions, `t.len() x names.len() x 3` (m), NaN when occluded.
    pub xyz: Vec<f64>,
}

impl MarkerTrack {
    /// Number of markers in the cluster.
    pub fn markers(&self) -> usize {
        self.names.len()
    }
    /// Position of marker `k` at sample `i` (m), `None` when occluded.
    pub fn get(&self, i: usize, k: usize) -> Option<Vector3<f64>> {
        let o = (i * self.names.len() + k) * 3;
        let v = Vector3::new(self.xyz[o], self.xyz[o + 1], self.xyz[o + 2]);
        v.iter().all(|x| x.is_finite()).then_some(v)
    }
}

/// Joint positions over time (a dVRK `measured_js` topic or `q1..qN` CSV columns).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointTrack {
    /// Where they came from (topic or file).
    pub source: String,
    /// Joint names (`outer_yaw`, ...), or `q1..qN`.
    pub names: Vec<String>,
    /// Sample times (s).
    pub t: Vec<f64>,
    /// Positions per sample (rad, m), each `names.len()` long.
    pub q: Vec<Vec<f64>>,
    /// Lines (1-based) of a CSV's rows left out for an empty or NaN joint value.
    pub skipped_lines: Vec<usize>,
}

/// Everything read from one recording.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    /// The file (or `synthetic`), for messages.
    pub source: String,
    /// Rigid-body pose tracks.
    pub bodies: Vec<BodyTrack>,
    /// Raw marker tracks, one per cluster.
    pub markers: Vec<MarkerTrack>,
    /// Joint states, if recorded.
    pub joints: Option<JointTrack>,
    /// Things the reader noticed and the user should know (NaN rows, skipped topics), with counts.
    pub warnings: Vec<String>,
}

/// True when `name` names `candidate`: the same string, the same without a leading `/`, or one
/// `/`-separated segment of a topic other than a trailing `pose` (`back` names `/mocap/back/pose`).
fn names(candidate: &str, name: &str) -> bool {
    if candidate == name || candidate.trim_start_matches('/') == name.trim_start_matches('/') {
        return true;
    }
    !name.contains('/') && candidate.split('/').filter(|s| !s.is_empty() && *s != "pose").any(|s| s == name)
}

impl Recording {
    /// The pose track of a rigid body, by exact name or an unambiguous short name.
    pub fn body(&self, name: &str) -> Result<&BodyTrack> {
        if let Some(b) = self.bodies.iter().find(|b| b.name == name) {
            return Ok(b);
        }
        let found: Vec<&BodyTrack> = self.bodies.iter().filter(|b| names(&b.name, name)).collect();
        match found.as_slice() {
            [b] => Ok(b),
            [] => Err(RecordingError::unknown("rigid body or topic", name, self.bodies.iter().map(|b| b.name.clone()))),
            many => Err(RecordingError::data(
                format!("rigid body `{name}`"),
                format!("ambiguous: it names {}", many.iter().map(|b| b.name.as_str()).collect::<Vec<_>>().join(", ")),
            )),
        }
    }

    /// The raw markers of a rigid body, if the recording has them.
    pub fn marker_track(&self, name: &str) -> Option<&MarkerTrack> {
        self.markers.iter().find(|m| m.body == name).or_else(|| {
            let found: Vec<&MarkerTrack> = self.markers.iter().filter(|m| names(&m.body, name)).collect();
            (found.len() == 1).then(|| found[0])
        })
    }

    /// Names of all pose tracks.
    pub fn body_names(&self) -> Vec<String> {
        self.bodies.iter().map(|b| b.name.clone()).collect()
    }
}

/// Typical sampling period (s) of a track: the median time step (0 for fewer than 2 samples).
pub fn median_period(t: &[f64]) -> f64 {
    if t.len() < 2 {
        return 0.0;
    }
    let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0).collect();
    if dt.is_empty() {
        return 0.0;
    }
    let mid = dt.len() / 2;
    *dt.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Sample indices at which every track has a sample, matched by time within half the shortest
/// median period (tracks from one tracker share frame times; this tolerates clock jitter).
/// Returns one `Vec` of `tracks.len()` indices per common instant.
pub fn common_samples(tracks: &[&BodyTrack]) -> Vec<Vec<usize>> {
    if tracks.is_empty() || tracks.iter().any(|t| t.is_empty()) {
        return Vec::new();
    }
    let period = tracks.iter().map(|t| median_period(&t.t)).filter(|p| *p > 0.0).fold(f64::INFINITY, f64::min);
    let tol = if period.is_finite() { 0.5 * period } else { 0.0 };
    let mut cursor = vec![0usize; tracks.len()];
    let mut out = Vec::new();
    let first = tracks[0];
    'outer: for (i0, &t0) in first.t.iter().enumerate() {
        let mut row = Vec::with_capacity(tracks.len());
        row.push(i0);
        for (k, tr) in tracks.iter().enumerate().skip(1) {
            let c = &mut cursor[k];
            while *c < tr.t.len() && tr.t[*c] < t0 - tol {
                *c += 1;
            }
            if *c >= tr.t.len() {
                break 'outer;
            }
            if (tr.t[*c] - t0).abs() > tol {
                continue 'outer;
            }
            row.push(*c);
        }
        out.push(row);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track(name: &str, t: &[f64]) -> BodyTrack {
        BodyTrack { name: name.into(), t: t.to_vec(), poses: vec![Pose::identity(); t.len()], ..Default::default() }
    }

    #[test]
    fn short_names_find_topics_and_ambiguity_is_an_error() {
        let rec = Recording {
            bodies: vec![track("/mocap/back/pose", &[0.0]), track("/mocap/front/pose", &[0.0]), track("/x/front", &[0.0])],
            ..Default::default()
        };
        assert_eq!(rec.body("back").unwrap().name, "/mocap/back/pose");
        assert_eq!(rec.body("mocap/back/pose").unwrap().name, "/mocap/back/pose");
        let e = rec.body("front").unwrap_err().to_string();
        assert!(e.contains("ambiguous") && e.contains("/x/front"), "{e}");
        let e = rec.body("nope").unwrap_err().to_string();
        assert!(e.contains("available: /mocap/back/pose"), "{e}");
    }

    #[test]
    fn common_samples_skip_instants_a_track_misses() {
        let a = track("a", &[0.0, 0.01, 0.02, 0.03, 0.04]);
        let b = track("b", &[0.0, 0.0201, 0.03, 0.04]);
        let rows = common_samples(&[&a, &b]);
        assert_eq!(rows, vec![vec![0, 0], vec![2, 1], vec![3, 2], vec![4, 3]]);
        assert_eq!(median_period(&a.t), 0.01);
    }
}
