//! Recording a run as MCAP: the dVRK's CRTK topics as ROS 2 CDR messages and every body's pose as
//! Foxglove frame transforms, through the project's one MCAP writer ([`mcap_out`]). The CDR
//! codec and the ROS 2 message types live here (dvrk-calib reads recordings with them: the
//! dependency order is kin <- sim <- calib).

pub mod camera_msgs;
pub mod cdr;
pub mod description;
pub mod frame_transform;
pub mod mcap_out;
pub mod ros_msgs;
pub mod scene_msgs;
pub mod writer;

pub use writer::{sample_stride, Recorder, RecordOptions};
