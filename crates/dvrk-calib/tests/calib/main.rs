//! Integration tests of dvrk-calib: one binary, one module per concern.
//!
//! - `paper`: noise-free synthetic recordings give the model's Table 6 distances and RCM (1e-6 m).
//! - `noise_bound`: 100 seeded trials at 0.1 mm marker noise against the closed-form bound.
//! - `perturbed`: a robot with link lengths off by 1-3 mm, calibrated and applied.
//! - `bad_input`: recordings that cannot give a result give an error or a warning with numbers.
//! - `identify`: dynamic identification on the real WPI recordings; bad wpi-csv files.
//! - `identify_mtm`: the real MTM (WPI's recordings): its columns, identified on `one`, `two`
//!   predicted better than the authors' model.
//! - `identify_synthetic`: 100 seeded synthetic trials inside their 95% intervals; excitation warnings.
//! - `formats`: MCAP (ROS 2 and Foxglove layouts), plain and raw-marker CSV round trips.
//! - `dvrk_layout`: the dVRK's CRTK topic layout and ROS 1 bags, written by Python's
//!   `mcap-ros2-support` and `rosbags` from a real recording: the same results from each.
//! - `python_mcap`: MCAP files written by the Python `mcap` / `mcap-ros2-support` packages.
//! - `discrepancy`: hidden-effect recordings: the effect named with its parameters, `none` on
//!   effect-free ones, bad recordings refused; the detection-rate table (`--ignored`).
//! - `payload_real`: the WPI insertion-payload recordings: a real 205 g weight named on the
//!   insertion stage, nothing on the weightless recording's second half.
//! - `sim_recording`: an MCAP recorded by dvrk-sim (`dvrk sim --out`), read with this crate's reader.

mod util;

mod bad_input;
mod discrepancy;
mod dvrk_layout;
mod formats;
mod identify;
mod identify_mtm;
mod identify_synthetic;
mod noise_bound;
mod paper;
mod payload_real;
mod perturbed;
mod python_mcap;
mod sim_recording;
