//! The three ROS 2 messages a tracker recording holds, in CDR: geometry_msgs/msg/PoseStamped
//! (one rigid body per topic), tf2_msgs/msg/TFMessage (many per message) and
//! sensor_msgs/msg/JointState (the dVRK's `measured_js`), with their `ros2msg` schema texts.
//! The decoders also read the same messages as ROS 1 serialized them (`*_ros1`: a bag's
//! sensor_msgs/JointState and friends differ only in the header's `seq` and the packing).

use super::cdr::{CdrReader, CdrWriter};

/// std_msgs/Header.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Header {
    pub sec: i32,
    pub nanosec: u32,
    pub frame_id: String,
}

impl Header {
    /// A header at time `t` (s).
    pub fn at(t: f64, frame_id: &str) -> Self {
        let sec = t.floor();
        let mut nanosec = ((t - sec) * 1e9).round() as u32;
        let mut sec = sec as i32;
        if nanosec >= 1_000_000_000 {
            sec += 1;
            nanosec -= 1_000_000_000;
        }
        Header { sec, nanosec, frame_id: frame_id.into() }
    }
    /// The stamp (s).
    pub fn time(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }
    fn write(&self, w: &mut CdrWriter) {
        w.i32(self.sec);
        w.u32(self.nanosec);
        w.string(&self.frame_id);
    }
    fn read(r: &mut CdrReader) -> Result<Self, String> {
        if r.is_ros1() {
            // ROS 1: uint32 seq, then time as uint32 secs and nsecs.
            r.u32("header.seq")?;
            let sec = r.u32("header.stamp.secs")?;
            let sec = i32::try_from(sec).map_err(|_| format!("header.stamp.secs: {sec} is past 2038"))?;
            return Ok(Header { sec, nanosec: r.u32("header.stamp.nsecs")?, frame_id: r.string("header.frame_id")? });
        }
        Ok(Header { sec: r.i32("header.stamp.sec")?, nanosec: r.u32("header.stamp.nanosec")?, frame_id: r.string("header.frame_id")? })
    }
}

/// geometry_msgs/msg/PoseStamped (m; quaternion x, y, z, w).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PoseStamped {
    pub header: Header,
    pub position: [f64; 3],
    pub orientation: [f64; 4],
}

/// geometry_msgs/msg/TransformStamped (m; quaternion x, y, z, w).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub translation: [f64; 3],
    pub rotation: [f64; 4],
}

/// sensor_msgs/msg/JointState (rad, m; velocity and effort may be empty).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

/// `decode` (from CDR bytes, with their encapsulation header) and `decode_ros1` (from a ROS 1
/// bag's bytes) of message types that have a `read`.
macro_rules! decoders {
    ($($t:ty),*) => {$(
        impl $t {
            /// From CDR bytes.
            pub fn decode(bytes: &[u8]) -> Result<Self, String> {
                Self::read(&mut CdrReader::new(bytes)?)
            }
            /// From ROS 1 bytes (the same message in a bag).
            pub fn decode_ros1(bytes: &[u8]) -> Result<Self, String> {
                Self::read(&mut CdrReader::ros1(bytes))
            }
        }
    )*};
}

decoders!(PoseStamped, TransformStamped, Joy, JointState);

fn read3(r: &mut CdrReader, field: &str) -> Result<[f64; 3], String> {
    Ok([r.f64(&format!("{field}.x"))?, r.f64(&format!("{field}.y"))?, r.f64(&format!("{field}.z"))?])
}

fn read4(r: &mut CdrReader, field: &str) -> Result<[f64; 4], String> {
    Ok([r.f64(&format!("{field}.x"))?, r.f64(&format!("{field}.y"))?, r.f64(&format!("{field}.z"))?, r.f64(&format!("{field}.w"))?])
}

impl PoseStamped {
    /// The message of pose `p` (m) in frame `frame` at time `t` (s).
    pub fn from_pose(t: f64, frame: &str, p: &dvrk_kin::Pose) -> PoseStamped {
        let q = nalgebra::UnitQuaternion::from_rotation_matrix(&p.rotation);
        let v = p.translation.vector;
        PoseStamped { header: Header::at(t, frame), position: [v.x, v.y, v.z], orientation: [q.i, q.j, q.k, q.w] }
    }

