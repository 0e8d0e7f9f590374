//! # dvrk-calib
//!
//! What a real robot's recordings tell about its model, in four products over shared readers:
//!
//! - [`mocap`], motion-capture calibration (Gondokaryono et al., sections 2.4 and 4.1): joint axes, the axis
//!   distances of Table 6 and the DH parameters they imply, the RCM by pivot calibration (eq.
//!   3-5, Table 7), an updated model file, and a synthetic tracker that writes what a real one
//!   would record;
//! - [`identify`]: every body's inertial parameters and the joints' friction, springs and motor
//!   inertias from a recording of efforts, physically consistent;
//! - [`discrepancy`]: which physical effect a model is missing, named from a recording;
//! - [`gravity`]: gravity compensation from a model (`dvrk gc`), checked on a recording.
//!
//! The products read through dvrk-sim's [`dvrk_sim::recording`], the home of every format the
//! project reads or writes (MCAP or ROS 1 bags with ROS 2 CDR, ROS 1 or Foxglove messages,
//! OptiTrack Motive CSV, the WPI CSV layout and plain CSV), and filter through [`filter`]; none
//! of them imports another.
//!
//! ```
//! use dvrk_calib::{pivot_calibration, PivotOptions, mocap::synth};
//! let model = dvrk_calib::dvrk_kin::load("psm", None).unwrap();
//! let options = synth::SynthOptions { noise: 0.0, duration: 10.0, ..Default::default() };
//! let scenario = synth::Scenario::new(&model, &options).unwrap();
//! let rec = scenario.record(1);
//! let fit = pivot_calibration(&rec.body("end").unwrap().poses, &PivotOptions::default()).unwrap();
//! assert!((fit.pivot - scenario.rcm.unwrap()).norm() < 1e-9);
//! ```
//!
//! Units: metres, radians, seconds. Poses are `dvrk_kin::Pose` (rotation matrix + translation).

pub mod discrepancy;
mod error;
pub mod filter;
pub mod gravity;
pub mod identify;
pub mod linalg;
pub mod mocap;
pub mod replay;

/// Plots (PNG / SVG): the figure renderer lives in dvrk-sim (`dvrk_sim::plot`, which also draws
/// the tracking figure of a run) and is re-exported here, with the calibration-specific figures.
pub mod plot {
    pub use dvrk_sim::plot::*;

    use crate::mocap::axis_distances::AxesReport;
    use crate::error::{CalibError, Result};

    /// Per-sample residual (mm) of every axis against the sample number.
    pub fn axis_residuals(report: &AxesReport) -> Result<Figure> {
        if report.axes.is_empty() {
            return Err(CalibError::data("plot", "no axis to draw"));
        }
        let panels = report
            .axes
            .iter()
            .map(|a| Panel {
                title: format!("axis {} ({} / {})", a.name, a.reference, a.moving),
                x_label: "sample".into(),
                y_label: "residual (mm)".into(),
                points: a.fit.residuals.iter().enumerate().map(|(i, r)| (i as f64, r * 1e3)).collect(),
                marks: vec![],
                equal: false,
                lines: vec![],
                scatter: vec![],
            })
            .collect();
        Ok(Figure { title: format!("axis residuals: {}", report.source), panels, columns: 0, panel_size: PANEL_SIZE })
    }
}

pub use mocap::axis_distances::{calibrate_axes, AxesOptions, AxesReport};
pub use mocap::axes_config::AxesConfig;
pub use mocap::axis_fit::{fit_axis, AxisFit, AxisMethod, AxisOptions};
pub use error::{CalibError, Result};
// The recording types this crate's public functions take (their home is `dvrk_sim::recording`).
pub use dvrk_sim::recording::{read_recording, BodyTrack, JointTrack, MarkerTrack, McapOptions, Recording};
pub use mocap::pivot::{pivot_calibration, PivotFit, PivotMethod, PivotOptions};
pub use dvrk_kin;
pub use dvrk_sim;
