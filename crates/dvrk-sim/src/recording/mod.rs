//! Recordings: every format the project reads or writes, readers and writers together, below
//! the products (dvrk-calib's motion-capture calibration, identification and discrepancy), which
//! read through it and never from each other.
//!
//! Read a dVRK bag or MCAP file (the CRTK `JointState` topics of one arm, ROS 1 or ROS 2) in one
//! call, whatever its format ([`read_joint_log`]):
//!
//! ```no_run
//! use std::path::Path;
//! let model = dvrk_kin::load("psm", None)?;
//! let (log, notes) = dvrk_sim::recording::read_joint_log(Path::new("psm1.bag"), "auto", &model, "PSM1")?;
//! println!("{} samples of {:?}; {}", log.t.len(), log.names, notes.join("; "));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! - Containers: MCAP and ROS 1 bags (`message_file.rs`), one visit per message whatever the
//!   container ([`for_each_message`]); the ROS 2 CDR codec (`cdr.rs`) and the ROS messages, ROS 1
//!   and ROS 2 (`ros_msgs.rs`, the camera's `camera_msgs.rs`, the scene's `scene_msgs.rs`);
//!   Foxglove's schemas (`foxglove.rs`, `frame_transform.rs`); the one MCAP writer (`mcap_out.rs`).
//! - Poses: MCAP and ROS 1 bags (`mcap_io.rs`), Motive CSV (`motive_csv.rs`), plain CSV
//!   (`plain_csv.rs`), one dispatch ([`read_recording`]); the tracks they fill (`tracks.rs`);
//!   marker clouds to body poses (`markers_to_pose.rs`).
//! - Joints: the dVRK's CRTK `JointState` topics (`joint_states.rs`); one joint log with efforts
//!   and setpoints ([`JointLog`], in the recorded channels with their map to the model's joints)
//!   and one reader of it whatever the format ([`read_joint_log`]: the WPI CSV `wpi_csv.rs`, MCAP
//!   and bags `joint_log_mcap.rs`, its CSV layout `joint_log_csv.rs`), read as recorded; each
//!   product prepares what it needs with [`JointLog`]'s operations. A tracked marker's poses:
//!   `marker_log.rs`.
//! - Joint configurations, one per CSV row, and the CSV of poses computed for them
//!   (`joint_rows.rs`, `dvrk fk --input`).
//! - A joint swept on its own, the WPI MTM platform's cable test (`joint_test_csv.rs`).
//! - An MTM's hand motion for teleoperation: pose, gripper, clutch pedal (`mtm_log.rs`).
//! - The format of a file, told from its content when asked for `auto` (`format.rs`).
//! - A simulation's run recorded as MCAP: the CRTK topics, every body's pose, the camera and the
//!   robot description ([`Recorder`], `writer.rs`, `description.rs`).
//!
//! Errors are [`RecordingError`]s, each naming the file and what in it.

pub mod camera_msgs;
pub mod cdr;
pub mod description;
pub mod frame_transform;
pub mod mcap_out;
pub mod ros_msgs;
pub mod scene_msgs;
pub mod writer;

// The readers' submodules are the crate's own; other crates see the flat names below (as rapier
// re-exports its pipeline), so a reader can move between files without breaking a caller.
mod error;
mod foxglove;
mod format;
mod joint_log;
mod joint_log_csv;
mod joint_log_mcap;
mod joint_rows;
mod joint_test_csv;
mod joint_states;
mod marker_log;
mod markers_to_pose;
mod mcap_io;
mod message_file;
mod motive_csv;
mod mtm_log;
mod plain_csv;
mod read;
mod tracks;
mod wpi_csv;

/// A text (CSV) recording whole, bounded ([`dvrk_kin::text_file::read_recording_text`]: a
/// regular file, at most 2 GiB, lines of at most 1 MiB, no NUL byte); errors name the file.
pub(crate) fn read_csv_text(path: &std::path::Path) -> Result<String> {
    use dvrk_kin::text_file::{read_recording_text, MAX_LINE_BYTES, MAX_RECORDING_TEXT_BYTES};
    Ok(read_recording_text(path, MAX_RECORDING_TEXT_BYTES, MAX_LINE_BYTES)?)
}

/// Cell `column` (1-based) of line `line` (1-based) of the CSV `path`, `text` (trimmed), as a
/// finite number; an error names the line, the column and the text.
pub(crate) fn finite_cell(path: &std::path::Path, line: usize, column: usize, text: &str) -> Result<f64> {
    let x: f64 = text.parse().map_err(|_| RecordingError::file(path, format!("line {line}, column {column}: `{text}` is not a number")))?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(RecordingError::file(path, format!("line {line}, column {column}: {x} is not finite")))
    }
}

pub use error::{RecordingError, Result};
// Writing a simulation's run.
pub use writer::{sample_stride, Recorder, RecordOptions};
// Any recording, by format.
pub use format::{auto_note, resolve as resolve_format, FORMATS};
pub use read::{read_joint_log, read_joint_log_parts, read_recording, Parts};
// Poses: MCAP and ROS 1 bags, Motive and plain CSV, marker clouds.
pub use markers_to_pose::{drop_outliers, estimate_layout, fit_pose, poses_from_markers, MIN_MARKERS};
pub use mcap_io::{parse as parse_mcap_poses, pose_topic, read as read_mcap_poses, write as write_mcap_poses, McapLayout, McapOptions};
pub use message_file::{container, for_each as for_each_message, for_each_mcap, Container};
pub use motive_csv::{parse as parse_motive_csv, read as read_motive_csv};
pub use plain_csv::{parse as parse_plain_csv, read as read_plain_csv, write as write_plain_csv};
pub use tracks::{common_samples, median_period, BodyTrack, JointTrack, MarkerTrack, Recording};
// Joint logs: one type, one reader ([`read_joint_log`]); each product prepares its own view.
pub use joint_log::{JointLog, NO_SETPOINTS};
pub use joint_log_mcap::write_mcap as write_joint_log_mcap;
pub use joint_log_csv::{parse as parse_joint_log_csv, read as read_joint_log_csv, read_markers as read_marker_csv, write as write_joint_log_csv, CsvLog};
pub use joint_states::{read_arm, read_arms, ArmStates, JointStates};
// Joint configurations one per row (`dvrk fk --input`) and the poses written for them.
pub use joint_rows::{push_pose_row, read_joint_rows, JointRows, POSE_ROWS_HEADER};
// An MTM's hand motion (pose, gripper, clutch) for teleoperation.
pub use mtm_log::{read_mtm, MtmLog, MtmTopics};
pub use marker_log::{marker_frame, read_mcap as read_marker_mcap, synthetic_topic, MarkerLog};
pub use wpi_csv::{parse as parse_wpi_csv, read as read_wpi_csv, WPI_RATE};
// A joint swept on its own (the WPI MTM platform's cable test).
pub use joint_test_csv::read_joint_test;
