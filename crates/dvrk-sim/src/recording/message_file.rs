//! Recorded message files, read message by message whatever the container: MCAP (ROS 2 `cdr`,
//! Foxglove `json`, or ROS 1 messages converted by `mcap convert`) and ROS 1 bags (v2.0,
//! uncompressed, bz2 or lz4 chunks, read with the `rosbag` crate). Every reader of recordings
//! (poses, joint states) walks a file through [`for_each`], so a format is added once.
//!
//! The container is told by the file's first bytes, not its name. Type names are given in
//! ROS 2's spelling (`sensor_msgs/msg/JointState`) whatever the file used
//! (`sensor_msgs/JointState` in a bag), with the wire [`Encoding`] beside them.

use crate::recording::error::{RecordingError, Result};
use std::collections::BTreeMap;
use std::path::Path;

/// MCAP's magic bytes.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";
/// A ROS 1 bag's version line.
const BAG_MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// The container of a recording.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Container {
    /// An MCAP file.
    Mcap,
    /// A ROS 1 bag (v2.0).
    Bag,
}

/// How a message's bytes are serialized.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// ROS 2's CDR (with its encapsulation header).
    Cdr,
    /// ROS 1's serialization (packed little endian).
    Ros1,
    /// JSON (Foxglove schemas).
    Json,
    /// Protobuf (Foxglove's SDK schemas).
    Protobuf,
    /// Anything else (skipped by every reader).
    Other,
}

impl Encoding {
    /// The name MCAP's channels use (`cdr`, `ros1`, `json`, `protobuf`; `other`).
    pub fn name(self) -> &'static str {
        match self {
            Encoding::Cdr => "cdr",
            Encoding::Ros1 => "ros1",
            Encoding::Json => "json",
            Encoding::Protobuf => "protobuf",
            Encoding::Other => "other",
        }
    }
}

/// One recorded message.
#[derive(Debug, Clone, Copy)]
pub struct Message<'a> {
    /// Its number in the file (1-based, in file order), for messages.
    pub index: usize,
    /// The topic (`/PSM1/measured_js`).
    pub topic: &'a str,
    /// The type in ROS 2's spelling (`sensor_msgs/msg/JointState`), or the file's own name for
    /// non-ROS schemas (`foxglove.PoseInFrame`); empty when the channel has no schema.
    pub schema: &'a str,
    /// The wire encoding.
    pub encoding: Encoding,
    /// When the recorder logged it (ns since the epoch, or since the recording's start).
    pub log_time_ns: u64,
    /// The serialized message.
    pub data: &'a [u8],
}

impl Message<'_> {
    /// The log time (s).
    pub fn log_time(&self) -> f64 {
        self.log_time_ns as f64 * 1e-9
    }
}

/// The container of `path` from its first bytes; `None` for anything else (CSV, text).
pub fn container(path: &Path) -> Result<Option<Container>> {
    use std::io::Read;
    let mut head = [0u8; 13];
    // A regular file only: a FIFO would wait for a writer forever, a device never end.
    let mut f = dvrk_kin::text_file::open_input(path)?;
    let n = f.read(&mut head).map_err(|e| RecordingError::file(path, format!("cannot read: {e}")))?;
    Ok(container_of(&head[..n]))
}

/// The container of bytes that start a file.
pub fn container_of(head: &[u8]) -> Option<Container> {
    if head.starts_with(MCAP_MAGIC) {
        Some(Container::Mcap)
    } else if head.starts_with(BAG_MAGIC) {
        Some(Container::Bag)
    } else {
        None
    }
}

/// ROS 2's spelling of a type: `pkg/Type` becomes `pkg/msg/Type`.
pub fn ros2_type_name(name: &str) -> String {
    match name.split_once('/') {
        Some((pkg, ty)) if !ty.contains('/') => format!("{pkg}/msg/{ty}"),
        _ => name.to_string(),
    }
}

fn encoding(name: &str) -> Encoding {
    match name {
        "cdr" => Encoding::Cdr,
        "ros1" => Encoding::Ros1,
        "json" => Encoding::Json,
        "protobuf" => Encoding::Protobuf,
        _ => Encoding::Other,
    }
}

