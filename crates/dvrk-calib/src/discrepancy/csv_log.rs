//! The plain CSV joint log of `dvrk discrepancy --format csv` (the conventions of
//! [`crate::plain_csv`]: a header row naming every column, `#` comment lines):
//!
//! ```text
//! # lines starting with '#' are comments
//! time,q1,...,qN,tau1,...,tauN,setpoint1,...,setpointN
//! ```
//!
//! - `time`: s, strictly increasing (required);
//! - `q1..qN`: measured (encoder) positions, rad or m (required);
//! - `tau1..tauN`: measured efforts, N·m or N (required);
//! - `setpoint1..setpointN`: commanded positions, rad or m (optional, all or none: without them
//!   the encoders stand in for the setpoints, as for wpi-csv).
//!
//! N is the model's joint count, joint k its k-th joint. Every cell must be a finite number.

use super::joint_log::JointLog;
use crate::error::{CalibError, Result};
use std::fmt::Write as _;
use std::path::Path;

/// The note when the file has no setpoint columns.
pub const NO_SETPOINTS: &str = "no setpoint columns: the encoder positions stand in for the setpoints (the tracking channel then replays the recording's own motion)";

/// A CSV joint log read for a model.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvLog {
    pub log: JointLog,
    /// What the reader assumed or ignored (no setpoints, unknown columns).
    pub notes: Vec<String>,
}

/// Read the CSV joint log at `path` for `model`'s joints.
pub fn read(path: &Path, model: &dvrk_kin::Model) -> Result<CsvLog> {
    let text = std::fs::read_to_string(path).map_err(|e| CalibError::file(path, format!("cannot read: {e}")))?;
    parse(&text, path, model)
}

/// Parse CSV joint-log text for `model`'s joints; `path` names it in errors.
pub fn parse(text: &str, path: &Path, model: &dvrk_kin::Model) -> Result<CsvLog> {
    let n = model.nq();
    let err = |line: u64, msg: String| CalibError::file(path, format!("line {line}: {msg}"));
    let mut reader = csv::ReaderBuilder::new().comment(Some(b'#')).flexible(false).trim(csv::Trim::All).from_reader(text.as_bytes());
    let header: Vec<String> = reader.headers().map_err(|e| CalibError::file(path, format!("cannot read the header: {e}")))?.iter().map(String::from).collect();
    let col = |name: &str| header.iter().position(|h| h == name);
    let names = |prefix: &'static str| (1..=n).map(move |k| format!("{prefix}{k}"));
    // Columns beyond the model's joints: a recording of another arm.
    let beyond: Vec<&String> = header.iter().filter(|h| ["q", "tau", "setpoint"].iter().any(|p| h.strip_prefix(p).and_then(|k| k.parse::<usize>().ok()).is_some_and(|k| k == 0 || k > n))).collect();
    if !beyond.is_empty() {
        let list: Vec<&str> = beyond.iter().map(|s| s.as_str()).collect();
        return Err(CalibError::file(path, format!("column(s) {} beyond the model's {n} joints (q1..q{n}, tau1..tau{n}, setpoint1..setpoint{n})", list.join(", "))));
    }
    let required: Vec<String> = std::iter::once("time".to_string()).chain(names("q")).chain(names("tau")).collect();
    let setpoints: Vec<String> = names("setpoint").collect();
    let has_setpoints = setpoints.iter().any(|s| col(s).is_some());
    let missing: Vec<&String> = required.iter().chain(if has_setpoints { &setpoints[..] } else { &[] }).filter(|c| col(c).is_none()).collect();
    if !missing.is_empty() {
        let list: Vec<&str> = missing.iter().map(|s| s.as_str()).collect();
        return Err(CalibError::file(path, format!("no column(s) {} for the model's {n} joints; the header is: {}", list.join(", "), header.join(","))));
    }
    let index = |names: &[String]| names.iter().map(|c| col(c).unwrap_or(0)).collect::<Vec<usize>>();
    let (time, q, tau) = (col("time").unwrap_or(0), index(&required[1..=n]), index(&required[n + 1..]));
    let sp = has_setpoints.then(|| index(&setpoints));
    let mut notes = Vec::new();
    let ignored: Vec<&str> = header.iter().filter(|h| !required.contains(h) && !setpoints.contains(h)).map(String::as_str).collect();
    if !ignored.is_empty() {
        notes.push(format!("{}: ignored column(s) {}", path.display(), ignored.join(", ")));
    }
    if !has_setpoints {
        notes.push(format!("{}: {NO_SETPOINTS}", path.display()));
    }
    let mut log = JointLog { names: model.joints.iter().map(|j| j.name.clone()).collect(), ..Default::default() };
    let mut record = csv::StringRecord::new();
    loop {
        match reader.read_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => return Err(err(e.position().map_or(0, |p| p.line()), e.to_string())),
        }
        let line = record.position().map_or(0, |p| p.line());
        let cell = |i: usize| -> Result<f64> {
            let s = record.get(i).unwrap_or("");
            match s.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ if s.is_empty() => Err(err(line, format!("column `{}` is empty", header[i]))),
                _ => Err(err(line, format!("column `{}`: `{s}` is not a finite number", header[i]))),
            }
        };
        let row = |cols: &[usize]| cols.iter().map(|&i| cell(i)).collect::<Result<Vec<f64>>>();
        let t = cell(time)?;
        if let Some(prev) = log.t.last().filter(|p| t <= **p) {
            return Err(err(line, format!("time {t} s does not increase (the row before is at {prev} s)")));
        }
        let position = row(&q)?;
        log.setpoint.push(match &sp {
            Some(cols) => row(cols)?,
            None => position.clone(),
        });
        log.t.push(t);
        log.position.push(position);
        log.effort.push(row(&tau)?);
    }
    if log.is_empty() {
        return Err(CalibError::file(path, "the header is followed by no data row"));
    }
    Ok(CsvLog { log, notes })
}

