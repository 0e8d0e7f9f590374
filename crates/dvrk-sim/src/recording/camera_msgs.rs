//! The camera's topics as foxglove.CompressedImage and foxglove.CameraCalibration, the SDK's
//! protobuf types: image bytes travel as they are (no base64).

use super::frame_transform::timestamp;
use crate::camera::Intrinsics;
use foxglove::bytes::Bytes;
use foxglove::messages::{CameraCalibration, CompressedImage};
use foxglove::{Decode, Encode};

/// foxglove.CompressedImage: `data` (a PNG file's bytes) taken at time `t` (s) in `frame_id`,
/// encoded into `buf` (cleared first).
pub fn compressed_image(t: f64, frame_id: &str, format: &str, data: &[u8], buf: &mut Vec<u8>) {
    buf.clear();
    let m = CompressedImage { timestamp: Some(timestamp(t)), frame_id: frame_id.into(), data: Bytes::copy_from_slice(data), format: format.into() };
    m.encode(buf).expect("a Vec grows to any message");
}

/// The image bytes of a foxglove.CompressedImage message, and its format and frame.
pub fn decode_compressed_image(bytes: &[u8]) -> Result<(Vec<u8>, String, String), String> {
    let m = CompressedImage::decode(bytes).map_err(|e| format!("not a foxglove.CompressedImage ({e})"))?;
    Ok((m.data.to_vec(), m.format, m.frame_id))
}

/// foxglove.CameraCalibration of a rectified pinhole eye without distortion. `tx` is the
/// projection's fourth column entry `P[3] = -fx * B` (px m) of a right eye at baseline `B` from
/// the left eye (ROS stereo convention), 0 for the left eye.
pub fn camera_calibration(t: f64, frame_id: &str, k: &Intrinsics, tx: f64) -> Vec<u8> {
    let m = CameraCalibration {
        timestamp: Some(timestamp(t)),
        frame_id: frame_id.into(),
        width: k.width,
        height: k.height,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: k.k().to_vec(),
        r: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: vec![k.fx, 0.0, k.cx, tx, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0],
    };
    let mut buf = Vec::new();
    m.encode(&mut buf).expect("a Vec grows to any message");
    buf
}

#[cfg(test)]
mod tests {
    #[test]
    fn image_round_trips_byte_for_byte() {
        let mut buf = Vec::new();
        super::compressed_image(2.5, "camera_left", "png", &[137, 80, 78, 71, 0, 255], &mut buf);
        let (data, format, frame) = super::decode_compressed_image(&buf).unwrap();
        assert_eq!(data, vec![137, 80, 78, 71, 0, 255]);
        assert_eq!((format.as_str(), frame.as_str()), ("png", "camera_left"));
        let m = <foxglove::messages::CompressedImage as foxglove::Decode>::decode(buf.as_slice()).unwrap();
        assert_eq!(m.timestamp.unwrap().nsec(), 500_000_000);
    }
}