/// Call `visit` on every message of the MCAP or bag file `path`, in file order; returns how many
/// there were. A file that is neither, or is damaged, is an error naming the file; an error of
/// `visit` stops the walk and is returned as it is.
pub fn for_each(path: &Path, visit: impl FnMut(&Message) -> Result<()>) -> Result<usize> {
    match container(path)? {
        Some(Container::Mcap) => {
            // Read as the reader asks, not whole: a 5-minute recording's file is 60 MB.
            let cannot = |e: std::io::Error| RecordingError::file(path, format!("cannot read: {e}"));
            let file = dvrk_kin::text_file::open_input(path)?;
            let len = file.metadata().map_err(cannot)?.len();
            for_each_mcap_from(file, usize::try_from(len).unwrap_or(usize::MAX), path, visit)
        }
        Some(Container::Bag) => for_each_bag(path, visit),
        None if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("bag")) => Err(RecordingError::file(path, "not a ROS 1 bag (it does not start with `#ROSBAG V2.0`)")),
        None => Err(RecordingError::file(path, "not an MCAP file (it does not start with the MCAP magic bytes) nor a ROS 1 bag")),
    }
}

/// Every message of the MCAP file `bytes` (from `path`), in file order, through the `mcap`
/// crate's sans-io reader with a record length limit (`record_length_limit`): its
/// `MessageStream` has none, and a damaged record inside a chunk (found by the fuzz target
/// `tests/fuzz.rs::mcap_joint_states`) made it reserve 3.5e18 bytes and abort the process.
/// Returns the number of messages.
pub fn for_each_mcap(bytes: &[u8], path: &Path, visit: impl FnMut(&Message) -> Result<()>) -> Result<usize> {
    for_each_mcap_from(bytes, bytes.len(), path, visit)
}

/// [`for_each_mcap`] on the `len` bytes `source` reads, read as the reader asks for them.
fn for_each_mcap_from(mut source: impl std::io::Read, len: usize, path: &Path, mut visit: impl FnMut(&Message) -> Result<()>) -> Result<usize> {
    use mcap::records::Record;
    use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
    // CRCs checked (the writer's, where it wrote them: a zero CRC is none): a flipped bit in a
    // chunk is an error, not a wrong number (Python's `mcap` raises CRCValidationError).
    let options = LinearReaderOptions::default().with_record_length_limit(record_length_limit(len)).with_validate_chunk_crcs(true).with_validate_data_section_crc(true);
    let mut reader = LinearReader::new_with_options(options);
    // The file's first bytes (whether it is an MCAP at all, for the error).
    let mut head: Vec<u8> = Vec::with_capacity(MCAP_MAGIC.len());
    let mut fed = 0usize;
    let mut count = 0usize;
    let damaged = |count: usize, head: &[u8], e: &dyn std::fmt::Display| {
        if head.starts_with(MCAP_MAGIC) {
            RecordingError::file(path, format!("truncated or damaged after {count} message(s): {e}; nothing was fitted (recover the file with `mcap recover`)"))
        } else {
            RecordingError::file(path, "not an MCAP file (it does not start with the MCAP magic bytes)")
        }
    };
    // Schema names (normalised once) by id; channels' topic, encoding and schema id by id.
    let mut schemas: BTreeMap<u16, String> = BTreeMap::new();
    let mut channels: BTreeMap<u16, (String, Encoding, u16)> = BTreeMap::new();
    let mut names: BTreeMap<u16, String> = BTreeMap::new();
    loop {
        let want = match reader.next_event() {
            None => break,
            Some(Err(mcap::McapError::BadChunkCrc { saved, calculated })) => {
                return Err(RecordingError::file(path, format!("a chunk ending by byte {fed} is damaged: its CRC is {saved:08x}, its content's {calculated:08x} ({count} message(s) read up to there); nothing was used (recover the rest with `mcap recover`)")));
            }
            Some(Err(mcap::McapError::BadDataCrc { saved, calculated })) => {
                return Err(RecordingError::file(path, format!("the data section is damaged: its CRC is {saved:08x}, its content's {calculated:08x}; nothing was read (recover the file with `mcap recover`)")));
            }
            Some(Err(e)) => return Err(damaged(count, &head, &e)),
            Some(Ok(LinearReadEvent::ReadRequest(n))) => n,
            Some(Ok(LinearReadEvent::Record { data, opcode })) => {
                // Only the records read here are parsed, and only once their strings fit.
                if !matches!(opcode, mcap::records::op::SCHEMA | mcap::records::op::CHANNEL | mcap::records::op::MESSAGE) {
                    continue;
                }
                if !strings_fit(opcode, data) {
                    return Err(damaged(count, &head, &"a schema or channel record whose string lengths run past its end"));
                }
                match mcap::parse_record(opcode, data).map_err(|e| damaged(count, &head, &e))? {
                    Record::Schema { header, .. } => {
                        schemas.insert(header.id, header.name);
                    }
                    Record::Channel(c) => {
                        channels.insert(c.id, (c.topic, encoding(&c.message_encoding), c.schema_id));
                    }
                    Record::Message { header, data } => {
                        count += 1;
                        let Some((topic, enc, schema_id)) = channels.get(&header.channel_id) else {
                            return Err(damaged(count - 1, &head, &format!("message {count} is on channel {}, which the file never declares", header.channel_id)));
                        };
                        let schema = names.entry(header.channel_id).or_insert_with(|| {
                            let s = schemas.get(schema_id).map_or("", |s| s.as_str());
                            if *enc == Encoding::Ros1 {
                                ros2_type_name(s)
                            } else {
                                s.to_string()
                            }
                        });
                        visit(&Message { index: count, topic, schema, encoding: *enc, log_time_ns: header.log_time, data: &data })?;
                    }
                    _ => {}
                }
                continue;
            }
        };
        // Never more than the file has left (a damaged length asks for more).
        let buf = reader.insert(want.min(len.saturating_sub(fed)));
        let n = read_up_to(&mut source, buf).map_err(|e| RecordingError::file(path, format!("cannot read: {e}")))?;
        let missing = (MCAP_MAGIC.len() - head.len()).min(n);
        head.extend_from_slice(&buf[..missing]);
        reader.notify_read(n);
        fed += n;
    }
    Ok(count)
}

