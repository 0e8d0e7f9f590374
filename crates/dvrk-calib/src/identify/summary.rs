//! The whole of `dvrk identify` as a library call (the CLI and the Python package share it):
//! identification, the rigid-body-only baseline, held-out validation (also as the WPI authors
//! computed their published errors: [`super::as_published`]) and the ablation, as the JSON summary.

use super::{ablation, identify, report, IdentifyOptions, Identification, JointLog};
use crate::error::Result;
use dvrk_kin::{BodyInertia, Model};
use serde_json::{json, Value};

/// Everything `dvrk identify` reports.
#[derive(Debug, Clone)]
pub struct IdentifyRun {
    /// The JSON summary (`relative_error`, `rigid_body_only`, `validation`, `ablation`, ...).
    pub summary: Value,
    pub identification: Identification,
    /// The rigid-body-only identification (the baseline).
    pub rigid: Identification,
    /// Which effects made the difference (also under `ablation` in the summary); empty when
    /// not asked for.
    pub ablation: Vec<ablation::AblationRow>,
}

/// What [`run_with`] reports besides the identification.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ablation {
    /// The ablation's rows: the identification again for each cumulative step of the options
    /// (most of the run: 12 of 14 s on the WPI PSM).
    Rows,
    /// None: the summary has no `ablation` (a sweep of identifications, or a model file wanted
    /// quickly).
    Skipped,
}

/// Identify `model` from `rec` (named `recording` in the report, format `format`), starting at
/// the CAD `prior`; with `held_out`, validate on it.
pub fn run(model: &Model, prior: &[BodyInertia], rec: &JointLog, held_out: Option<&JointLog>, options: &IdentifyOptions, recording: &str, format: &str) -> Result<IdentifyRun> {
    run_with(model, prior, rec, held_out, options, recording, format, Ablation::Rows, &mut |_| {})
}

/// [`run`], with or without the ablation, telling `progress` what it is doing.
#[allow(clippy::too_many_arguments)]
pub fn run_with(
    model: &Model,
    prior: &[BodyInertia],
    rec: &JointLog,
    held_out: Option<&JointLog>,
    options: &IdentifyOptions,
    recording: &str,
    format: &str,
    ablation: Ablation,
    progress: &mut dyn FnMut(&str),
) -> Result<IdentifyRun> {
    progress("identifying (regression, cutting planes)");
    let (id, _) = identify(model, prior, rec, options)?;
    let rigid_options = options.rigid_only();
    progress("the rigid-body-only baseline");
    let (rigid, _) = identify(model, prior, rec, &rigid_options)?;
    let mut summary = report::summary(model, &id, recording, format, &rigid.relative_error);
    if let Some(r2) = held_out {
        progress("validating on the held-out recording");
        let (errors, in_band, as_published) = id.validate_all(model, r2, options)?;
        let (rigid_errors, _) = rigid.validate(model, r2, &rigid_options)?;
        summary["validation"] = json!({"recording": r2.source, "relative_error": errors, "relative_error_in_band": in_band, "rigid_body_only": rigid_errors, "as_published": as_published});
    }
    let rows = match ablation {
        Ablation::Rows => {
            progress("the ablation (which effects made the difference)");
            let rows = ablation::ablation(model, prior, rec, held_out, options, Some(&id))?;
            summary["ablation"] = serde_json::to_value(&rows).unwrap_or(Value::Null);
            rows
        }
        Ablation::Skipped => Vec::new(),
    };
    Ok(IdentifyRun { summary, identification: id, rigid, ablation: rows })
}
