//! The report of `dvrk discrepancy` (issue 8's JSON contract, plus per-joint detail).

use serde::Serialize;
use std::collections::BTreeMap;

/// A named effect with its evidence.
#[derive(Debug, Clone, Serialize)]
pub struct EffectReport {
    /// From the effects vocabulary.
    pub name: String,
    pub joint: Option<String>,
    pub link: Option<String>,
    /// The actuator (1-based, a column of the coupling) of an actuator effect.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub actuator: Option<usize>,
    /// Model-file parameters (units of the vocabulary).
    pub parameters: BTreeMap<String, f64>,
    /// 95% intervals of the fitted parameters.
    pub ci95: BTreeMap<String, [f64; 2]>,
    pub delta_bic: f64,
    pub p_value: f64,
    /// A payload's place, what the recording fixes of it and the bodies it cannot tell apart.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub payload: Option<super::payload::PayloadReport>,
    /// Per analysed joint, in its own unit (N·m, N): the residual's band RMS on the fitted part
    /// before and after the effect, and the share of the joint's measured effort it explains.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub explained: Vec<JointExplained>,
}

/// What an effect explains on one joint, in physical units.
#[derive(Debug, Clone, Serialize)]
pub struct JointExplained {
    pub joint: String,
    pub unit: &'static str,
    pub rms_before: f64,
    pub rms_after: f64,
    /// `(rms_before - rms_after) / rms(measured effort)`, both in the analysis band.
    pub share_of_effort: f64,
}

impl EffectReport {
    /// `name on joint`, `name on link`, `name on actuator N`, `name`, or a coupling error with its entries:
    /// `coupling_error d55` (as the candidates' labels).
    pub fn label(&self) -> String {
        match self.joint.as_ref().or(self.link.as_ref()) {
            Some(at) => format!("{} on {at}", self.name),
            None if self.actuator.is_some() => format!("{} on actuator {}", self.name, self.actuator.unwrap_or(0)),
            None if self.name == dvrk_kin::effects::EffectKind::CouplingError.name() => {
                std::iter::once(self.name.as_str()).chain(self.parameters.keys().map(String::as_str)).collect::<Vec<_>>().join(" ")
            }
            None => self.name.clone(),
        }
    }
}

/// One ranked candidate: its effect and evidence (the same fields as a named effect's), and
/// what decided whether it is supported.
#[derive(Debug, Clone, Serialize)]
pub struct CandidateReport {
    pub label: String,
    #[serde(flatten)]
    pub effect: EffectReport,
    /// The fitted effect's likelihood-ratio test on the held-out part.
    pub heldout_p_value: f64,
    /// A linear candidate's held-out test over the whole recording (each of 5 parts predicted
    /// by a fit to the others); either test confirms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heldout_cv_p_value: Option<f64>,
    /// RMS of the fitted effect on its joint over that joint's effort noise.
    pub effect_to_noise: f64,
    /// Strong evidence, confirmed on held-out data, and large enough to matter.
    pub supported: bool,
    /// How much of the candidate's signature the refitted inertias can mimic (0: none, 1: all;
    /// the correlation of its main parameter's column with what the inertia nuisance takes up
    /// within its prior). A linear candidate's only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nuisance_correlation: Option<f64>,
}

/// Per joint, in its own units: the raw effort noise, the analysis band's noise floor and the
/// band-limited residual before and after.
#[derive(Debug, Clone, Serialize)]
pub struct JointRms {
    pub joint: String,
    pub unit: &'static str,
    pub noise: f64,
    pub band_floor: f64,
    pub band_rms_before: f64,
    pub band_rms_after: f64,
    pub band_rms_heldout_before: f64,
    pub band_rms_heldout_after: f64,
    /// The measured effort's band RMS on the fitted part (N·m, N).
    pub effort_band_rms: f64,
    /// `(band_rms_before - band_rms_after) / effort_band_rms`: the share of the joint's
    /// measured effort the named effect explains.
    pub share_explained: f64,
    /// Why the residual left after is what it is, as far as the workflow can tell.
    pub unexplained: String,
}

/// The tracking channel: the recording's setpoints replayed through the simulator, encoder
/// positions compared (rad, m) per joint, with the nominal model and with the named effect.
#[derive(Debug, Clone, Serialize)]
pub struct TrackingReport {
    pub joints: Vec<String>,
    pub rms_before: Vec<f64>,
    pub rms_after: Option<Vec<f64>>,
}

/// The kinematic channel: a tracked marker on one link against the model's forward kinematics,
/// the tracker's and the marker's placements estimated as nuisance. RMS are normalised: each
/// residual axis over the tracker's noise on it, 1 at the noise floor.
#[derive(Debug, Clone, Serialize)]
pub struct KinematicReport {
    pub topic: String,
    pub link: String,
    /// Tracked poses analysed; the first held-out one's time (s).
    pub samples: usize,
    pub heldout_from: f64,
    /// The tracker's noise per axis (m, rad), from fourth differences of its poses.
    pub noise_position: f64,
    pub noise_rotation: f64,
    /// Tracker <- base and link <- marker, as `[x, y, z]` (m) and a rotation vector (rad).
    pub tracker_from_base: [f64; 6],
    pub link_from_marker: [f64; 6],
    pub rms_before: f64,
    pub rms_after: f64,
    pub rms_heldout_before: f64,
    pub rms_heldout_after: f64,
    /// The channel's own ranking (best change in BIC first).
    pub candidates: Vec<CandidateReport>,
}

/// One round of the repeated workflow (the model with the effects of the rounds before it).
#[derive(Debug, Clone, Serialize)]
pub struct StepReport {
    pub round: usize,
    pub verdict: String,
    /// `name on joint-or-link` of the effect named in this round.
    pub named: Option<String>,
    pub rms_before: f64,
    pub rms_after: f64,
    pub rms_heldout_before: f64,
    pub rms_heldout_after: f64,
    pub raw_rms_heldout_after: f64,
}

/// The whole report.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// `named`, `none` or `ambiguous`.
    pub verdict: String,
    /// The channel the evidence comes from.
    pub channel: String,
    pub effects: Vec<EffectReport>,
    /// Ranked by change in BIC, best first.
    pub candidates: Vec<CandidateReport>,
    /// For `ambiguous`: the experiment that separates the two best.
    pub experiment: Option<String>,
    pub rms_before: f64,
    pub rms_after: f64,
    pub rms_heldout_before: f64,
    pub rms_heldout_after: f64,
    /// Held-out RMS of the raw (unfiltered) effort residual over each joint's sensor noise: 1 is
    /// the noise floor of a single sample.
    pub raw_rms_heldout_before: f64,
    pub raw_rms_heldout_after: f64,
    /// The model as given (its inertias not refitted), fitted and held-out parts.
    pub rms_nominal: f64,
    pub rms_heldout_nominal: f64,
    pub noise_floor: f64,
    pub rms_units: String,
    pub joints: Vec<JointRms>,
    /// Where along the motion each joint's residual (before) is large.
    pub location: Vec<super::locate::Location>,
    pub tracking: Option<TrackingReport>,
    /// With `--marker-topic`: the kinematic channel.
    pub kinematic: Option<KinematicReport>,
    /// Analysed samples and the start of the held-out part (s).
    pub samples: usize,
    pub heldout_from: f64,
    pub notes: Vec<String>,
    /// The rounds of the repeated workflow (empty for a single analysis).
    pub steps: Vec<StepReport>,
}
