//! ROS 2 messages as the bytes the recorder already encodes ([`crate::recording::ros_msgs`]):
//! DDS carries a CDR payload after a 4-byte encapsulation header, the same layout an MCAP `cdr`
//! message has, so the ROS 2 topics are the recording's messages byte for byte, and a command
//! is decoded by the same codec that reads recordings.

use rustdds::no_key::{Decode, DefaultDecoder, DeserializerAdapter, SerializerAdapter};
use rustdds::RepresentationIdentifier;

/// One serialized message, with its 4-byte encapsulation header (`00 01 00 00`: CDR, little
/// endian), as [`crate::recording::ros_msgs`] encodes and decodes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawCdr(pub Vec<u8>);

/// A message shorter than its encapsulation header, or in an encoding other than CDR.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct RawError(String);

/// Writes a [`RawCdr`]'s payload; reads one back with the header DDS sent.
pub struct RawAdapter;

impl SerializerAdapter<RawCdr> for RawAdapter {
    type Error = RawError;

    fn output_encoding() -> RepresentationIdentifier {
        RepresentationIdentifier::CDR_LE
    }

    fn to_bytes(value: &RawCdr) -> Result<rustdds::bytes::Bytes, RawError> {
        match value.0.get(..4) {
            Some([0, 1, _, _]) => Ok(rustdds::bytes::Bytes::copy_from_slice(&value.0[4..])),
            _ => Err(RawError("not a little-endian CDR message (its header is not 00 01)".into())),
        }
    }
}

const ENCODINGS: [RepresentationIdentifier; 2] = [RepresentationIdentifier::CDR_LE, RepresentationIdentifier::CDR_BE];

impl DeserializerAdapter<RawCdr> for RawAdapter {
    type Error = RawError;
    type Decoded = RawCdr;

    fn supported_encodings() -> &'static [RepresentationIdentifier] {
        &ENCODINGS
    }

    fn transform_decoded(decoded: RawCdr) -> RawCdr {
        decoded
    }
}

/// Puts the encapsulation header DDS took off back in front of the payload.
#[derive(Clone, Copy)]
pub struct RawDecoder;

impl Decode<'_, RawCdr> for RawDecoder {
    type Error = RawError;

    fn decode_bytes(self, input: &[u8], encoding: RepresentationIdentifier) -> Result<RawCdr, RawError> {
        if encoding != RepresentationIdentifier::CDR_LE {
            return Err(RawError(format!("encoding {encoding:?}: only little-endian CDR is read")));
        }
        let mut bytes = Vec::with_capacity(input.len() + 4);
        bytes.extend_from_slice(&[0, 1, 0, 0]);
        bytes.extend_from_slice(input);
        Ok(RawCdr(bytes))
    }
}

impl DefaultDecoder<RawCdr> for RawAdapter {
    type Decoder = RawDecoder;
    const DECODER: RawDecoder = RawDecoder;
}

/// The DDS type name of a ROS 2 message type: `sensor_msgs/msg/JointState` ->
/// `sensor_msgs::msg::dds_::JointState_` (how every ROS 2 middleware names it on the wire).
pub fn dds_type_name(ros_type: &str) -> Option<String> {
    let (package, rest) = ros_type.split_once('/')?;
    let name = rest.strip_prefix("msg/")?;
    (!package.is_empty() && !name.is_empty() && !name.contains('/')).then(|| format!("{package}::msg::dds_::{name}_"))
}

/// The DDS topic name of a ROS 2 topic: `/PSM1/measured_js` -> `rt/PSM1/measured_js`.
pub fn dds_topic_name(ros_topic: &str) -> String {
    format!("rt/{}", ros_topic.trim_start_matches('/'))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_the_ros2_middleware_convention() {
        assert_eq!(dds_type_name("sensor_msgs/msg/JointState").unwrap(), "sensor_msgs::msg::dds_::JointState_");
        assert_eq!(dds_type_name("crtk_msgs/msg/OperatingState").unwrap(), "crtk_msgs::msg::dds_::OperatingState_");
        assert!(dds_type_name("foxglove.SceneUpdate").is_none());
        assert_eq!(dds_topic_name("/PSM1/jaw/measured_js"), "rt/PSM1/jaw/measured_js");
    }

    #[test]
    fn a_message_survives_the_header_dds_removes_and_restores() {
        let js = crate::recording::ros_msgs::JointState { name: vec!["outer_yaw".into()], position: vec![0.25], ..Default::default() };
        let raw = RawCdr(js.encode());
        let payload = <RawAdapter as SerializerAdapter<RawCdr>>::to_bytes(&raw).unwrap();
        let back = RawDecoder.decode_bytes(&payload, RepresentationIdentifier::CDR_LE).unwrap();
        assert_eq!(back, raw);
        assert_eq!(crate::recording::ros_msgs::JointState::decode(&back.0).unwrap().position, vec![0.25]);
    }
}
