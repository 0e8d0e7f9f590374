//! The plain CSV joint log of `dvrk discrepancy --format csv` (the conventions of
//! [`crate::recording::plain_csv`]: a header row naming every column, `#` comment lines):
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
//!
//! A tracked marker body NAME (the kinematic channel, `--marker-topic NAME`) adds the pose
//! columns of the plain CSV: `NAME.x,NAME.y,NAME.z` (m, tracker frame) and
//! `NAME.qx,NAME.qy,NAME.qz,NAME.qw` (unit quaternion), empty on rows without a tracker sample.

use super::joint_log::JointLog;
use crate::recording::error::{RecordingError, Result};
use std::fmt::Write as _;
use std::path::Path;


/// A CSV joint log read for a model.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvLog {
    pub log: JointLog,
    /// What the reader assumed or ignored (no setpoints, unknown columns).
    pub notes: Vec<String>,
}

/// Read the CSV joint log at `path` for `model`'s joints.
pub fn read(path: &Path, model: &dvrk_kin::Model) -> Result<CsvLog> {
    let text = crate::recording::read_csv_text(path)?;
    parse(&text, path, model)
}

/// Parse CSV joint-log text for `model`'s joints; `path` names it in errors.
pub fn parse(text: &str, path: &Path, model: &dvrk_kin::Model) -> Result<CsvLog> {
    let n = model.nq();
    let err = |line: u64, msg: String| RecordingError::file(path, format!("line {line}: {msg}"));
    let mut reader = csv::ReaderBuilder::new().comment(Some(b'#')).flexible(false).trim(csv::Trim::All).from_reader(text.as_bytes());
    let header: Vec<String> = reader.headers().map_err(|e| RecordingError::file(path, format!("cannot read the header: {e}")))?.iter().map(String::from).collect();
    let col = |name: &str| header.iter().position(|h| h == name);
    let names = |prefix: &'static str| (1..=n).map(move |k| format!("{prefix}{k}"));
    // Columns beyond the model's joints: a recording of another arm.
    let beyond: Vec<&String> = header.iter().filter(|h| ["q", "tau", "setpoint"].iter().any(|p| h.strip_prefix(p).and_then(|k| k.parse::<usize>().ok()).is_some_and(|k| k == 0 || k > n))).collect();
    if !beyond.is_empty() {
        let list: Vec<&str> = beyond.iter().map(|s| s.as_str()).collect();
        return Err(RecordingError::file(path, format!("column(s) {} beyond the model's {n} joints (q1..q{n}, tau1..tau{n}, setpoint1..setpoint{n})", list.join(", "))));
    }
    let required: Vec<String> = std::iter::once("time".to_string()).chain(names("q")).chain(names("tau")).collect();
    let setpoints: Vec<String> = names("setpoint").collect();
    let has_setpoints = setpoints.iter().any(|s| col(s).is_some());
    let missing: Vec<&String> = required.iter().chain(if has_setpoints { &setpoints[..] } else { &[] }).filter(|c| col(c).is_none()).collect();
    if !missing.is_empty() {
        let list: Vec<&str> = missing.iter().map(|s| s.as_str()).collect();
        return Err(RecordingError::file(path, format!("no column(s) {} for the model's {n} joints; the header is: {}", list.join(", "), dvrk_kin::text_file::excerpt(&header.join(","), 80))));
    }
    let index = |names: &[String]| names.iter().map(|c| col(c).unwrap_or(0)).collect::<Vec<usize>>();
    let (time, q, tau) = (col("time").unwrap_or(0), index(&required[1..=n]), index(&required[n + 1..]));
    let sp = has_setpoints.then(|| index(&setpoints));
    let mut notes = Vec::new();
    // Pose columns (NAME.x, ...) are the tracker's, read by [`read_markers`].
    let ignored: Vec<&str> = header.iter().filter(|h| !required.contains(h) && !setpoints.contains(h) && !h.contains('.')).map(String::as_str).collect();
    if !ignored.is_empty() {
        notes.push(format!("{}: ignored column(s) {}", path.display(), ignored.join(", ")));
    }
    if !has_setpoints {
        notes.push(format!("{}: {}", path.display(), super::joint_log::NO_SETPOINTS));
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
                _ => Err(err(line, format!("column `{}`: `{}` is not a finite number", dvrk_kin::text_file::excerpt(&header[i], 80), dvrk_kin::text_file::excerpt(s, 80)))),
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
        return Err(RecordingError::file(path, "the header is followed by no data row"));
    }
    Ok(CsvLog { log, notes })
}

