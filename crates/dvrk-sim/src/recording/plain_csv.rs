//! The plain CSV recording format: one row per tracker frame, a header naming every column.
//!
//! ```text
//! # lines starting with '#' are comments
//! time,back.x,back.y,back.z,back.qx,back.qy,back.qz,back.qw,back.m1.x,back.m1.y,back.m1.z,...,q1,q2
//! ```
//!
//! - `time`: s (required).
//! - `NAME.x, NAME.y, NAME.z` (m) and `NAME.qx, NAME.qy, NAME.qz, NAME.qw` (unit quaternion):
//!   the pose of rigid body NAME in the tracker frame. All seven, or none.
//! - `NAME.mK.x, NAME.mK.y, NAME.mK.z` (m): raw marker K (1, 2, ...) of rigid body NAME.
//! - `q1..qN` (rad, m): joint positions.
//! - An empty cell is an occlusion; `nan` counts as one, with a warning. Other columns are
//!   ignored with a warning.

use crate::recording::error::{RecordingError, Result};
use crate::recording::tracks::{BodyTrack, JointTrack, MarkerTrack, Recording};
use dvrk_kin::Pose;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

const POSE: [&str; 7] = ["x", "y", "z", "qx", "qy", "qz", "qw"];

/// A unit quaternion from `(x, y, z, w)`: renormalised when within 1 % of unit norm, an error
/// message otherwise.
pub(crate) fn unit_quaternion(x: f64, y: f64, z: f64, w: f64) -> std::result::Result<UnitQuaternion<f64>, String> {
    let q = Quaternion::new(w, x, y, z);
    let n = q.norm();
    if !(n - 1.0).abs().lt(&0.01) {
        return Err(format!("quaternion ({x}, {y}, {z}, {w}) has norm {n:.4}, not 1"));
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// Read a plain CSV recording.
pub fn read(path: &Path) -> Result<Recording> {
    let text = crate::recording::read_csv_text(path)?;
    parse(&text, path)
}

/// Parse plain CSV text; `path` names it in errors.
pub fn parse(text: &str, path: &Path) -> Result<Recording> {
    let err = |line: u64, msg: String| RecordingError::file(path, format!("line {line}: {msg}"));
    let mut reader = csv::ReaderBuilder::new().comment(Some(b'#')).flexible(false).trim(csv::Trim::All).from_reader(text.as_bytes());
    let header: Vec<String> = reader.headers().map_err(|e| RecordingError::file(path, format!("cannot read the header: {e}")))?.iter().map(String::from).collect();
    let col = |name: &str| header.iter().position(|h| h == name);
    let time = col("time").ok_or_else(|| RecordingError::file(path, format!("no `time` column; the header is: {}", dvrk_kin::text_file::excerpt(&header.join(","), 80))))?;
    // Group columns.
    let mut bodies: BTreeMap<String, [Option<usize>; 7]> = BTreeMap::new();
    let mut markers: BTreeMap<String, BTreeMap<usize, [Option<usize>; 3]>> = BTreeMap::new();
    let mut joints: Vec<(usize, usize)> = Vec::new();
    let mut ignored = Vec::new();
    for (i, h) in header.iter().enumerate() {
        if i == time {
            continue;
        }
        let parts: Vec<&str> = h.rsplitn(3, '.').collect();
        if let Some(k) = h.strip_prefix('q').and_then(|k| k.parse::<usize>().ok()).filter(|k| *k >= 1) {
            joints.push((k, i));
        } else if parts.len() == 3 && parts[1].starts_with('m') && parts[1][1..].parse::<usize>().is_ok() && ["x", "y", "z"].contains(&parts[0]) {
            let k: usize = parts[1][1..].parse().unwrap_or(0);
            let c = ["x", "y", "z"].iter().position(|a| *a == parts[0]).unwrap_or(0);
            markers.entry(parts[2].to_string()).or_default().entry(k).or_default()[c] = Some(i);
        } else if let Some((name, field)) = h.rsplit_once('.').filter(|(_, f)| POSE.contains(f)) {
            let c = POSE.iter().position(|a| *a == field).unwrap_or(0);
            bodies.entry(name.to_string()).or_default()[c] = Some(i);
        } else {
            ignored.push(h.clone());
        }
    }
    for (name, cols) in &bodies {
        if let Some(c) = cols.iter().position(|c| c.is_none()) {
            return Err(RecordingError::file(path, format!("rigid body `{name}` has pose columns but no `{name}.{}` column", POSE[c])));
        }
    }
    for (name, ms) in &markers {
        for (k, cols) in ms {
            if let Some(c) = cols.iter().position(|c| c.is_none()) {
                return Err(RecordingError::file(path, format!("marker `{name}.m{k}` lacks its `{}` column", ["x", "y", "z"][c])));
            }
        }
    }
    joints.sort();
    for (n, (k, _)) in joints.iter().enumerate() {
        if *k != n + 1 {
            return Err(RecordingError::file(path, format!("joint columns must be q1..qN without gaps; q{} is missing", n + 1)));
        }
    }
    let mut rec = Recording { source: path.display().to_string(), ..Default::default() };
    let mut tracks: Vec<BodyTrack> = bodies.keys().map(|n| BodyTrack::new(n.clone(), "")).collect();
    let mut mtracks: Vec<MarkerTrack> = markers
        .iter()
        .map(|(n, ms)| MarkerTrack { body: n.clone(), names: ms.keys().map(|k| format!("{n}.m{k}")).collect(), ..Default::default() })
        .collect();
    let mut jt = JointTrack { source: path.display().to_string(), names: joints.iter().map(|(k, _)| format!("q{k}")).collect(), ..Default::default() };
    let mut nan_rows: BTreeMap<String, usize> = BTreeMap::new();
    let mut rows = 0usize;
    let mut record = csv::StringRecord::new();
    loop {
        match reader.read_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => {
                let line = e.position().map_or(0, |p| p.line());
                return Err(err(line, format!("{e}")));
            }
        }
        let line = record.position().map_or(0, |p| p.line());
        rows += 1;
        // A cell: None when empty, Some(value) otherwise (NaN allowed: the caller decides).
        let cell = |i: usize| -> Result<Option<f64>> {
            let s = record.get(i).unwrap_or("");
            if s.is_empty() {
                return Ok(None);
            }
            s.parse::<f64>().map(Some).map_err(|_| err(line, format!("column `{}`: `{}` is not a number", dvrk_kin::text_file::excerpt(&header[i], 80), dvrk_kin::text_file::excerpt(s, 80))))
        };
        let t = match cell(time)? {
            Some(t) if t.is_finite() => t,
            other => return Err(err(line, format!("column `time`: {} is not a finite time", other.map_or("empty".to_string(), |v| v.to_string())))),
        };
        for (tr, cols) in tracks.iter_mut().zip(bodies.values()) {
            let mut v = [0.0; 7];
            let mut missing = false;
            for (x, c) in v.iter_mut().zip(cols) {
                match cell(c.unwrap_or(0))? {
                    Some(val) => *x = val,
                    None => missing = true,
                }
            }
            if missing {
                tr.occluded += 1;
                continue;
            }
            if v.iter().any(|x| !x.is_finite()) {
                *nan_rows.entry(tr.name.clone()).or_default() += 1;
                tr.occluded += 1;
                continue;
            }
            let q = unit_quaternion(v[3], v[4], v[5], v[6]).map_err(|m| err(line, format!("rigid body `{}`: {m}", tr.name)))?;
            tr.t.push(t);
            tr.poses.push(Pose::from_parts(Translation3::new(v[0], v[1], v[2]), q.to_rotation_matrix()));
        }
        for (mt, ms) in mtracks.iter_mut().zip(markers.values()) {
            mt.t.push(t);
            for cols in ms.values() {
                for c in cols {
                    let v = cell(c.unwrap_or(0))?.unwrap_or(f64::NAN);
                    mt.xyz.push(v);
                }
            }
        }
        if !joints.is_empty() {
            let q: Vec<f64> = joints.iter().map(|(_, c)| cell(*c).map(|v| v.unwrap_or(f64::NAN))).collect::<Result<_>>()?;
            if q.iter().all(|x| x.is_finite()) {
                jt.t.push(t);
                jt.q.push(q);
            } else {
                jt.skipped_lines.push(line as usize);
            }
        }
    }
    if rows == 0 {
        return Err(RecordingError::file(path, "the header is followed by no data row"));
    }
    if let Some(first) = jt.skipped_lines.first() {
        rec.warnings.push(format!("{}: {} row(s) without a finite value in every joint column (first: line {first}) left out of the joints", path.display(), jt.skipped_lines.len()));
    }
    for (name, n) in nan_rows {
        rec.warnings.push(format!("{}: rigid body `{name}`: {n} row(s) hold NaN; treated as occluded", path.display()));
    }
    if !ignored.is_empty() {
        rec.warnings.push(format!("{}: ignored column(s) {}", path.display(), ignored.join(", ")));
    }
    for t in tracks.iter_mut() {
        t.sort_by_time();
    }
    rec.bodies = tracks;
    rec.markers = mtracks;
    rec.joints = (!jt.names.is_empty()).then_some(jt);
    Ok(rec)
}

/// Write a recording as plain CSV (every number in its shortest exact form). Rows are the
/// union of all tracks' times; a track without a sample at a row's time leaves empty cells.
pub fn write(rec: &Recording) -> String {
    let mut times: Vec<f64> = rec.bodies.iter().flat_map(|b| b.t.iter().copied()).chain(rec.markers.iter().flat_map(|m| m.t.iter().copied())).collect();
    if let Some(j) = &rec.joints {
        times.extend(j.t.iter().copied());
    }
    times.sort_by(f64::total_cmp);
    times.dedup();
    let row_of = |t: f64| times.binary_search_by(|x| x.total_cmp(&t)).unwrap_or(0);
    let mut out = String::from(
        "# dvrk-calib plain CSV: time (s); NAME.x,y,z (m) and NAME.qx,qy,qz,qw: rigid-body pose in the tracker frame;\n\
         # NAME.mK.x,y,z (m): raw marker K of NAME; qN: joint N (rad, m). Empty cell: occluded.\n",
    );
    let mut header = vec!["time".to_string()];
    for b in &rec.bodies {
        header.extend(POSE.iter().map(|f| format!("{}.{f}", b.name)));
    }
    for m in &rec.markers {
        for k in 1..=m.markers() {
            header.extend(["x", "y", "z"].iter().map(|c| format!("{}.m{k}.{c}", m.body)));
        }
    }
    let nj = rec.joints.as_ref().map_or(0, |j| j.names.len());
    header.extend((1..=nj).map(|k| format!("q{k}")));
    out += &header.join(",");
    out.push('\n');
    let width = header.len();
    let mut cells = vec![String::new(); times.len() * width];
    for (r, t) in times.iter().enumerate() {
        cells[r * width] = format!("{t}");
    }
    let mut col = 1;
    for b in &rec.bodies {
        for (t, p) in b.t.iter().zip(&b.poses) {
            let r = row_of(*t);
            let q = UnitQuaternion::from_rotation_matrix(&p.rotation);
            let v = p.translation.vector;
            for (k, x) in [v.x, v.y, v.z, q.i, q.j, q.k, q.w].iter().enumerate() {
                cells[r * width + col + k] = format!("{x}");
            }
        }
        col += 7;
    }
    for m in &rec.markers {
        let k = m.markers();
        for (i, t) in m.t.iter().enumerate() {
            let r = row_of(*t);
            for c in 0..3 * k {
                let x = m.xyz[i * 3 * k + c];
                if x.is_finite() {
                    cells[r * width + col + c] = format!("{x}");
                }
            }
        }
        col += 3 * k;
    }
    if let Some(j) = &rec.joints {
        for (t, q) in j.t.iter().zip(&j.q) {
            let r = row_of(*t);
            for (k, x) in q.iter().enumerate() {
                cells[r * width + col + k] = format!("{x}");
            }
        }
    }
    for row in cells.chunks(width) {
        for (i, c) in row.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            let _ = write!(out, "{c}");
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_the_line_and_column() {
        let p = Path::new("rec.csv");
        let e = parse("t,a.x\n0,1\n", p).unwrap_err().to_string();
        assert!(e.contains("no `time` column"), "{e}");
        let e = parse("time,a.x,a.y,a.z,a.qx,a.qy,a.qz\n0,1,2,3,0,0,0\n", p).unwrap_err().to_string();
        assert!(e.contains("no `a.qw` column"), "{e}");
        let e = parse("time,a.x,a.y,a.z,a.qx,a.qy,a.qz,a.qw\n0,1,2,3,0,0,0,1\n0.1,1,2,x,0,0,0,1\n", p).unwrap_err().to_string();
        assert_eq!(e, "rec.csv: line 3: column `a.z`: `x` is not a number");
        let e = parse("time,a.x,a.y,a.z,a.qx,a.qy,a.qz,a.qw\n0,1,2,3,0,0,0,2\n", p).unwrap_err().to_string();
        assert!(e.contains("line 2: rigid body `a`: quaternion (0, 0, 0, 2) has norm 2.0000"), "{e}");
        let e = parse("time,q1\n", p).unwrap_err().to_string();
        assert!(e.contains("no data row"), "{e}");
    }

    #[test]
    fn nan_rows_and_empty_cells_are_occlusions_with_a_warning() {
        let text = "# c\ntime,a.x,a.y,a.z,a.qx,a.qy,a.qz,a.qw,q1\n0,1,2,3,0,0,0,1,0.5\n0.1,,,,,,,,0.6\n0.2,nan,2,3,0,0,0,1,0.7\n";
        let rec = parse(text, Path::new("r.csv")).unwrap();
        let a = rec.body("a").unwrap();
        assert_eq!((a.len(), a.occluded), (1, 2));
        assert!(rec.warnings[0].contains("1 row(s) hold NaN"), "{:?}", rec.warnings);
        assert_eq!(rec.joints.as_ref().unwrap().q, vec![vec![0.5], vec![0.6], vec![0.7]]);
        // And back: the written file reads the same.
        let again = parse(&write(&rec), Path::new("w.csv")).unwrap();
        assert_eq!(again.bodies, rec.bodies.iter().map(|b| BodyTrack { occluded: 2, ..b.clone() }).collect::<Vec<_>>());
    }
}
