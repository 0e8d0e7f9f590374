//! The project's one MCAP writer: Foxglove's own (`foxglove::McapWriter`), on a context of its
//! own so that two writers in one process never see each other's channels. A run's recording
//! ([`super::Recorder`]), the synthetic tracker's and the hidden-effect generator's files all go
//! through it: ROS 2 topics with their `ros2msg` schema and `cdr` messages, Foxglove's messages
//! with the SDK's protobuf schemas ([`sdk_schema`]). Files carry the `ros2` profile and the
//! MCAP crate's default chunked compression.
//!
//! The SDK logs a sink's write error as a warning and goes on. A recording with a hole in it
//! must not be committed, so the destination is wrapped in [`Latch`], which keeps the first I/O
//! error and refuses every later write: [`McapOut::check`] reports it at once and
//! [`McapOut::finish`] fails with it.

use foxglove::{ChannelBuilder, Context, Encode, McapWriteOptions, McapWriter, McapWriterHandle, PartialMetadata, RawChannel, Schema};
use std::io::{self, Seek, SeekFrom, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// The schema and message encoding of a Foxglove message type, as the SDK publishes it.
pub fn sdk_schema<T: Encode>() -> (Schema, String) {
    (T::get_schema().expect("the SDK's message types have schemas"), T::get_message_encoding())
}

/// A ROS 2 message definition (`sensor_msgs/msg/JointState` and its text) as a schema.
pub fn ros2_schema(name: &str, definition: &str) -> Schema {
    Schema::new(name, "ros2msg", definition.as_bytes().to_vec())
}

/// The first I/O error of a writer, shared with the [`McapOut`] that owns it.
#[derive(Debug, Default)]
struct FirstError {
    failed: AtomicBool,
    error: Mutex<Option<(io::ErrorKind, String)>>,
}

impl FirstError {
    fn keep(&self, e: &io::Error) {
        let mut slot = self.error.lock().unwrap_or_else(|p| p.into_inner());
        if slot.is_none() {
            *slot = Some((e.kind(), e.to_string()));
        }
        self.failed.store(true, Ordering::Release);
    }

    fn get(&self) -> Option<io::Error> {
        if !self.failed.load(Ordering::Acquire) {
            return None;
        }
        let slot = self.error.lock().unwrap_or_else(|p| p.into_inner());
        slot.as_ref().map(|(kind, text)| io::Error::new(*kind, text.clone()))
    }
}

/// A destination that remembers its first I/O error and fails every call after it.
#[derive(Debug)]
pub struct Latch<W> {
    inner: W,
    first: Arc<FirstError>,
}

impl<W> Latch<W> {
    fn run<T>(&mut self, f: impl FnOnce(&mut W) -> io::Result<T>) -> io::Result<T> {
        if let Some(e) = self.first.get() {
            return Err(io::Error::new(e.kind(), format!("an earlier write failed: {e}")));
        }
        f(&mut self.inner).inspect_err(|e| self.first.keep(e))
    }
}

impl<W: Write> Write for Latch<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.run(|w| w.write(buf))
    }

    fn flush(&mut self) -> io::Result<()> {
        self.run(|w| w.flush())
    }
}

impl<W: Seek> Seek for Latch<W> {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.run(|w| w.seek(pos))
    }
}

/// An MCAP file being written: channels added by topic, messages logged by channel index with
/// their time, finished once.
pub struct McapOut<W: Write + Seek + Send + 'static> {
    context: Arc<Context>,
    handle: McapWriterHandle<Latch<W>>,
    first: Arc<FirstError>,
    channels: Vec<Arc<RawChannel>>,
}

