//! CDR (XCDR1) as ROS 2 writes it: a 4-byte encapsulation header (`00 01 00 00` for little
//! endian, `00 00 00 00` for big endian), then the fields, each primitive aligned to its own
//! size counted from the first byte after the header. Strings are a u32 length that counts the
//! terminating NUL, the bytes and the NUL; sequences are a u32 count and the elements.
//!
//! The reader also reads ROS 1's serialization (rosbag v2.0 messages), which is the same
//! little-endian layout without the encapsulation header and without alignment, and strings
//! without the NUL: [`CdrReader::ros1`].
//!
//! The reader checks every length against the bytes left, so a damaged message is an error
//! naming the field, never a panic or a huge allocation.

/// Encapsulation header of little-endian plain CDR.
pub const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Writes a little-endian CDR message.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// A message with its encapsulation header.
    pub fn new() -> Self {
        let mut buf = Vec::with_capacity(128);
        buf.extend_from_slice(&CDR_LE);
        CdrWriter { buf }
    }
    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - 4;
        let pad = (n - pos % n) % n;
        self.buf.extend(std::iter::repeat_n(0u8, pad));
    }
    /// A u32 (aligned to 4).
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// An i32 (aligned to 4).
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// An f64 (aligned to 8).
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// A bool (one byte, no alignment).
    pub fn bool(&mut self, v: bool) {
        self.buf.push(v as u8);
    }
    /// A u8 (one byte, no alignment).
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    /// A string: length with the NUL, bytes, NUL.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    /// A sequence of f64.
    pub fn f64_seq(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        for x in v {
            self.f64(*x);
        }
    }
    /// A sequence of f32 (narrowed from f64).
    pub fn f32_seq(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        for x in v {
            self.u32((*x as f32).to_bits());
        }
    }
    /// A sequence of i32.
    pub fn i32_seq(&mut self, v: &[i32]) {
        self.u32(v.len() as u32);
        for x in v {
            self.i32(*x);
        }
    }
    /// A sequence of strings.
    pub fn string_seq(&mut self, v: &[String]) {
        self.u32(v.len() as u32);
        for s in v {
            self.string(s);
        }
    }
    /// The bytes of the message.
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads a CDR message (either byte order), or a ROS 1 message.
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
    little: bool,
    /// ROS 1: no alignment padding.
    packed: bool,
}