/// Whether every string of a schema or channel record `body` (and a channel's metadata map) fits
/// inside it. The `mcap` crate reserves a string's declared length before reading it: a damaged
/// length made it ask for 2.8 GB (`tests/fuzz.rs::mcap_joint_states`, libFuzzer).
fn strings_fit(opcode: u8, body: &[u8]) -> bool {
    let u32_at = |at: usize| body.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
    // A string at `at`: where it ends, if inside `end`.
    let string = |at: usize, end: usize| u32_at(at).and_then(|n| (at + 4).checked_add(n)).filter(|&e| e <= end);
    let (mut at, strings) = match opcode {
        // id; name, encoding (the data's length the crate checks).
        mcap::records::op::SCHEMA => (2, 2),
        // id, schema id; topic, message encoding; then the metadata map.
        mcap::records::op::CHANNEL => (4, 2),
        _ => return true,
    };
    for _ in 0..strings {
        match string(at, body.len()) {
            Some(e) => at = e,
            None => return false,
        }
    }
    if opcode == mcap::records::op::CHANNEL {
        // The map: its length in bytes, then key and value strings.
        let Some(end) = string(at, body.len()) else { return false };
        at += 4;
        while at < end {
            match string(at, end).and_then(|k| string(k, end)) {
                Some(e) => at = e,
                None => return false,
            }
        }
    }
    true
}

