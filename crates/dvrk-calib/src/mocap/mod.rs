//! Motion-capture calibration (Gondokaryono et al., sections 2.4 and 4.1): what a tracker's
//! marker clusters on the links tell about the robot's geometry.
//!
//! - [`axis_fit`]: one joint axis between two clusters; [`motion_range`]: whether they moved
//!   enough; [`axes_config`]: which tracked body sits on which link (`markers.toml`).
//! - [`axis_distances`]: every configured axis and the Table 6 distances between them;
//!   [`psm_dh`]: the PSM's DH lengths and angle they imply.
//! - [`pivot`]: the RCM (or a tool tip) by pivot calibration, eq. 3-5, Table 7.
//! - [`apply`]: a model file for one specific robot from the fitted figures.
//! - [`report_json`]: the JSON contracts of `dvrk calib pivot --json` and `dvrk calib axes --json`.
//! - [`synth`]: a synthetic tracker that writes what a real one would record.
//!
//! Reads through [`dvrk_sim::recording`]; imports neither identification nor discrepancy.

pub mod apply;
pub mod axes_config;
pub mod axis_distances;
pub mod axis_fit;
pub mod motion_range;
pub mod pivot;
pub mod psm_dh;
pub mod report_json;
pub mod synth;
