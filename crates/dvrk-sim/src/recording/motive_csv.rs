//! OptiTrack Motive CSV exports (format versions 1.2x): rigid bodies and labelled markers.
//!
//! Layout: a metadata row of key/value pairs (`Format Version,1.23,...,Rotation Type,Quaternion,
//! Length Units,Millimeters,...`), then header rows naming each column's type (`Rigid Body`,
//! `Rigid Body Marker`, `Marker`, ...), name, ID and kind (`Rotation`, `Position`, `Mean Marker
//! Error`), then `Frame,Time (Seconds),X,Y,Z,W,...` and the data. Quaternions are X Y Z W.
//! Lengths are in the export's unit (millimetres or metres) and converted to metres. Empty
//! cells are occlusions. `Rigid Body Marker` columns (where the solver expected markers) and
//! unlabelled markers are skipped; labelled markers `BODY:MarkerN` become BODY's raw markers.

use crate::recording::error::{RecordingError, Result};
use crate::recording::plain_csv::unit_quaternion;
use crate::recording::tracks::{BodyTrack, MarkerTrack, Recording};
use dvrk_kin::Pose;
use nalgebra::Translation3;
use std::path::Path;

/// True when `text` starts like a Motive export.
pub fn looks_like_motive(text: &str) -> bool {
    text.trim_start_matches('\u{feff}').starts_with("Format Version")
}

/// Read a Motive CSV export.
pub fn read(path: &Path) -> Result<Recording> {
    let text = crate::recording::read_csv_text(path)?;
    parse(&text, path)
}

struct Body {
    name: String,
    rot: [Option<usize>; 4],
    pos: [Option<usize>; 3],
    error: Option<usize>,
}

struct Marker {
    body: String,
    label: String,
    pos: [Option<usize>; 3],
}