    /// CDR bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.write(&mut w);
        self.position.iter().chain(&self.orientation).for_each(|x| w.f64(*x));
        w.finish()
    }
    fn read(r: &mut CdrReader) -> Result<Self, String> {
        Ok(PoseStamped { header: Header::read(r)?, position: read3(r, "pose.position")?, orientation: read4(r, "pose.orientation")? })
    }
}

impl PoseStamped {
    /// The pose it carries (m), as a command takes it: every value finite, the quaternion of
    /// norm 1 within 1e-3; otherwise why not.
    pub fn pose(&self) -> Result<dvrk_kin::Pose, String> {
        if !self.position.iter().chain(&self.orientation).all(|v| v.is_finite()) {
            return Err("the pose has a value that is not a finite number".into());
        }
        let [x, y, z, w] = self.orientation;
        let norm = (x * x + y * y + z * z + w * w).sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err(format!("the orientation's quaternion has norm {norm:.6}, not 1"));
        }
        let rotation = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)).to_rotation_matrix();
        let [px, py, pz] = self.position;
        Ok(dvrk_kin::Pose::from_parts(nalgebra::Translation3::new(px, py, pz), rotation))
    }
}

impl TransformStamped {
    /// CDR bytes of one geometry_msgs/msg/TransformStamped.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.write(&mut w);
        w.string(&self.child_frame_id);
        self.translation.iter().chain(&self.rotation).for_each(|x| w.f64(*x));
        w.finish()
    }
    fn read(r: &mut CdrReader) -> Result<Self, String> {
        let header = Header::read(r)?;
        let child_frame_id = r.string("child_frame_id")?;
        Ok(TransformStamped { header, child_frame_id, translation: read3(r, "transform.translation")?, rotation: read4(r, "transform.rotation")? })
    }
}

/// sensor_msgs/msg/Joy: how the dVRK publishes its foot pedals and buttons (`/footpedals/clutch`:
/// `buttons[0]` is 1 while pressed, 0 when released, 2 for a quick click).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Joy {
    pub header: Header,
    /// Axes (the wire's float32, widened).
    pub axes: Vec<f64>,
    pub buttons: Vec<i32>,
}

impl Joy {
    /// CDR bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.write(&mut w);
        w.f32_seq(&self.axes);
        w.i32_seq(&self.buttons);
        w.finish()
    }
    fn read(r: &mut CdrReader) -> Result<Self, String> {
        Ok(Joy { header: Header::read(r)?, axes: r.f32_seq("axes")?, buttons: r.i32_seq("buttons")? })
    }
}

/// Schema name and `ros2msg` text of sensor_msgs/msg/Joy.
pub fn joy_schema() -> (&'static str, String) {
    ("sensor_msgs/msg/Joy", format!("std_msgs/Header header
float32[] axes
int32[] buttons
{}", header_defs()))
}

/// tf2_msgs/msg/TFMessage: CDR bytes of `transforms`.
pub fn encode_tf(transforms: &[TransformStamped]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.u32(transforms.len() as u32);
    for t in transforms {
        t.header.write(&mut w);
        w.string(&t.child_frame_id);
        t.translation.iter().chain(&t.rotation).for_each(|x| w.f64(*x));
    }
    w.finish()
}

/// tf2_msgs/msg/TFMessage from CDR bytes.
pub fn decode_tf(bytes: &[u8]) -> Result<Vec<TransformStamped>, String> {
    read_tf(&mut CdrReader::new(bytes)?)
}

/// tf2_msgs/TFMessage from ROS 1 bytes.
pub fn decode_tf_ros1(bytes: &[u8]) -> Result<Vec<TransformStamped>, String> {
    read_tf(&mut CdrReader::ros1(bytes))
}

fn read_tf(r: &mut CdrReader) -> Result<Vec<TransformStamped>, String> {
    // Smallest element: header (4 + 4 + 4) + child id (4) + 7 f64.
    let n = r.seq_len("transforms", 16 + 56)?;
    (0..n)
        .map(|i| {
            let f = |s: &str| format!("transforms[{i}].{s}");
            let header = Header::read(r).map_err(|e| format!("transforms[{i}].{e}"))?;
            let child_frame_id = r.string(&f("child_frame_id"))?;
            let translation = read3(r, &f("transform.translation"))?;
            let rotation = read4(r, &f("transform.rotation"))?;
            Ok(TransformStamped { header, child_frame_id, translation, rotation })
        })
        .collect()
}

impl JointState {
    /// CDR bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.write(&mut w);
        w.string_seq(&self.name);
        w.f64_seq(&self.position);
        w.f64_seq(&self.velocity);
        w.f64_seq(&self.effort);
        w.finish()
    }
    fn read(r: &mut CdrReader) -> Result<Self, String> {
        Ok(JointState { header: Header::read(r)?, name: r.string_seq("name")?, position: r.f64_seq("position")?, velocity: r.f64_seq("velocity")?, effort: r.f64_seq("effort")? })
    }
}

/// crtk_msgs/msg/OperatingState: the arm's CRTK state (`DISABLED`, `ENABLED`, `PAUSED`, `FAULT`),
/// whether it is homed and busy.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OperatingState {
    pub header: Header,
    pub state: String,
    pub is_homed: bool,
    pub is_busy: bool,
}