/// `log` as CSV text (every number in its shortest exact form, so it reads back equal), with the
/// setpoint columns.
pub fn write(log: &JointLog) -> String {
    let n = log.names.len();
    let mut out = format!("# dvrk discrepancy joint log: time (s); qK: measured position, tauK: measured effort, setpointK: commanded position of joint K (rad or m, N·m or N)\n# joints: {}\ntime", log.names.join(", "));
    for prefix in ["q", "tau", "setpoint"] {
        for k in 1..=n {
            let _ = write!(out, ",{prefix}{k}");
        }
    }
    out.push('\n');
    for i in 0..log.len() {
        let _ = write!(out, "{}", log.t[i]);
        for x in log.position[i].iter().chain(&log.effort[i]).chain(&log.setpoint[i]) {
            let _ = write!(out, ",{x}");
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn psm() -> dvrk_kin::Model {
        dvrk_kin::load("psm", None).unwrap()
    }

    /// Three samples of the PSM's joints with values that print long (thirds, tiny, negative).
    fn log(model: &dvrk_kin::Model) -> JointLog {
        let n = model.nq();
        let row = |i: usize, s: f64| (0..n).map(|k| s * (i * n + k + 1) as f64 / 3.0 - 1e-17).collect::<Vec<f64>>();
        JointLog {
            names: model.joints.iter().map(|j| j.name.clone()).collect(),
            t: vec![0.0, 1e-3, 2.0 / 3.0],
            setpoint: (0..3).map(|i| row(i, 0.1)).collect(),
            position: (0..3).map(|i| row(i, -0.2)).collect(),
            effort: (0..3).map(|i| row(i, 7.0)).collect(),
            markers: None,
        }
    }

    #[test]
    fn a_written_log_reads_back_equal() {
        let m = psm();
        let l = log(&m);
        let back = parse(&write(&l), Path::new("w.csv"), &m).unwrap();
        assert_eq!(back.log, l);
        assert!(back.notes.is_empty(), "{:?}", back.notes);
        // Without the setpoint columns the encoders stand in, with a note.
        let text: String = write(&l).lines().map(|line| line.split(',').take(1 + 2 * m.nq()).collect::<Vec<_>>().join(",") + "\n").collect();
        let back = parse(&text, Path::new("w.csv"), &m).unwrap();
        assert_eq!(back.log.setpoint, l.position);
        assert!(back.notes[0].contains("w.csv") && back.notes[0].contains("encoder positions stand in"), "{:?}", back.notes);
    }

    #[test]
    fn errors_name_the_file_line_and_column() {
        let m = psm();
        let p = Path::new("rec.csv");
        let text = write(&log(&m));
        let e = parse(&text.replace(",tau3,", ",torque3,"), p, &m).unwrap_err().to_string();
        assert!(e.starts_with("rec.csv: no column(s) tau3 for the model's 7 joints"), "{e}");
        let e = parse("time,q1\n0,1\n", p, &m).unwrap_err().to_string();
        assert!(e.contains("q2, q3, q4, q5, q6, q7, tau1, tau2"), "{e}");
        let e = parse(&text.replace(",setpoint5,", ",sp5,"), p, &m).unwrap_err().to_string();
        assert!(e.contains("no column(s) setpoint5"), "{e}");
        let e = parse(&text.replace(",tau1,", ",q8,"), p, &m).unwrap_err().to_string();
        assert!(e.contains("q8 beyond the model's 7 joints"), "{e}");
        // Line 4 holds the first data row (two comment lines and the header before it); the
        // header's third column is q2.
        let rows: Vec<&str> = text.lines().collect();
        let mut cells: Vec<String> = rows[3].split(',').map(String::from).collect();
        cells[2] = "NaN".into();
        let bad = text.replace(rows[3], &cells.join(","));
        assert_eq!(parse(&bad, p, &m).unwrap_err().to_string(), "rec.csv: line 4: column `q2`: `NaN` is not a finite number");
        cells[2] = String::new();
        let bad = text.replace(rows[3], &cells.join(","));
        assert_eq!(parse(&bad, p, &m).unwrap_err().to_string(), "rec.csv: line 4: column `q2` is empty");
        cells[2] = "x".into();
        let bad = text.replace(rows[3], &cells.join(","));
        assert_eq!(parse(&bad, p, &m).unwrap_err().to_string(), "rec.csv: line 4: column `q2`: `x` is not a finite number");
        // Time must increase.
        let again = format!("{}{}\n", text, rows[5]);
        let e = parse(&again, p, &m).unwrap_err().to_string();
        assert!(e.starts_with("rec.csv: line 7: time 0.6666666666666666 s does not increase"), "{e}");
        let e = parse(rows[2], p, &m).unwrap_err().to_string();
        assert!(e.contains("no data row"), "{e}");
        let e = read(Path::new("/nonexistent/rec.csv"), &m).unwrap_err().to_string();
        assert!(e.contains("/nonexistent/rec.csv: cannot read"), "{e}");
    }
}
