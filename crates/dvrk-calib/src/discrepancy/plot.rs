//! The before/after plot of `dvrk discrepancy --plot`: per moving joint, the torque channel's
//! residual in the analysis band against time, velocity, load and position, before (the model with
//! its inertias refitted) and after (with the named effects), and the noise floor.

use crate::error::{CalibError, Result};
use crate::plot::{Figure, Line, Panel, Scatter, GREEN};

/// Colour of the residual before (the model as given, inertias refitted).
pub const BEFORE: [u8; 3] = [230, 85, 13];
/// Colour of the residual after (with the named effects).
pub const AFTER: [u8; 3] = [31, 119, 180];
/// Colour of the noise floor's lines.
pub const FLOOR: [u8; 3] = [110, 110, 110];
/// Panels in a joint's row: residual against time, velocity, load and position.
pub const COLUMNS: usize = 4;
/// Size of one panel (px).
pub const PANEL: (usize, usize) = (320, 250);
/// At most this many points per series: the analysed samples are thinned evenly beyond it (a
/// 100 Hz, 60 s recording would otherwise put 6000 dots in a panel 230 px wide).
pub const MAX_POINTS: usize = 1000;

/// The torque channel's residual in the analysis band, before and after, at the analysed
/// samples; per moving joint, `[joint][sample]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Residuals {
    /// The moving (analysed) joints' names.
    pub joints: Vec<String>,
    /// Their effort units (`N·m`, `N`).
    pub units: Vec<&'static str>,
    /// Their position units (`rad`, `m`).
    pub position_units: Vec<&'static str>,
    /// Sample times (s).
    pub t: Vec<f64>,
    /// Filtered encoder positions (rad, m).
    pub q: Vec<Vec<f64>>,
    /// Velocities (rad/s, m/s).
    pub qd: Vec<Vec<f64>>,
    /// The load: the effort predicted before (N·m, N).
    pub load: Vec<Vec<f64>>,
    /// Measured minus predicted effort before and after (N·m, N).
    pub before: Vec<Vec<f64>>,
    pub after: Vec<Vec<f64>>,
    /// The residual's noise floor in the band per joint (N·m, N).
    pub floor: Vec<f64>,
    /// Start of the held-out part (s).
    pub heldout_from: f64,
}

/// Every `stride`-th index so that at most [`MAX_POINTS`] remain.
fn thinned(n: usize) -> impl Iterator<Item = usize> {
    (0..n).step_by(n.div_ceil(MAX_POINTS).max(1))
}

/// The figure: one row of [`COLUMNS`] panels per moving joint, its title naming `source` (the
/// recording) and the colours.
pub fn figure(r: &Residuals, source: &str) -> Result<Figure> {
    if r.joints.is_empty() || r.t.is_empty() {
        return Err(CalibError::data("plot", "no effort residual to draw (a recording without efforts has none: the kinematic channel's figures are in the report)"));
    }
    let mut panels = Vec::with_capacity(COLUMNS * r.joints.len());
    for (k, name) in r.joints.iter().enumerate() {
        let (unit, pu) = (r.units[k], r.position_units[k]);
        let axes: [(&str, String, &[f64]); COLUMNS] = [
            ("time", "time (s)".into(), &r.t),
            ("velocity", format!("velocity ({pu}/s)"), &r.qd[k]),
            ("load", format!("predicted effort ({unit})"), &r.load[k]),
            ("position", format!("position ({pu})"), &r.q[k]),
        ];
        let (ylo, yhi) = r.before[k].iter().chain(&r.after[k]).filter(|v| v.is_finite()).fold((-r.floor[k], r.floor[k]), |(a, b), v| (a.min(*v), b.max(*v)));
        for (what, x_label, x) in axes {
            // The legend once per joint, on its time panel.
            let named = |label: &str| if what == "time" { label.to_string() } else { String::new() };
            let series = |y: &[f64], color, label: &str| Scatter { points: thinned(x.len()).map(|i| (x[i], y[i])).collect(), color, label: named(label) };
            let (xlo, xhi) = x.iter().filter(|v| v.is_finite()).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
            let floor = |f: f64, label: &str| Line { points: vec![(xlo, f), (xhi, f)], color: FLOOR, width: 1, label: named(label) };
            let mut lines = vec![floor(r.floor[k], "noise floor"), floor(-r.floor[k], "")];
            if what == "time" {
                lines.push(Line { points: vec![(r.heldout_from, ylo), (r.heldout_from, yhi)], color: GREEN, width: 1, label: "held out from".into() });
            }
            panels.push(Panel {
                title: format!("{name}: residual against {what}"),
                x_label,
                y_label: format!("residual ({unit})"),
                scatter: vec![series(&r.before[k], BEFORE, "before"), series(&r.after[k], AFTER, "after")],
                lines,
                ..Default::default()
            });
        }
    }
    let title = format!("{}: effort residual in the analysis band, before (orange) and after (blue) the named effects; noise floor grey, held out from {:.1} s", crate::plot::file_label(source), r.heldout_from);
    Ok(Figure { title, panels, columns: COLUMNS, panel_size: PANEL })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn residuals(n: usize) -> Residuals {
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
        let s: Vec<f64> = t.iter().map(|t| t.sin()).collect();
        Residuals {
            joints: vec!["a".into(), "b".into()],
            units: vec!["N·m", "N"],
            position_units: vec!["rad", "m"],
            q: vec![s.clone(), s.clone()],
            qd: vec![s.clone(), s.clone()],
            load: vec![s.clone(), s.clone()],
            before: vec![s.iter().map(|v| 2.0 * v).collect(), s.clone()],
            after: vec![s.iter().map(|v| 0.1 * v).collect(), s.clone()],
            floor: vec![0.2, 0.1],
            heldout_from: t[n * 7 / 10],
            t,
        }
    }

    #[test]
    fn a_row_per_joint_thinned_with_both_colours() {
        let fig = figure(&residuals(6000), "t").unwrap();
        assert_eq!(fig.panels.len(), 8);
        assert_eq!(fig.size(), (4 * PANEL.0, 20 + 2 * PANEL.1));
        assert!(fig.panels.iter().all(|p| p.scatter.iter().all(|s| s.points.len() == 1000)));
        // The floor's two lines everywhere, the held-out start on the time panels.
        assert_eq!(fig.panels[0].lines.len(), 3);
        assert_eq!(fig.panels[1].lines.len(), 2);
        let (_, _, px) = fig.pixels();
        let has = |c: [u8; 3]| px.chunks(3).any(|p| p == c);
        assert!(has(BEFORE) && has(AFTER) && has(FLOOR));
        assert!(figure(&Residuals::default(), "t").is_err());
    }
}