impl OperatingState {
    /// CDR bytes.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.write(&mut w);
        w.string(&self.state);
        w.bool(self.is_homed);
        w.bool(self.is_busy);
        w.finish()
    }
}

/// Schema name and `ros2msg` text of crtk_msgs/msg/OperatingState.
pub fn operating_state_schema() -> (&'static str, String) {
    ("crtk_msgs/msg/OperatingState", format!("std_msgs/Header header\nstring state\nbool is_homed\nbool is_busy\n{}", header_defs()))
}

const SEP: &str = "================================================================================\n";

fn header_defs() -> String {
    format!("{SEP}MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n{SEP}MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")
}

/// crtk_msgs/msg/StringStamped (a `state_command`: `enable`, `home`, ...): its header and string.
pub fn decode_string_stamped(bytes: &[u8]) -> Result<(Header, String), String> {
    let mut r = CdrReader::new(bytes)?;
    let header = Header::read(&mut r)?;
    Ok((header, r.string("string")?))
}

/// crtk_msgs/msg/StringStamped as CDR.
pub fn encode_string_stamped(t: f64, text: &str) -> Vec<u8> {
    let mut w = CdrWriter::new();
    Header::at(t, "").write(&mut w);
    w.string(text);
    w.finish()
}

/// Schema name and `ros2msg` text of crtk_msgs/msg/StringStamped (`state`, `warning`, ...).
pub fn string_stamped_schema() -> (&'static str, String) {
    ("crtk_msgs/msg/StringStamped", format!("std_msgs/Header header\nstring string\n{}", header_defs()))
}

/// geometry_msgs/msg/TwistStamped at time `t` (s) in `frame`: linear (m/s) and angular (rad/s)
/// velocity, as the dVRK's `measured_cv`.
pub fn encode_twist_stamped(t: f64, frame: &str, linear: [f64; 3], angular: [f64; 3]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    Header::at(t, frame).write(&mut w);
    for x in linear.into_iter().chain(angular) {
        w.f64(x);
    }
    w.finish()
}

/// Schema name and `ros2msg` text of geometry_msgs/msg/TwistStamped.
pub fn twist_stamped_schema() -> (&'static str, String) {
    (
        "geometry_msgs/msg/TwistStamped",
        format!("std_msgs/Header header\nTwist twist\n{}{SEP}MSG: geometry_msgs/Twist\nVector3 linear\nVector3 angular\n{SEP}MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n", header_defs()),
    )
}

/// rcl_interfaces/msg/Log, what a ROS 2 node publishes on `/rosout`: at time `t` (s), `level`
/// (10 debug, 20 info, 30 warn, 40 error, 50 fatal) from logger `name`.
pub fn encode_log(t: f64, level: u8, name: &str, msg: &str) -> Vec<u8> {
    let mut w = CdrWriter::new();
    let h = Header::at(t, "");
    w.i32(h.sec);
    w.u32(h.nanosec);
    w.u8(level);
    w.string(name);
    w.string(msg);
    w.string("");
    w.string("");
    w.u32(0);
    w.finish()
}