/// The pose columns' suffixes, in order.
const POSE: [&str; 7] = ["x", "y", "z", "qx", "qy", "qz", "qw"];

/// The body name a marker's pose columns carry: its topic's one segment that is not `mocap` or
/// `pose` (`/mocap/marker_tool_roll/pose` -> `marker_tool_roll`), else the topic itself.
pub fn marker_name(topic: &str) -> String {
    let parts: Vec<&str> = topic.split('/').filter(|s| !s.is_empty() && *s != "mocap" && *s != "pose").collect();
    match parts.as_slice() {
        [one] => one.to_string(),
        _ => topic.trim_start_matches('/').replace('/', "_"),
    }
}

/// `log` as CSV text (every number in its shortest exact form, so it reads back equal), with the
/// setpoint columns and, if the log has a tracked marker, its pose columns (empty on rows without
/// a tracker sample at that time).
pub fn write(log: &JointLog) -> String {
    let n = log.names.len();
    let mut out = format!("# dvrk discrepancy joint log: time (s); qK: measured position, tauK: measured effort, setpointK: commanded position of joint K (rad or m, N·m or N)\n# joints: {}\ntime", log.names.join(", "));
    for prefix in ["q", "tau", "setpoint"] {
        for k in 1..=n {
            let _ = write!(out, ",{prefix}{k}");
        }
    }
    if let Some(m) = &log.markers {
        let name = marker_name(&m.topic);
        for c in POSE {
            let _ = write!(out, ",{name}.{c}");
        }
    }
    out.push('\n');
    let mut next = 0;
    for i in 0..log.len() {
        let _ = write!(out, "{}", log.t[i]);
        for x in log.position[i].iter().chain(&log.effort[i]).chain(&log.setpoint[i]) {
            let _ = write!(out, ",{x}");
        }
        if let Some(m) = &log.markers {
            while next < m.t.len() && m.t[next] < log.t[i] - 1e-9 {
                next += 1;
            }
            if next < m.t.len() && (m.t[next] - log.t[i]).abs() <= 1e-9 {
                let p = &m.poses[next];
                let q = nalgebra::UnitQuaternion::from_rotation_matrix(&p.rotation);
                let v = p.translation.vector;
                for x in [v.x, v.y, v.z, q.i, q.j, q.k, q.w] {
                    let _ = write!(out, ",{x}");
                }
            } else {
                out.push_str(",,,,,,,");
            }
        }
        out.push('\n');
    }
    out
}

