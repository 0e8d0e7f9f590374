//! What the report says of what is left: why a joint's residual stays where it is, and which
//! candidates the refitted inertias can mimic.

use super::nuisance::Nuisance;
use dvrk_kin::Model;
use super::scoring::Scored;

/// Why joint `joint`'s residual is left at `ratio` times its noise floor, as far as the model
/// tells: at the floor; terms the model's identification fitted that no effect expresses (an
/// identified model's notes list them, `- <joint>...`); or nothing the vocabulary holds.
pub(super) fn unexplained_guess(model: &Model, joint: &str, ratio: f64) -> String {
    if ratio < 1.5 {
        return format!("at the noise floor ({ratio:.1}x)");
    }
    let terms: Vec<&str> = model.spec.notes.lines().filter_map(|l| l.strip_prefix("- ")).filter(|l| l.starts_with(joint)).filter_map(|l| l.split(" = ").next()).collect();
    if terms.is_empty() {
        format!("{ratio:.1}x the noise floor: no candidate of the vocabulary explains it (model error outside the vocabulary, or effects below the gates)")
    } else {
        format!("{ratio:.1}x the noise floor: the identification fitted terms here that no effect of the vocabulary expresses ({}; the model's notes give their values)", terms.join(", "))
    }
}

/// A candidate whose signature the inertia nuisance mimics this closely (correlation) cannot be
/// told from an inertia error by the recording.
pub(super) const MIMICKED: f64 = 0.9;

/// With a wide (relative, CAD) inertia prior: the candidates the refitted inertias can mimic
/// (a linear candidate's `nuisance_correlation` above [`MIMICKED`]) and the recording that would
/// separate them; `None` with a model's own covariance or when none is mimicked.
pub(super) fn mimicked_note(nuisance: Option<&Nuisance>, scored: &[Scored]) -> Option<String> {
    if nuisance.is_none_or(|n| n.from_model) {
        return None;
    }
    let mut mimicked: Vec<(&str, f64)> = scored.iter().filter_map(|e| e.score.nuisance_correlation.filter(|r| *r > MIMICKED).map(|r| (e.label.as_str(), r))).collect();
    mimicked.sort_by(|a, b| b.1.total_cmp(&a.1));
    let shown: Vec<String> = mimicked.iter().take(8).map(|(l, r)| format!("{l} ({r:.2})")).collect();
    let more = if mimicked.len() > shown.len() { format!(" and {} more", mimicked.len() - shown.len()) } else { String::new() };
    (!shown.is_empty()).then(|| {
        format!(
            "the model carries no inertial covariance (a CAD model): its inertias are refitted under a wide prior and can mimic {}{more} (each candidate's nuisance_correlation); a recording that separates them: the robot identified without the suspected effect first (`dvrk identify -o`: its covariance then holds the inertias), or the same trajectory recorded with and without the suspected change",
            shown.join(", ")
        )
    })
}