/// Fill `buf` from `source` as far as it goes (less only at its end); the bytes read.
fn read_up_to(source: &mut impl std::io::Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match source.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// The longest record (bytes) an MCAP of `file_len` bytes may hold, inside a chunk or not: 64 MiB
/// or four times the file (a record decompressed from a chunk may be larger than its share of
/// the file), at most 1 GiB. A damaged length field past it is an error, not an allocation.
fn record_length_limit(file_len: usize) -> usize {
    (64usize << 20).max(file_len.saturating_mul(4)).min(1 << 30)
}

/// The bag header's `index_pos` (where the index section starts), checked against the file's
/// length: the `rosbag` crate slices the file there, and a cut or unclosed bag would make it
/// panic.
fn bag_index_pos(bytes: &[u8], file_len: usize, path: &Path) -> Result<usize> {
    let damaged = || RecordingError::file(path, "a ROS 1 bag whose header record is damaged");
    let u32_at = |at: usize| -> Option<usize> { bytes.get(at..at + 4).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize) };
    let start = BAG_MAGIC.len();
    let header_len = u32_at(start).ok_or_else(damaged)?;
    let header = bytes.get(start + 4..start + 4 + header_len).ok_or_else(damaged)?;
    // The record's data (padding in bags rosbag writes) follows its header: the chunks start
    // after both, and an index before that is no index (the rosbag crate slices from the one to
    // the other, and panics when they cross).
    let data_len = u32_at(start + 4 + header_len).ok_or_else(damaged)?;
    let chunks_start = (start + 8 + header_len).checked_add(data_len).ok_or_else(damaged)?;
    let mut at = 0;
    while at + 4 <= header.len() {
        let n = u32::from_le_bytes([header[at], header[at + 1], header[at + 2], header[at + 3]]) as usize;
        let field = header.get(at + 4..at + 4 + n).ok_or_else(damaged)?;
        if let Some(v) = field.strip_prefix(b"index_pos=") {
            let v: [u8; 8] = v.try_into().map_err(|_| damaged())?;
            let pos = u64::from_le_bytes(v) as usize;
            if pos == 0 {
                return Err(RecordingError::file(path, "a ROS 1 bag without an index (its recording was not closed); `rosbag reindex` repairs it"));
            }
            if pos < chunks_start {
                return Err(RecordingError::file(path, format!("a ROS 1 bag whose header record is damaged: its index at byte {pos} is inside the header record (which ends at byte {chunks_start})")));
            }
            if pos > file_len {
                return Err(RecordingError::file(
                    path,
                    format!("a truncated ROS 1 bag: its index should start at byte {pos} of {file_len} (was the copy or the recording cut short? `rosbag reindex` repairs a cut recording)"),
                ));
            }
            return Ok(pos);
        }
        at += 4 + n;
    }
    Err(damaged())
}

