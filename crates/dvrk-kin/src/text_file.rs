//! Opening and reading input files with bounds, below every format's parser: a description file
//! (model, scene, inertials, dVRK JSON, URDF, configuration) is read whole up to
//! [`MAX_TEXT_BYTES`]; a text recording (CSV) up to [`MAX_RECORDING_TEXT_BYTES`] with lines of at
//! most [`MAX_LINE_BYTES`]. Only regular files are read ([`open_input`]): a FIFO would wait for a
//! writer forever and a device (`/dev/zero`) never ends, so both are refused with one line.

use crate::error::{KinError, Result};
use std::io::Read;
use std::path::Path;

/// The largest description file (model, scene, inertials, dVRK JSON, URDF, configuration) read
/// (bytes): the dVRK's are a few kB to a few MB; a larger one is a recording or a mistake, read
/// whole into memory otherwise.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// The largest text (CSV) recording read (bytes): CSV is read whole (a 5-minute 1 kHz PSM log
/// is about 100 MB); a larger recording belongs in MCAP, which is read as it goes.
pub const MAX_RECORDING_TEXT_BYTES: u64 = 2 << 30;

/// The longest line of a text recording (bytes): a row of the dVRK's logs is under 1 kB, a wide
/// Motive export a few tens of kB.
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// At most `max` characters of `s` (file content quoted in an error message), with `…` when cut.
pub fn excerpt(s: &str, max: usize) -> String {
    match s.char_indices().nth(max) {
        Some((i, _)) => format!("{}…", &s[..i]),
        None => s.to_string(),
    }
}

/// What a path that is not a regular file is (`a FIFO (named pipe)`, `a character device`, ...).
pub fn kind(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if t.is_dir() {
        "a directory"
    } else {
        "not a regular file"
    }
}

/// Why `path` (its metadata, symlinks followed) is not readable as an input, if it is not a
/// regular file: FIFOs, devices, sockets and directories are refused.
pub fn not_regular(meta: &std::fs::Metadata) -> Option<String> {
    (!meta.is_file()).then(|| format!("is {}, not a regular file (inputs are read from files: a FIFO would wait for a writer, a device may never end)", kind(meta)))
}

/// Open the input `path`, refusing anything but a regular file (symlinks are followed) without
/// blocking on it; errors name the file.
pub fn open_input(path: &Path) -> Result<std::fs::File> {
    let file = |message: String| KinError::File { path: path.into(), message };
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => file("no such file".into()),
        _ => file(format!("cannot read: {e}")),
    })?;
    if let Some(m) = not_regular(&meta) {
        return Err(file(m));
    }
    let f = std::fs::File::open(path).map_err(|e| file(format!("cannot read: {e}")))?;
    // Checked again on what was opened (the path may have changed in between).
    match f.metadata() {
        Ok(m) if !m.is_file() => Err(file(not_regular(&m).unwrap_or_default())),
        Ok(_) => Ok(f),
        Err(e) => Err(file(format!("cannot read: {e}"))),
    }
}

/// A description file's text, refused past [`MAX_TEXT_BYTES`]; errors name the file.
pub fn read_text(path: &Path) -> Result<String> {
    let file = |message: String| KinError::File { path: path.into(), message };
    let f = open_input(path)?;
    let size = f.metadata().map_err(|e| file(format!("cannot read: {e}")))?.len();
    let too_big = |size: String| file(format!("{size} bytes: a model, scene or configuration file is at most {MAX_TEXT_BYTES} bytes (is this a recording?)"));
    if size > MAX_TEXT_BYTES {
        return Err(too_big(size.to_string()));
    }
    let mut bytes = Vec::with_capacity(size as usize);
    f.take(MAX_TEXT_BYTES + 1).read_to_end(&mut bytes).map_err(|e| file(format!("cannot read: {e}")))?;
    if bytes.len() as u64 > MAX_TEXT_BYTES {
        return Err(too_big(format!("over {MAX_TEXT_BYTES}")));
    }
    String::from_utf8(bytes).map_err(|e| file(format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to())))
}

/// A text recording (CSV) whole, read with bounds: at most `max_bytes`, lines of at most
/// `max_line` bytes, no NUL byte (a binary file); errors name the file, the line and the limit.
pub fn read_recording_text(path: &Path, max_bytes: u64, max_line: usize) -> Result<String> {
    let file = |message: String| KinError::File { path: path.into(), message };
    let f = open_input(path)?;
    let size = f.metadata().map_err(|e| file(format!("cannot read: {e}")))?.len();
    if size > max_bytes {
        return Err(file(format!("{size} bytes: a text (CSV) recording is read whole and is at most {max_bytes} bytes (convert it to MCAP)")));
    }
    let mut reader = std::io::BufReader::with_capacity(1 << 16, f.take(max_bytes + 1));
    let mut bytes: Vec<u8> = Vec::new();
    let (mut line, mut line_len) = (1u64, 0usize);
    loop {
        let chunk = match std::io::BufRead::fill_buf(&mut reader) {
            Ok([]) => break,
            Ok(c) => c,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(file(format!("cannot read: {e}"))),
        };
        for (i, &b) in chunk.iter().enumerate() {
            match b {
                b'\n' => {
                    line += 1;
                    line_len = 0;
                }
                0 => return Err(file(format!("a NUL byte at byte {} (line {line}): a binary file, not text (CSV)", bytes.len() + i))),
                _ => {
                    line_len += 1;
                    if line_len > max_line {
                        return Err(file(format!("line {line} is longer than {max_line} bytes: not a CSV recording")));
                    }
                }
            }
        }
        let n = chunk.len();
        bytes.extend_from_slice(chunk);
        std::io::BufRead::consume(&mut reader, n);
        if bytes.len() as u64 > max_bytes {
            return Err(file(format!("over {max_bytes} bytes: a text (CSV) recording is read whole and is at most {max_bytes} bytes (convert it to MCAP)")));
        }
    }
    String::from_utf8(bytes).map_err(|e| file(format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to())))
}
