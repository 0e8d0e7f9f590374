//! Which format a joint recording is in, told from the file itself: `--format auto` (the
//! default of `dvrk identify` and `dvrk discrepancy`) resolves here.

use crate::recording::error::{RecordingError, Result};
use crate::recording::message_file::{self, Container};
use std::path::Path;

/// What `--format` may say.
pub const FORMATS: [&str; 5] = ["auto", "mcap", "bag", "wpi-csv", "csv"];

/// `format`, or for `auto` the format of `path`: `mcap` or `bag` by the first bytes; for text,
/// `wpi-csv` when the first row is numbers only (no header: the wpi-csv reader then checks its
/// 21 columns), else `csv` (the plain format, which has a header). An unknown `format` is an
/// error naming the flag.
pub fn resolve(path: &Path, format: &str) -> Result<&'static str> {
    if let Some(f) = FORMATS.iter().find(|f| **f == format && **f != "auto") {
        return Ok(f);
    }
    if format != "auto" {
        return Err(RecordingError::field("--format", format!("`{format}` is not a format; valid: {}", FORMATS.join(", "))));
    }
    if !path.exists() {
        return Err(RecordingError::file(path, "no such file"));
    }
    match message_file::container(path)? {
        Some(Container::Mcap) => return Ok("mcap"),
        Some(Container::Bag) => return Ok("bag"),
        None => {}
    }
    // The first data line tells; read with a bound (a file without newlines is not read whole).
    use std::io::Read;
    let max = dvrk_kin::text_file::MAX_LINE_BYTES;
    let mut head = Vec::new();
    dvrk_kin::text_file::open_input(path)?.take(max as u64 + 1).read_to_end(&mut head).map_err(|e| RecordingError::file(path, format!("cannot read: {e}")))?;
    let full = head.len() > max;
    let mut lines = head.split(|&b| b == b'\n').enumerate().peekable();
    while let Some((i, line)) = lines.next() {
        if i >= 50 {
            break;
        }
        if full && lines.peek().is_none() {
            return Err(RecordingError::file(path, format!("line {} is longer than {max} bytes: not a CSV recording (neither MCAP nor a ROS 1 bag); give --format", i + 1)));
        }
        let Ok(line) = std::str::from_utf8(line) else {
            return Err(RecordingError::file(path, "neither MCAP, a ROS 1 bag nor text (CSV); give --format"));
        };
        if line.contains('\0') {
            return Err(RecordingError::file(path, "neither MCAP, a ROS 1 bag nor text (CSV: it holds NUL bytes); give --format"));
        }
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        let numbers = cells.iter().all(|c| c.trim().parse::<f64>().is_ok());
        return Ok(if numbers { "wpi-csv" } else { "csv" });
    }
    Err(RecordingError::file(path, "holds no data row to tell its format from; give --format"))
}

/// The note a reader adds when `format` was `auto`: what the file was read as.
pub fn auto_note(path: &Path, format: &str, resolved: &str) -> Option<String> {
    (format == "auto").then(|| format!("{}: read as {resolved} (told from the file; --format overrides)", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_are_told_by_their_content() {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, bytes: &[u8]| {
            let p = dir.path().join(name);
            std::fs::write(&p, bytes).unwrap();
            p
        };
        let wpi = write("a.txt", format!("{}\n", vec!["0.5"; 21].join(",")).as_bytes());
        assert_eq!(resolve(&wpi, "auto").unwrap(), "wpi-csv");
        let csv = write("b.csv", b"# joints: a\ntime,q1,tau1\n0,0,0\n");
        assert_eq!(resolve(&csv, "auto").unwrap(), "csv");
        let short = write("d.csv", b"0.1,0.2\n");
        assert_eq!(resolve(&short, "auto").unwrap(), "wpi-csv", "headerless numbers: the wpi-csv reader names the column count");
        let bag = write("c.dat", b"#ROSBAG V2.0\nrest");
        assert_eq!(resolve(&bag, "auto").unwrap(), "bag");
        assert_eq!(resolve(&bag, "wpi-csv").unwrap(), "wpi-csv");
        let e = resolve(&bag, "rosbag").unwrap_err().to_string();
        assert!(e.contains("--format") && e.contains("`rosbag`"), "{e}");
    }
}
