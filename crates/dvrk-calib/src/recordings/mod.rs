//! Recordings: every reader and writer of what a robot or a tracker recorded, below the three
//! products (motion-capture calibration, identification, discrepancy), which read through it and
//! never from each other.
//!
//! - Poses: MCAP and ROS 1 bags ([`message_file`], [`mcap_io`], with Foxglove's protobuf poses
//!   in [`foxglove`]), Motive CSV ([`motive_csv`]), plain CSV ([`plain_csv`]), one dispatch
//!   ([`read_recording`]); the tracks they fill ([`tracks`]); marker clouds to body poses
//!   ([`markers_to_pose`]).
//! - Joints: the dVRK's CRTK `JointState` topics ([`joint_states`]); one joint log with efforts
//!   ([`JointLog`], in the recorded channels with their map to the model's joints), read as
//!   identification wants it ([`torque_log`]: the WPI CSV in its actuator channels, the dVRK's
//!   `measured_js` with velocities) and as the discrepancy workflow wants it ([`read_log`]: in the
//!   joints, with setpoints: [`joint_log`] for MCAP and bags, its CSV layout [`joint_log_csv`], a
//!   tracked marker's poses [`marker_log`]).
//! - The format of a file, told from its content when asked for `auto` ([`format`]).
//!
//! The ROS 2 message codec is dvrk-sim's (`dvrk_sim::recording::{cdr, ros_msgs}`), which records
//! them; re-exported at the crate's root.

pub mod foxglove;
pub mod format;
pub mod joint_log;
pub mod joint_log_csv;
pub mod joint_states;
pub mod marker_log;
pub mod markers_to_pose;
pub mod mcap_io;
pub mod message_file;
pub mod motive_csv;
pub mod plain_csv;
pub mod read;
pub mod torque_log;
pub mod tracks;

pub use joint_log::JointLog;
pub use marker_log::MarkerLog;
pub use mcap_io::{McapLayout, McapOptions};
pub use read::{read_log, read_recording};
pub use torque_log::read_wpi_csv;
pub use tracks::{BodyTrack, JointTrack, MarkerTrack, Recording};