/// The tracked marker body `name` of the CSV joint log at `path`, on model frame `frame`: its
/// pose columns on the rows that have them. A row with some but not all of them is an error.
pub fn read_markers(path: &Path, name: &str, frame: usize) -> Result<super::marker_log::MarkerLog> {
    let text = crate::recording::read_csv_text(path)?;
    let name = marker_name(name);
    let mut reader = csv::ReaderBuilder::new().comment(Some(b'#')).flexible(false).trim(csv::Trim::All).from_reader(text.as_bytes());
    let header: Vec<String> = reader.headers().map_err(|e| RecordingError::file(path, format!("cannot read the header: {e}")))?.iter().map(String::from).collect();
    let col = |c: &str| header.iter().position(|h| h == c);
    let cols: Vec<Option<usize>> = POSE.iter().map(|c| col(&format!("{name}.{c}"))).collect();
    let (Some(time), true) = (col("time"), cols.iter().all(Option::is_some)) else {
        let have: Vec<&str> = header.iter().filter(|h| h.contains('.')).map(|h| h.split('.').next().unwrap_or("")).collect();
        return Err(RecordingError::file(path, format!("--marker-topic {name}: no columns time, {name}.x .. {name}.qw (pose columns of: {})", if have.is_empty() { "none".to_string() } else { have.join(", ") })));
    };
    let cols: Vec<usize> = cols.into_iter().flatten().collect();
    let mut out = super::marker_log::MarkerLog { topic: name.clone(), frame, t: Vec::new(), poses: Vec::new() };
    for rec in reader.records() {
        let rec = rec.map_err(|e| RecordingError::file(path, format!("line {}: {e}", e.position().map_or(0, |p| p.line()))))?;
        let line = rec.position().map_or(0, |p| p.line());
        let cells: Vec<&str> = cols.iter().map(|&i| rec.get(i).unwrap_or("")).collect();
        if cells.iter().all(|c| c.is_empty()) {
            continue;
        }
        let v: Vec<f64> = cells.iter().map(|c| c.parse::<f64>().ok().filter(|x| x.is_finite())).collect::<Option<_>>().ok_or_else(|| RecordingError::file(path, format!("line {line}: {name}'s pose columns hold {}: all seven finite numbers, or all empty", dvrk_kin::text_file::excerpt(&format!("{cells:?}"), 80))))?;
        let t: f64 = rec.get(time).unwrap_or("").parse().map_err(|_| RecordingError::file(path, format!("line {line}: column `time` is not a number")))?;
        let q = crate::recording::plain_csv::unit_quaternion(v[3], v[4], v[5], v[6]).map_err(|e| RecordingError::file(path, format!("line {line}: {name}: {e}")))?;
        out.t.push(t);
        out.poses.push(dvrk_kin::Pose::from_parts(nalgebra::Translation3::new(v[0], v[1], v[2]), q.to_rotation_matrix()));
    }
    if out.t.len() < 50 {
        return Err(RecordingError::file(path, format!("--marker-topic {name}: {} poses (need at least 50)", out.t.len())));
    }
    Ok(out)
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
            ..JointLog::default()
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

    /// A tracked marker on every other row: its pose columns read back (to 1e-12), empty cells
    /// skipped; a row with only some of them, or too few poses, is refused naming them.
    #[test]
    fn marker_pose_columns_read_back() {
        use nalgebra::{Rotation3, Translation3, Vector3};
        let m = psm();
        let mut l = log(&m);
        let n = 120;
        l.t = (0..n).map(|i| i as f64 * 1e-3).collect();
        for v in [&mut l.setpoint, &mut l.position, &mut l.effort] {
            *v = (0..n).map(|i| vec![i as f64 * 1e-4; m.nq()]).collect();
        }
        let poses: Vec<dvrk_kin::Pose> = (0..n / 2).map(|i| dvrk_kin::Pose::from_parts(Translation3::new(0.1, -0.2, i as f64 * 1e-3), Rotation3::new(Vector3::new(0.3, i as f64 * 0.01, -0.2)))).collect();
        l.markers = Some(crate::recording::marker_log::MarkerLog { topic: "/mocap/marker_tool_roll/pose".into(), frame: 9, t: (0..n / 2).map(|i| 2.0 * i as f64 * 1e-3).collect(), poses: poses.clone() });
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.csv");
        let text = write(&l);
        std::fs::write(&path, &text).unwrap();
        let back = read_markers(&path, "marker_tool_roll", 9).unwrap();
        assert_eq!(back.t.len(), n / 2);
        for (a, b) in back.poses.iter().zip(&poses) {
            let d = a.inverse() * b;
            assert!(d.translation.vector.norm() < 1e-12 && (d.rotation.matrix() - nalgebra::Matrix3::identity()).norm() < 1e-12);
        }
        // The joints read as before, the pose columns not listed as ignored.
        assert!(parse(&text, &path, &m).unwrap().notes.is_empty());
        let cut: String = text.lines().map(|line| if line.starts_with("0.002,") { line.rsplitn(2, ',').nth(1).unwrap().to_string() + ",\n" } else { line.to_string() + "\n" }).collect();
        std::fs::write(&path, cut).unwrap();
        let e = read_markers(&path, "marker_tool_roll", 9).unwrap_err().to_string();
        assert!(e.contains("all seven finite numbers"), "{e}");
        let e = read_markers(&path, "other", 9).unwrap_err().to_string();
        assert!(e.contains("other.x") && e.contains("marker_tool_roll"), "{e}");
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
        assert!(e.contains("/nonexistent/rec.csv: no such file"), "{e}");
    }
}
