//! What a discrepancy analysis is asked ([`Options`]: thresholds and settings) and what it
//! returns ([`Outcome`]): the contract the torque-channel workflow, the kinematic-only one and
//! the repeated rounds share.

use super::nuisance::InertiaPrior;
use super::plot::Residuals;
use super::report::Report;
use super::signals::Processing;
use dvrk_kin::effects::EffectSpec;

/// Thresholds and settings.
#[derive(Debug, Clone)]
pub struct Options {
    pub processing: Processing,
    /// Strong evidence: a change in BIC above this (Kass and Raftery's "very strong", 10).
    pub min_delta_bic: f64,
    /// ... and a nested-model p-value below this (0.05 shared among ~40 candidates).
    pub max_p_value: f64,
    /// ... and the fitted effect at least this many times its joint's effort noise (RMS): below,
    /// the residual left by the rigid model's own small errors would be named as an effect.
    pub min_effect_to_noise: f64,
    /// ... the same for an effect only the tracker sees, over the tracker's noise: the kinematic
    /// chain leaves no residual of its own (effect-free, the tracker's held-out RMS is at its
    /// noise), so a smaller effect seen over thousands of samples is no model error.
    pub min_kinematic_effect_to_noise: f64,
    /// Two candidates whose changes in BIC differ by less than this are not told apart.
    pub ambiguity_bic: f64,
    /// ... nor by less than this share of the best's change in BIC. BIC's 10 points hold for a
    /// model that is right but for the effect; a real one is not (its inertias a few percent
    /// off), and what the model's own error adds to two near-alike candidates' evidence grows
    /// with the evidence: the tool's viscous friction on actuator 6 or 7 (which turn alike while
    /// the jaw holds) came 11 apart at 1050 on one truth engine, 0.1 on the other (seed 11).
    pub ambiguity_share: f64,
    /// Bootstrap replicates for p-values on a bound.
    pub bootstrap: usize,
    /// Replay the setpoints through the simulator before and after (the tracking channel).
    pub tracking: bool,
    pub seed: u64,
    /// The inertias re-estimated next to every candidate, within this prior.
    pub inertia_prior: InertiaPrior,
    /// Analyse only this effect's candidate ([`super::workflow::same_effect`]): the repeated workflow's refit of
    /// an effect named in an earlier round, the model holding every other.
    pub only: Option<EffectSpec>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            processing: Processing::default(),
            min_delta_bic: 10.0,
            max_p_value: 1e-3,
            min_effect_to_noise: 1.0,
            min_kinematic_effect_to_noise: 0.5,
            ambiguity_bic: 10.0,
            ambiguity_share: 0.02,
            bootstrap: 199,
            tracking: true,
            seed: 1,
            inertia_prior: InertiaPrior::default(),
            only: None,
        }
    }
}

/// The report and, when an effect is named, the model with it.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub report: Report,
    pub named: Option<EffectSpec>,
    /// The band-limited residual before and after, for the plot (not in the report).
    pub residuals: Residuals,
}