impl<'a> CdrReader<'a> {
    /// Check the encapsulation header.
    pub fn new(bytes: &'a [u8]) -> Result<Self, String> {
        if bytes.len() < 4 {
            return Err(format!("{} byte(s): shorter than the 4-byte CDR header", bytes.len()));
        }
        let little = match (bytes[0], bytes[1]) {
            (0x00, 0x01) => true,
            (0x00, 0x00) => false,
            (a, b) => return Err(format!("CDR header {a:02x} {b:02x} is not plain CDR (00 00 or 00 01)")),
        };
        Ok(CdrReader { data: &bytes[4..], pos: 0, little, packed: false })
    }
    /// A ROS 1 message (rosbag v2.0): little endian, packed, no header.
    pub fn ros1(bytes: &'a [u8]) -> Self {
        CdrReader { data: bytes, pos: 0, little: true, packed: true }
    }
    /// True for a ROS 1 message (its std_msgs/Header starts with a `seq`).
    pub fn is_ros1(&self) -> bool {
        self.packed
    }
    fn align(&mut self, n: usize) {
        if !self.packed {
            self.pos += (n - self.pos % n) % n;
        }
    }
    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|e| *e <= self.data.len());
        match end {
            Some(e) => {
                let s = &self.data[self.pos..e];
                self.pos = e;
                Ok(s)
            }
            None => Err(format!("{field}: the message ends at byte {} of its payload, {n} more byte(s) needed", self.data.len())),
        }
    }
    /// A u32.
    pub fn u32(&mut self, field: &str) -> Result<u32, String> {
        self.align(4);
        let b: [u8; 4] = self.take(4, field)?.try_into().map_err(|_| format!("{field}: short read"))?;
        Ok(if self.little { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) })
    }
    /// An i32.
    pub fn i32(&mut self, field: &str) -> Result<i32, String> {
        self.u32(field).map(|v| v as i32)
    }
    /// An f64.
    pub fn f64(&mut self, field: &str) -> Result<f64, String> {
        self.align(8);
        let b: [u8; 8] = self.take(8, field)?.try_into().map_err(|_| format!("{field}: short read"))?;
        Ok(if self.little { f64::from_le_bytes(b) } else { f64::from_be_bytes(b) })
    }
    /// A string (UTF-8; the NUL is dropped).
    pub fn string(&mut self, field: &str) -> Result<String, String> {
        let n = self.u32(field)? as usize;
        let bytes = self.take(n, field)?;
        let bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(bytes.to_vec()).map_err(|_| format!("{field}: not UTF-8"))
    }
    /// A sequence length, checked against the bytes left (`min_size` per element).
    pub fn seq_len(&mut self, field: &str, min_size: usize) -> Result<usize, String> {
        let n = self.u32(field)? as usize;
        let left = self.data.len().saturating_sub(self.pos);
        if n.saturating_mul(min_size) > left {
            return Err(format!("{field}: {n} element(s) announced but only {left} byte(s) left"));
        }
        Ok(n)
    }
    /// A sequence of f64.
    pub fn f64_seq(&mut self, field: &str) -> Result<Vec<f64>, String> {
        let n = self.seq_len(field, 8)?;
        // Exactly `n` (bounded by the bytes left): a reader keeps the decoded samples, and a
        // collected Result grows its Vec by doubling (8 for a PSM's 7 joints, 10 MB more on a
        // 5-minute recording). The element is named only in an error.
        let mut v = Vec::with_capacity(n);
        for i in 0..n {
            v.push(self.f64(field).map_err(|e| e.replacen(field, &format!("{field}[{i}]"), 1))?);
        }
        Ok(v)
    }
    /// A sequence of f32 (widened to f64: sensor_msgs/Joy's axes).
    pub fn f32_seq(&mut self, field: &str) -> Result<Vec<f64>, String> {
        let n = self.seq_len(field, 4)?;
        let mut v = Vec::with_capacity(n);
        for i in 0..n {
            let bits = self.u32(field).map_err(|e| e.replacen(field, &format!("{field}[{i}]"), 1))?;
            v.push(f32::from_bits(bits) as f64);
        }
        Ok(v)
    }
    /// A sequence of i32 (sensor_msgs/Joy's buttons).
    pub fn i32_seq(&mut self, field: &str) -> Result<Vec<i32>, String> {
        let n = self.seq_len(field, 4)?;
        let mut v = Vec::with_capacity(n);
        for i in 0..n {
            v.push(self.i32(field).map_err(|e| e.replacen(field, &format!("{field}[{i}]"), 1))?);
        }
        Ok(v)
    }
    /// A sequence of strings.
    pub fn string_seq(&mut self, field: &str) -> Result<Vec<String>, String> {
        let n = self.seq_len(field, if self.packed { 4 } else { 5 })?;
        (0..n).map(|i| self.string(&format!("{field}[{i}]"))).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_after_the_header() {
        let mut w = CdrWriter::new();
        w.i32(7);
        w.string("ab");
        w.f64(1.5);
        let b = w.finish();
        // header 4 | i32 at 0..4 | len 4..8 = 3 | "ab\0" 8..11 | pad to 16 | f64 16..24
        assert_eq!(b.len(), 4 + 24);
        assert_eq!(&b[4..8], &7i32.to_le_bytes());
        assert_eq!(&b[8..12], &3u32.to_le_bytes());
        assert_eq!(&b[12..15], b"ab\0");
        assert_eq!(&b[15..20], &[0, 0, 0, 0, 0]);
        assert_eq!(&b[20..28], &1.5f64.to_le_bytes());
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.i32("a").unwrap(), 7);
        assert_eq!(r.string("b").unwrap(), "ab");
        assert_eq!(r.f64("c").unwrap(), 1.5);
        let e = r.f64("d").unwrap_err();
        assert_eq!(e, "d: the message ends at byte 24 of its payload, 8 more byte(s) needed");
    }

    /// A sequence decodes to exactly its length, and a short one names the element it ends in.
    #[test]
    fn f64_sequences_are_exact_and_name_their_element() {
        let mut w = CdrWriter::new();
        w.f64_seq(&[0.5; 7]);
        let b = w.finish();
        let v = CdrReader::new(&b).unwrap().f64_seq("q").unwrap();
        assert_eq!((v.len(), v.capacity(), v[6]), (7, 7, 0.5));
        // Length 2 at payload 0..4, then 16 bytes: the count passes, but the f64s start at 8
        // after padding, so the second ends past the payload.
        let mut b = vec![0, 1, 0, 0];
        b.extend_from_slice(&2u32.to_le_bytes());
        b.extend_from_slice(&[0; 16]);
        let e = CdrReader::new(&b).unwrap().f64_seq("q").unwrap_err();
        assert_eq!(e, "q[1]: the message ends at byte 20 of its payload, 8 more byte(s) needed");
    }

    #[test]
    fn ros1_is_packed_and_has_no_header() {
        let mut b = Vec::new();
        b.extend_from_slice(&7u32.to_le_bytes());
        b.extend_from_slice(&2u32.to_le_bytes());
        b.extend_from_slice(b"ab");
        b.extend_from_slice(&1.5f64.to_le_bytes());
        let mut r = CdrReader::ros1(&b);
        assert_eq!(r.u32("a").unwrap(), 7);
        assert_eq!(r.string("b").unwrap(), "ab");
        assert_eq!(r.f64("c").unwrap(), 1.5);
        assert!(r.u32("d").unwrap_err().starts_with("d: the message ends at byte 18"));
    }

    #[test]
    fn big_endian_and_bad_headers() {
        let mut b = vec![0, 0, 0, 0];
        b.extend_from_slice(&5u32.to_be_bytes());
        assert_eq!(CdrReader::new(&b).unwrap().u32("x").unwrap(), 5);
        assert!(CdrReader::new(&[0x00, 0x03, 0, 0]).unwrap_err().contains("00 03"));
        let mut huge = CDR_LE.to_vec();
        huge.extend_from_slice(&u32::MAX.to_le_bytes());
        let e = CdrReader::new(&huge).unwrap().f64_seq("position").unwrap_err();
        assert!(e.contains("4294967295 element(s) announced but only 0 byte(s) left"), "{e}");
    }
}
