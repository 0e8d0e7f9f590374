//! A joint test recorded on its own: the WPI authors' sweep of one MTM platform joint
//! (`joint_test_cable.csv`), read as recorded. Layout: no header, 3 columns (the swept joint's
//! position, rad; an unused 0; its effort, N·m), one row per sample; blank lines skipped.

use crate::recording::error::{RecordingError, Result};
use std::path::Path;

/// The joint test `path`'s samples: (position rad, effort N·m) per row, in the file's order.
/// A row without 3 columns, or a value that is not a finite number, is an error naming its line.
pub fn read_joint_test(path: &Path) -> Result<Vec<(f64, f64)>> {
    let text = crate::recording::read_csv_text(path)?;
    let mut rows = Vec::new();
    for (line, row) in text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let cells: Vec<&str> = row.split(',').map(str::trim).collect();
        if cells.len() != 3 {
            return Err(RecordingError::file(path, format!("line {}: {} columns; a joint test has 3 (position rad, unused, effort N·m)", line + 1, cells.len())));
        }
        rows.push((super::finite_cell(path, line + 1, 1, cells[0])?, super::finite_cell(path, line + 1, 3, cells[2])?));
    }
    Ok(rows)
}