impl<W: Write + Seek + Send + 'static> McapOut<W> {
    /// Start a recording into `writer` (the file's header is written now).
    pub fn new(writer: W) -> io::Result<McapOut<W>> {
        let context = Context::new();
        let first = Arc::new(FirstError::default());
        let latch = Latch { inner: writer, first: first.clone() };
        let handle = McapWriter::with_options(McapWriteOptions::new().profile("ros2"))
            .context(&context)
            .create(latch)
            .map_err(|e| first.get().unwrap_or_else(|| io::Error::other(e.to_string())))?;
        Ok(McapOut { context, handle, first, channels: Vec::new() })
    }

    /// Add a channel: its index for [`McapOut::log`]. Its schema and channel records are written
    /// with its first message (a channel never logged to does not appear in the file).
    pub fn add_channel(&mut self, topic: &str, schema: Schema, message_encoding: &str) -> io::Result<usize> {
        let channel = ChannelBuilder::new(topic)
            .schema(schema)
            .message_encoding(message_encoding)
            .context(&self.context)
            .build_raw()
            .map_err(|e| io::Error::other(format!("channel {topic}: {e}")))?;
        self.channels.push(channel);
        Ok(self.channels.len() - 1)
    }

    /// Write one message on channel `channel` at `log_time_ns` (ns; also its publish time). A
    /// write error is kept for [`McapOut::check`] and [`McapOut::finish`].
    pub fn log(&self, channel: usize, log_time_ns: u64, data: &[u8]) {
        self.channels[channel].log_with_meta(data, PartialMetadata { log_time: Some(log_time_ns) });
    }

    /// The first write error so far, if any.
    pub fn check(&self) -> io::Result<()> {
        self.first.get().map_or(Ok(()), Err)
    }

    /// Write the summary and footer and hand back the destination (flushed by the SDK), or the
    /// first error of the whole recording.
    pub fn finish(self) -> io::Result<W> {
        for c in &self.channels {
            c.close();
        }
        let closed = self.handle.close();
        if let Some(e) = self.first.get() {
            return Err(e);
        }
        let latch = closed.map_err(|e| io::Error::other(e.to_string()))?;
        Ok(latch.inner)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn messages_come_back_with_their_topic_schema_and_time() {
        let mut out = McapOut::new(Cursor::new(Vec::new())).unwrap();
        let a = out.add_channel("/a", ros2_schema("std_msgs/msg/String", "string data"), "cdr").unwrap();
        let b = out.add_channel("/b", ros2_schema("std_msgs/msg/String", "string data"), "cdr").unwrap();
        out.log(a, 1_000, b"one");
        out.log(b, 2_000, b"two");
        out.log(a, 3_000, b"three");
        let bytes = out.finish().unwrap().into_inner();
        let got: Vec<(String, String, u64, u32, Vec<u8>)> = mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(|m| {
                let m = m.unwrap();
                (m.channel.topic.clone(), m.channel.schema.as_ref().unwrap().name.clone(), m.log_time, m.sequence, m.data.to_vec())
            })
            .collect();
        let s = "std_msgs/msg/String".to_string();
        assert_eq!(got, vec![("/a".into(), s.clone(), 1_000, 1, b"one".to_vec()), ("/b".into(), s.clone(), 2_000, 1, b"two".to_vec()), ("/a".into(), s, 3_000, 2, b"three".to_vec())]);
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert_eq!(summary.stats.unwrap().message_count, 3);
    }

    /// A destination that accepts `room` bytes, then fails as a full disk does.
    struct Full {
        inner: Cursor<Vec<u8>>,
        room: usize,
    }

    impl Write for Full {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.inner.get_ref().len() + buf.len() > self.room {
                return Err(io::Error::new(io::ErrorKind::StorageFull, "no space left on device"));
            }
            self.inner.write(buf)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Seek for Full {
        fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
            self.inner.seek(pos)
        }
    }

    #[test]
    fn a_write_error_in_the_middle_fails_the_whole_file() {
        let mut out = McapOut::new(Full { inner: Cursor::new(Vec::new()), room: 4096 }).unwrap();
        let a = out.add_channel("/a", ros2_schema("std_msgs/msg/String", "string data"), "cdr").unwrap();
        let noise: Vec<u8> = (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8).collect();
        for k in 0..2000u64 {
            out.log(a, k, &noise);
        }
        let e = out.check().unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::StorageFull, "{e}");
        let e = out.finish().err().expect("a file with a failed write is not finished");
        assert!(e.to_string().contains("no space left"), "{e}");
    }
}