/// Schema name and `ros2msg` text of std_msgs/msg/String.
pub fn string_schema() -> (&'static str, String) {
    ("std_msgs/msg/String", "string data\n".into())
}

/// A std_msgs/msg/String (the robot description's message).
pub fn encode_string(data: &str) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.string(data);
    w.finish()
}

/// Schema name and `ros2msg` text of geometry_msgs/msg/PoseStamped.
pub fn pose_stamped_schema() -> (&'static str, String) {
    (
        "geometry_msgs/msg/PoseStamped",
        format!(
            "std_msgs/Header header\ngeometry_msgs/Pose pose\n{}{SEP}MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n\
             {SEP}MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n{SEP}MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
            header_defs()
        ),
    )
}

/// Schema name and `ros2msg` text of tf2_msgs/msg/TFMessage.
pub fn tf_schema() -> (&'static str, String) {
    (
        "tf2_msgs/msg/TFMessage",
        format!(
            "geometry_msgs/TransformStamped[] transforms\n{SEP}MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\nstring child_frame_id\n\
             geometry_msgs/Transform transform\n{}{SEP}MSG: geometry_msgs/Transform\ngeometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n\
             {SEP}MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n{SEP}MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
            header_defs()
        ),
    )
}

/// Schema name and `ros2msg` text of sensor_msgs/msg/JointState.
pub fn joint_state_schema() -> (&'static str, String) {
    ("sensor_msgs/msg/JointState", format!("std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n{}", header_defs()))
}

#[cfg(test)]
mod tests {
    /// Joy and one TransformStamped round-trip through CDR; a Joy's float32 axes and int32
    /// buttons are 4-byte aligned after the header (as `ros2 bag` writes them).
    #[test]
    fn joy_and_transform_stamped_round_trip() {
        let j = Joy { header: Header::at(3.5, ""), axes: vec![0.25, -1.0], buttons: vec![1, 0, 2] };
        assert_eq!(Joy::decode(&j.encode()).unwrap(), j);
        assert!(Joy::decode(&j.encode()[..20]).unwrap_err().contains("axes"));
        let t = TransformStamped { header: Header::at(1.0, "MTMR_base"), child_frame_id: "MTMR".into(), translation: [0.1, 0.2, 0.3], rotation: [0.0, 0.0, 0.0, 1.0] };
        assert_eq!(TransformStamped::decode(&t.encode()).unwrap(), t);
    }

    use super::*;

    #[test]
    fn pose_stamped_has_the_ros2_layout() {
        let m = PoseStamped { header: Header::at(12.25, "world"), position: [1.0, 2.0, 3.0], orientation: [0.0, 0.0, 0.0, 1.0] };
        let b = m.encode();
        // header 4 | sec 4 | nanosec 4 | len 4 + "world\0" 6 = 18 -> pad to 24 | 7 f64 = 56: 80 bytes of payload.
        assert_eq!(b.len(), 4 + 80);
        assert_eq!(&b[4..8], &12i32.to_le_bytes());
        assert_eq!(&b[8..12], &250_000_000u32.to_le_bytes());
        assert_eq!(&b[28..36], &1.0f64.to_le_bytes());
        assert_eq!(PoseStamped::decode(&b).unwrap(), m);
        let e = PoseStamped::decode(&b[..48]).unwrap_err();
        assert_eq!(e, "pose.position.z: the message ends at byte 44 of its payload, 8 more byte(s) needed");
    }

    #[test]
    fn joint_state_and_tf_round_trip() {
        let js = JointState { header: Header::at(1.5, ""), name: vec!["outer_yaw".into(), "outer_pitch".into()], position: vec![0.1, -0.2], ..Default::default() };
        assert_eq!(JointState::decode(&js.encode()).unwrap(), js);
        let tf = vec![
            TransformStamped { header: Header::at(2.0, "tracker"), child_frame_id: "back".into(), translation: [0.1, 0.2, 0.3], rotation: [0.0, 0.0, 1.0, 0.0] },
            TransformStamped { header: Header::at(2.0, "tracker"), child_frame_id: "end".into(), translation: [0.4, 0.5, 0.6], rotation: [0.0, 0.0, 0.0, 1.0] },
        ];
        assert_eq!(decode_tf(&encode_tf(&tf)).unwrap(), tf);
    }
}
