//! `dvrk identify --plot`: per channel, the measured efforts (low-passed as the fit sees them)
//! against the identified model's prediction over a recording (the validation one when given).

use super::{Identification, IdentifyOptions, JointLog};
use crate::error::Result;
use crate::plot::{file_label, Figure, Line, Panel, BLUE, ORANGE};
use dvrk_kin::Model;

/// Points per line at most (a 30 s, 200 Hz recording is drawn whole).
const MAX_POINTS: usize = 3000;

/// The figure of `id`'s prediction of `rec` (named `source` in the title).
pub fn figure(id: &Identification, model: &Model, rec: &JointLog, options: &IdentifyOptions, source: &str) -> Result<Figure> {
    let (reg, predicted) = id.predict(model, rec, options)?;
    let in_band = super::errors_against(&predicted, &reg.tau_filtered);
    let trim = options.processing.trim;
    let t = &rec.t[trim..trim + reg.len()];
    let stride = reg.len().div_ceil(MAX_POINTS).max(1);
    // An actuator channel is not a joint: its effort is a torque.
    let unit = |name: &str| model.joints.iter().find(|j| j.name == name).map_or("N·m", |j| j.effort_unit());
    let panels = rec
        .names
        .iter()
        .enumerate()
        .map(|(c, name)| {
            let series = |v: &[f64]| (0..v.len()).step_by(stride).map(|i| (t[i] - t[0], v[i])).collect::<Vec<_>>();
            Panel {
                title: format!("{name}: relative error {:.3}", in_band[c]),
                x_label: "time (s)".into(),
                y_label: format!("effort ({})", unit(name)),
                lines: vec![
                    Line { points: series(&reg.tau_filtered[c]), color: ORANGE, width: 1, label: "measured (in band)".into() },
                    Line { points: series(&predicted[c]), color: BLUE, width: 1, label: "identified model".into() },
                ],
                ..Default::default()
            }
        })
        .collect();
    Ok(Figure { title: format!("{}: measured efforts against the identified model's prediction", file_label(source)), panels, columns: 2, panel_size: (560, 220) })
}
