//! `/tf` as foxglove.FrameTransforms (the SDK's protobuf schema): the pose of child frames in a
//! parent frame at one time, as Foxglove's 3D panel reads them. One message per sample holds
//! every body, as a ROS `tf2_msgs/TFMessage` does.

use foxglove::messages::{FrameTransform, FrameTransforms, Quaternion, Timestamp, Vector3};
use foxglove::Encode;

/// Simulated time `t` (s) as a Foxglove timestamp (negative times read as 0).
pub fn timestamp(t: f64) -> Timestamp {
    Timestamp::saturating_from_epoch_secs_f64(t.max(0.0))
}

/// One transform: `child` in `parent` at time `t` (s), translation (m), rotation quaternion
/// (x, y, z, w).
pub fn transform(t: f64, parent: &str, child: &str, translation: [f64; 3], rotation: [f64; 4]) -> FrameTransform {
    let [x, y, z] = translation;
    let [qx, qy, qz, qw] = rotation;
    FrameTransform {
        timestamp: Some(timestamp(t)),
        parent_frame_id: parent.into(),
        child_frame_id: child.into(),
        translation: Some(Vector3 { x, y, z }),
        rotation: Some(Quaternion { x: qx, y: qy, z: qz, w: qw }),
    }
}

/// `transforms` as one foxglove.FrameTransforms message, encoded into `buf` (cleared first).
pub fn encode(transforms: Vec<FrameTransform>, buf: &mut Vec<u8>) {
    buf.clear();
    FrameTransforms { transforms }.encode(buf).expect("a Vec grows to any message");
}

#[cfg(test)]
mod tests {
    use foxglove::messages::FrameTransforms;
    use foxglove::Decode;

    #[test]
    fn frame_transforms_decode_with_the_sdk() {
        let mut buf = Vec::new();
        super::encode(vec![super::transform(1.25, "world", "PSM1/yaw_link", [0.1, 0.2, 0.3], [0.0, 0.0, 0.0, 1.0])], &mut buf);
        let m = FrameTransforms::decode(buf.as_slice()).unwrap();
        let t = &m.transforms[0];
        let stamp = t.timestamp.unwrap();
        assert_eq!((stamp.sec(), stamp.nsec()), (1, 250_000_000));
        assert_eq!((t.parent_frame_id.as_str(), t.child_frame_id.as_str()), ("world", "PSM1/yaw_link"));
        assert_eq!(t.translation.unwrap().z, 0.3);
        assert_eq!(t.rotation.unwrap().w, 1.0);
    }
}
