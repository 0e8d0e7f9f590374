//! A CSV of joint configurations, one per row (`dvrk fk --input`), and the CSV of poses written
//! for it. A joint's column is `qK` (1-based) or the joint's name, in any order; a joint the
//! caller does not need may be absent and is held at its home.

use crate::recording::error::{RecordingError, Result};
use dvrk_kin::Model;
use std::path::{Path, PathBuf};

/// The rows of a joints CSV, read one at a time ([`JointRows::next_into`]).
pub struct JointRows {
    path: PathBuf,
    /// The column of each joint of the model, `None` for one held at its home.
    columns: Vec<Option<usize>>,
    records: csv::StringRecordsIntoIter<std::io::Cursor<String>>,
    line: usize,
    /// The joints held at their home, as `qK (name) at its home VALUE UNIT`.
    pub held: Vec<String>,
}

/// Open the joints CSV `path` for `model` (read whole and bounded, as every text recording).
/// `needed[k]`: whether joint `k` must have a column; `dependent` names what needs them (an
/// error's words, `frame tool_tip of model psm`).
pub fn read_joint_rows(path: &Path, model: &Model, needed: &[bool], dependent: &str) -> Result<JointRows> {
    let text = crate::recording::read_csv_text(path)?;
    let mut reader = csv::Reader::from_reader(std::io::Cursor::new(text));
    let header = reader.headers().map_err(|e| RecordingError::file(path, format!("cannot read the header: {e}")))?.clone();
    let mut held = Vec::new();
    let mut columns = Vec::with_capacity(model.nq());
    for k in 1..=model.nq() {
        let (col, joint) = (format!("q{k}"), &model.joints[k - 1].name);
        match header.iter().position(|h| h.trim() == col || h.trim() == joint) {
            Some(c) => columns.push(Some(c)),
            None if !needed[k - 1] => {
                held.push(format!("{col} ({joint}) at its home {} {}", model.joints[k - 1].home, model.joints[k - 1].unit()));
                columns.push(None);
            }
            None => {
                let names = dvrk_kin::text_file::excerpt(&header.iter().collect::<Vec<_>>().join(","), 120);
                return Err(RecordingError::file(path, format!("missing column {col} or {joint} ({dependent} depends on it; header: {names})")));
            }
        }
    }
    Ok(JointRows { path: path.to_path_buf(), columns, records: reader.into_records(), line: 1, held })
}

impl JointRows {
    /// The next row's joints into `q` (rad, m; the held ones left as they are): its line in the
    /// file (1-based, the header is line 1), `None` after the last. A value that is not a finite
    /// number is an error naming the line and the column.
    pub fn next_into(&mut self, q: &mut [f64]) -> Result<Option<usize>> {
        let Some(record) = self.records.next() else { return Ok(None) };
        self.line += 1;
        let line = self.line;
        let record = record.map_err(|e| RecordingError::file(&self.path, format!("line {line}: cannot read: {e}")))?;
        for (k, c) in self.columns.iter().enumerate() {
            let Some(c) = *c else { continue };
            let text = record.get(c).unwrap_or("").trim();
            let x: f64 = text.parse().map_err(|_| RecordingError::file(&self.path, format!("line {line}, column q{}: `{text}` is not a number", k + 1)))?;
            if !x.is_finite() {
                return Err(RecordingError::file(&self.path, format!("line {line}, column q{} = {text}: not finite", k + 1)));
            }
            q[k] = x;
        }
        Ok(Some(line))
    }
}

/// The header of the poses CSV written for a joints CSV: position (m) and unit quaternion.
pub const POSE_ROWS_HEADER: &str = "x,y,z,qx,qy,qz,qw\n";

/// One pose's row of that CSV: `position` (m), `rotation` as a unit quaternion `[x, y, z, w]`.
pub fn push_pose_row(out: &mut String, position: [f64; 3], rotation: [f64; 4]) {
    use std::fmt::Write;
    let [x, y, z] = position;
    let [qx, qy, qz, qw] = rotation;
    // Writing to a String cannot fail.
    let _ = writeln!(out, "{x},{y},{z},{qx},{qy},{qz},{qw}");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_by_index_or_name_a_held_joint_and_errors_by_line() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("q.csv");
        // Named and numbered columns in any order; the jaw (q7) absent and not needed.
        std::fs::write(&path, "q3,outer_yaw,q2,q4,q5,q6\n0.12,0.1,-0.2,0,0,0\n0.13,x,0,0,0,0\n").unwrap();
        let mut needed = vec![true; model.nq()];
        needed[6] = false;
        let mut rows = read_joint_rows(&path, &model, &needed, "frame tool_tip of model psm").unwrap();
        assert_eq!(rows.held.len(), 1);
        assert!(rows.held[0].starts_with("q7 (jaw) at its home"), "{:?}", rows.held);
        let mut q = model.home();
        assert_eq!(rows.next_into(&mut q).unwrap(), Some(2));
        assert_eq!(&q[..3], &[0.1, -0.2, 0.12]);
        assert_eq!(q[6], model.home()[6]);
        let e = rows.next_into(&mut q).unwrap_err().to_string();
        assert!(e.ends_with("q.csv: line 3, column q1: `x` is not a number"), "{e}");
        // A needed joint without a column names it and what needs it.
        needed[6] = true;
        let e = read_joint_rows(&path, &model, &needed, "frame jaw_tip of model psm").err().unwrap().to_string();
        assert!(e.contains("missing column q7 or jaw (frame jaw_tip of model psm depends on it; header: q3,outer_yaw"), "{e}");
        let mut out = String::from(POSE_ROWS_HEADER);
        push_pose_row(&mut out, [0.5, -1.0, 0.25], [0.0, 0.0, 0.0, 1.0]);
        assert_eq!(out, "x,y,z,qx,qy,qz,qw\n0.5,-1,0.25,0,0,0,1\n");
    }
}