/// Parse Motive CSV text; `path` names it in errors.
pub fn parse(text: &str, path: &Path) -> Result<Recording> {
    let err = |line: usize, msg: String| RecordingError::file(path, format!("line {line}: {msg}"));
    let mut reader = csv::ReaderBuilder::new().has_headers(false).flexible(true).from_reader(text.trim_start_matches('\u{feff}').as_bytes());
    let rows: Vec<csv::StringRecord> = reader.records().collect::<std::result::Result<_, _>>().map_err(|e| RecordingError::file(path, format!("{e}")))?;
    let meta = rows.first().ok_or_else(|| RecordingError::file(path, "empty file"))?;
    let value = |key: &str| -> Option<String> {
        let cells: Vec<&str> = meta.iter().collect();
        cells.iter().position(|c| c.trim() == key).and_then(|i| cells.get(i + 1)).map(|s| s.trim().to_string())
    };
    let version = value("Format Version").ok_or_else(|| err(1, "no `Format Version`: not a Motive CSV export".into()))?;
    match value("Rotation Type").as_deref() {
        Some("Quaternion") | None => {}
        Some(other) => return Err(err(1, format!("Rotation Type is `{other}`; export with Rotation Type = Quaternion"))),
    }
    let scale = match value("Length Units").as_deref() {
        Some("Millimeters") => 1e-3,
        Some("Centimeters") => 1e-2,
        Some("Meters") => 1.0,
        Some(other) => return Err(err(1, format!("Length Units `{other}` is not one of Millimeters, Centimeters, Meters"))),
        None => return Err(err(1, format!("no `Length Units` in the header (format version {version}); export with units"))),
    };
    let frame_row = rows
        .iter()
        .position(|r| r.get(0).is_some_and(|c| c.trim() == "Frame"))
        .ok_or_else(|| RecordingError::file(path, "no `Frame,Time (Seconds),...` header row"))?;
    let is_type = |c: &str| ["Rigid Body", "Rigid Body Marker", "Marker", "Bone", "Bone Marker", "Skeleton"].contains(&c.trim());
    let type_row = rows[..frame_row]
        .iter()
        .position(|r| r.iter().skip(2).any(is_type))
        .ok_or_else(|| err(frame_row + 1, "no row of column types (Rigid Body, Marker) above it".into()))?;
    let name_row = type_row + 1;
    let kind_row = frame_row - 1;
    if name_row >= kind_row {
        return Err(err(type_row + 1, "the type row is not followed by name and kind rows".into()));
    }
    let (types, names, kinds, axes) = (&rows[type_row], &rows[name_row], &rows[kind_row], &rows[frame_row]);
    let time_col = axes.iter().position(|c| c.trim().starts_with("Time")).ok_or_else(|| err(frame_row + 1, "no `Time (Seconds)` column".into()))?;
    let mut bodies: Vec<Body> = Vec::new();
    let mut markers: Vec<Marker> = Vec::new();
    let mut skipped = 0usize;
    let xyzw = |c: &str| ["X", "Y", "Z", "W"].iter().position(|a| *a == c.trim());
    for i in 2..axes.len() {
        let (ty, name, kind, axis) = (types.get(i).unwrap_or("").trim(), names.get(i).unwrap_or("").trim(), kinds.get(i).unwrap_or("").trim(), axes.get(i).unwrap_or(""));
        match ty {
            "Rigid Body" => {
                let b = match bodies.iter().position(|b| b.name == name) {
                    Some(k) => &mut bodies[k],
                    None => {
                        bodies.push(Body { name: name.to_string(), rot: [None; 4], pos: [None; 3], error: None });
                        bodies.last_mut().expect("just pushed")
                    }
                };
                match (kind, xyzw(axis)) {
                    ("Rotation", Some(k)) => b.rot[k] = Some(i),
                    ("Position", Some(k)) if k < 3 => b.pos[k] = Some(i),
                    ("Mean Marker Error", _) => b.error = Some(i),
                    _ => {}
                }
            }
            "Marker" => {
                let Some((body, label)) = name.split_once(':') else {
                    skipped += 1;
                    continue;
                };
                let m = match markers.iter().position(|m| m.body == body && m.label == label) {
                    Some(k) => &mut markers[k],
                    None => {
                        markers.push(Marker { body: body.to_string(), label: label.to_string(), pos: [None; 3] });
                        markers.last_mut().expect("just pushed")
                    }
                };
                if let ("Position", Some(k)) = (kind, xyzw(axis)) {
                    if k < 3 {
                        m.pos[k] = Some(i);
                    }
                }
            }
            _ => {}
        }
    }
    for b in &bodies {
        if b.rot.iter().any(Option::is_none) || b.pos.iter().any(Option::is_none) {
            return Err(err(type_row + 1, format!("rigid body `{}` lacks some of its Rotation X,Y,Z,W and Position X,Y,Z columns", b.name)));
        }
    }
    markers.retain(|m| m.pos.iter().all(Option::is_some));
    let mut rec = Recording { source: path.display().to_string(), ..Default::default() };
    let mut tracks: Vec<BodyTrack> = bodies.iter().map(|b| BodyTrack::new(b.name.clone(), "motive")).collect();
    let mut mbodies: Vec<String> = markers.iter().map(|m| m.body.clone()).collect();
    mbodies.dedup();
    let mut mtracks: Vec<MarkerTrack> = mbodies
        .iter()
        .map(|b| MarkerTrack { body: b.clone(), names: markers.iter().filter(|m| &m.body == b).map(|m| format!("{b}:{}", m.label)).collect(), ..Default::default() })
        .collect();
    let mut nan_cells = 0usize;
    for (r, row) in rows.iter().enumerate().skip(frame_row + 1) {
        let line = row.position().map_or(r + 1, |p| p.line() as usize);
        if row.iter().all(|c| c.trim().is_empty()) {
            continue;
        }
        let cell = |i: usize| -> Result<Option<f64>> {
            let s = row.get(i).unwrap_or("").trim();
            if s.is_empty() {
                return Ok(None);
            }
            s.parse::<f64>().map(Some).map_err(|_| err(line, format!("column {} ({} {}): `{}` is not a number", i + 1, dvrk_kin::text_file::excerpt(names.get(i).unwrap_or(""), 80), dvrk_kin::text_file::excerpt(axes.get(i).unwrap_or(""), 80), dvrk_kin::text_file::excerpt(s, 80))))
        };
        let t = cell(time_col)?.filter(|t| t.is_finite()).ok_or_else(|| err(line, "empty or non-finite time".into()))?;
        for (b, tr) in bodies.iter().zip(tracks.iter_mut()) {
            let get = |c: &Option<usize>| cell(c.unwrap_or(0));
            let (qx, qy, qz, qw) = (get(&b.rot[0])?, get(&b.rot[1])?, get(&b.rot[2])?, get(&b.rot[3])?);
            let (x, y, z) = (get(&b.pos[0])?, get(&b.pos[1])?, get(&b.pos[2])?);
            let (Some(qx), Some(qy), Some(qz), Some(qw), Some(x), Some(y), Some(z)) = (qx, qy, qz, qw, x, y, z) else {
                tr.occluded += 1;
                continue;
            };
            if ![qx, qy, qz, qw, x, y, z].iter().all(|v| v.is_finite()) {
                nan_cells += 1;
                tr.occluded += 1;
                continue;
            }
            let q = unit_quaternion(qx, qy, qz, qw).map_err(|m| err(line, format!("rigid body `{}`: {m}", b.name)))?;
            tr.t.push(t);
            tr.poses.push(Pose::from_parts(Translation3::new(x * scale, y * scale, z * scale), q.to_rotation_matrix()));
            if let Some(e) = b.error {
                tr.residual.push(cell(e)?.map_or(f64::NAN, |v| v * scale));
            }
        }
        for mt in mtracks.iter_mut() {
            mt.t.push(t);
            for m in markers.iter().filter(|m| m.body == mt.body) {
                for c in &m.pos {
                    mt.xyz.push(cell(c.unwrap_or(0))?.map_or(f64::NAN, |v| v * scale));
                }
            }
        }
    }
    for tr in tracks.iter_mut() {
        if tr.residual.len() != tr.poses.len() || tr.residual.iter().any(|r| !r.is_finite()) {
            tr.residual.clear();
        }
    }
    if nan_cells > 0 {
        rec.warnings.push(format!("{}: {nan_cells} rigid-body sample(s) hold NaN; treated as occluded", path.display()));
    }
    if skipped > 0 {
        rec.warnings.push(format!("{}: {skipped} unlabelled marker column(s) skipped", path.display()));
    }
    rec.bodies = tracks;
    rec.markers = mtracks;
    Ok(rec)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Motive 1.23 export as Motive writes it: one rigid body in millimetres, its three
    /// labelled markers, one occluded frame, one frame with a hidden marker.
    const SAMPLE: &str = "Format Version,1.23,Take Name,Take 2024-03-01 02.15.40 PM,Take Notes,,Capture Frame Rate,120.000000,Export Frame Rate,120.000000,Capture Start Time,2024-03-01 02.15.40.123 PM,Capture Start Frame,0,Total Frames in Take,3,Total Exported Frames,3,Rotation Type,Quaternion,Length Units,Millimeters,Coordinate Space,Global
\r
,,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body Marker,Rigid Body Marker,Rigid Body Marker,Rigid Body Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker,Marker
,,end,end,end,end,end,end,end,end,end:Marker1,end:Marker1,end:Marker1,end:Marker1,end:Marker1,end:Marker1,end:Marker1,end:Marker2,end:Marker2,end:Marker2,end:Marker3,end:Marker3,end:Marker3
,,1,1,1,1,1,1,1,1,1,1,1,1,2,2,2,3,3,3,4,4,4
,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error,Position,Position,Position,Marker Quality,Position,Position,Position,Position,Position,Position,Position,Position,Position
Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,,X,Y,Z,,X,Y,Z,X,Y,Z,X,Y,Z
0,0.000000,0.000000,0.000000,0.000000,1.000000,100.000000,-20.000000,1500.000000,0.050000,130.0,-20.0,1500.0,1.0,130.0,-20.0,1500.0,88.0,7.0,1500.0,85.0,-40.0,1500.0
1,0.008333,0.000000,0.707107,0.000000,0.707107,101.000000,-20.000000,1500.000000,0.060000,,,,,131.0,-20.0,1500.0,,,,86.0,-40.0,1500.0
2,0.016667,,,,,,,,,,,,,,,,,,,,,
";

    #[test]
    fn reads_a_motive_export_in_millimetres() {
        let rec = parse(SAMPLE, Path::new("take.csv")).unwrap();
        let b = rec.body("end").unwrap();
        assert_eq!((b.len(), b.occluded), (2, 1));
        assert!((b.poses[0].translation.vector - nalgebra::Vector3::new(0.1, -0.02, 1.5)).norm() < 1e-12);
        // X Y Z W = (0, 0.707107, 0, 0.707107): 90 degrees about y.
        let r = b.poses[1].rotation;
        assert!((r * nalgebra::Vector3::x() - nalgebra::Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-6);
        assert!((b.residual[1] - 6e-5).abs() < 1e-15);
        let m = rec.marker_track("end").unwrap();
        assert_eq!(m.names, vec!["end:Marker1", "end:Marker2", "end:Marker3"]);
        assert_eq!(m.get(0, 1), Some(nalgebra::Vector3::new(0.088, 0.007, 1.5)));
        assert_eq!(m.get(1, 1), None);
        assert!((b.t[1] - 0.008333).abs() < 1e-12);
    }

    #[test]
    fn euler_exports_and_missing_units_are_errors() {
        let e = parse(&SAMPLE.replace("Rotation Type,Quaternion", "Rotation Type,XYZ"), Path::new("t.csv")).unwrap_err().to_string();
        assert!(e.contains("line 1: Rotation Type is `XYZ`"), "{e}");
        let e = parse(&SAMPLE.replace("Length Units,Millimeters,", ""), Path::new("t.csv")).unwrap_err().to_string();
        assert!(e.contains("no `Length Units`"), "{e}");
        let e = parse(&SAMPLE.replace("131.0", "abc"), Path::new("t.csv")).unwrap_err().to_string();
        assert!(e.contains("line 9: column 15 (end:Marker1 X): `abc` is not a number"), "{e}");
    }
}