/// [`for_each`] over a ROS 1 bag.
fn for_each_bag(path: &Path, mut visit: impl FnMut(&Message) -> Result<()>) -> Result<usize> {
    {
        // The header record (4 kB in bags rosbag writes) is all the check needs.
        use std::io::Read;
        let cannot = |e: std::io::Error| RecordingError::file(path, format!("cannot read: {e}"));
        let f = dvrk_kin::text_file::open_input(path)?;
        let file_len = f.metadata().map_err(cannot)?.len() as usize;
        let mut head = Vec::new();
        f.take(1 << 16).read_to_end(&mut head).map_err(cannot)?;
        bag_index_pos(&head, file_len, path)?;
    }
    let bag = rosbag::RosBag::new(path).map_err(|e| RecordingError::file(path, format!("not a readable ROS 1 bag: {e}")))?;
    let mut connections: BTreeMap<u32, (String, String)> = BTreeMap::new();
    let mut count = 0usize;
    let damaged = |count: usize, e: rosbag::Error| RecordingError::file(path, format!("damaged after {count} message(s): {}", e.to_string().trim_start_matches("rosbag::Error: ")));
    for record in bag.chunk_records() {
        let rosbag::ChunkRecord::Chunk(chunk) = record.map_err(|e| damaged(count, e))? else {
            continue;
        };
        for m in chunk.messages() {
            match m.map_err(|e| damaged(count, e))? {
                rosbag::MessageRecord::Connection(c) => {
                    connections.insert(c.id, (c.topic.to_string(), ros2_type_name(c.tp)));
                }
                rosbag::MessageRecord::MessageData(d) => {
                    count += 1;
                    let Some((topic, schema)) = connections.get(&d.conn_id) else {
                        return Err(RecordingError::file(path, format!("message {count} is on connection {} that no connection record announces", d.conn_id)));
                    };
                    visit(&Message { index: count, topic, schema, encoding: Encoding::Ros1, log_time_ns: d.time, data: d.data })?;
                }
            }
        }
    }
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn type_names_take_ros2_spelling() {
        assert_eq!(ros2_type_name("sensor_msgs/JointState"), "sensor_msgs/msg/JointState");
        assert_eq!(ros2_type_name("sensor_msgs/msg/JointState"), "sensor_msgs/msg/JointState");
        assert_eq!(ros2_type_name("foxglove.PoseInFrame"), "foxglove.PoseInFrame");
    }

    #[test]
    fn containers_are_told_by_their_first_bytes() {
        assert_eq!(container_of(b"\x89MCAP0\r\nrest"), Some(Container::Mcap));
        assert_eq!(container_of(b"#ROSBAG V2.0\n"), Some(Container::Bag));
        assert_eq!(container_of(b"#ROSBAG V1.2\n"), None);
        assert_eq!(container_of(b"time,q1"), None);
    }

    #[test]
    fn a_cut_bag_is_named_not_a_panic() {
        let mut b = BAG_MAGIC.to_vec();
        let field = [b"index_pos=".as_slice(), &5000u64.to_le_bytes()].concat();
        let header = [(field.len() as u32).to_le_bytes().as_slice(), &field].concat();
        b.extend_from_slice(&(header.len() as u32).to_le_bytes());
        b.extend_from_slice(&header);
        b.extend_from_slice(&[0u8; 100]);
        let e = bag_index_pos(&b, b.len(), Path::new("cut.bag")).unwrap_err().to_string();
        assert!(e.contains("cut.bag") && e.contains("truncated ROS 1 bag") && e.contains("byte 5000 of 139"), "{e}");
        assert_eq!(bag_index_pos(&b, 6000, Path::new("whole.bag")).unwrap(), 5000);
        let e = bag_index_pos(&b[..20], 6000, Path::new("cut.bag")).unwrap_err().to_string();
        assert!(e.contains("header record is damaged"), "{e}");
        // An index inside the header record's 4 kB of padding (a flipped byte; the rosbag crate
        // panicked slicing from the padding's end back to it): named, not read.
        let mut b = BAG_MAGIC.to_vec();
        let field = [b"index_pos=".as_slice(), &1000u64.to_le_bytes()].concat();
        let header = [(field.len() as u32).to_le_bytes().as_slice(), &field].concat();
        b.extend_from_slice(&(header.len() as u32).to_le_bytes());
        b.extend_from_slice(&header);
        b.extend_from_slice(&4096u32.to_le_bytes());
        b.extend_from_slice(&[b' '; 4096]);
        let e = bag_index_pos(&b, 9000, Path::new("flipped.bag")).unwrap_err().to_string();
        assert!(e.contains("flipped.bag") && e.contains("index at byte 1000 is inside the header record (which ends at byte 4139)"), "{e}");
    }

    /// Twenty messages `hello 000` .. `hello 019` on one channel, written with `options`.
    fn hello_mcap(options: mcap::WriteOptions) -> Vec<u8> {
        let mut w = options.create(std::io::Cursor::new(Vec::new())).unwrap();
        let schema = w.add_schema("std_msgs/msg/String", "ros2msg", b"string data").unwrap();
        let channel = w.add_channel(schema, "/x", "cdr", &BTreeMap::new()).unwrap();
        for i in 0..20u64 {
            let header = mcap::records::MessageHeader { channel_id: channel, sequence: i as u32, log_time: i, publish_time: i };
            w.write_to_known_channel(&header, format!("hello {i:03}").as_bytes()).unwrap();
        }
        w.finish().unwrap();
        w.into_inner().into_inner()
    }

    #[test]
    fn a_chunk_whose_crc_does_not_match_is_an_error() {
        let mut bytes = hello_mcap(mcap::WriteOptions::new().compression(None));
        assert_eq!(for_each_mcap(&bytes, Path::new("good.mcap"), |_| Ok(())).unwrap(), 20);
        let at = bytes.windows(9).position(|x| x == b"hello 010").unwrap();
        bytes[at + 6] = b'9';
        let e = for_each_mcap(&bytes, Path::new("bad.mcap"), |_| Ok(())).unwrap_err().to_string();
        assert!(e.starts_with("bad.mcap: a chunk ending by byte") && e.contains("is damaged: its CRC is"), "{e}");
        // Without chunks the data section's CRC (in its end record) guards the messages.
        let mut bytes = hello_mcap(mcap::WriteOptions::new().use_chunks(false));
        assert_eq!(for_each_mcap(&bytes, Path::new("good.mcap"), |_| Ok(())).unwrap(), 20);
        let at = bytes.windows(9).position(|x| x == b"hello 010").unwrap();
        bytes[at + 6] = b'9';
        let e = for_each_mcap(&bytes, Path::new("flat.mcap"), |_| Ok(())).unwrap_err().to_string();
        assert!(e.starts_with("flat.mcap: the data section is damaged: its CRC is"), "{e}");
    }
}
