//! Input parsing and atomic output for the commands.

use anyhow::{anyhow, bail, Context, Result};
use std::io::Write;
use std::path::Path;

/// Parse a comma-separated list of finite numbers given to `flag`.
pub fn parse_list(flag: &str, text: &str) -> Result<Vec<f64>> {
    text.split(',')
        .enumerate()
        .map(|(i, s)| {
            let s = s.trim();
            let x: f64 = s.parse().map_err(|_| anyhow!("{flag}: item {} `{s}` is not a number", i + 1))?;
            if !x.is_finite() {
                bail!("{flag}: item {} = {s} is not finite", i + 1);
            }
            Ok(x)
        })
        .collect()
}

/// Write `contents` to `path` whole or not at all: a temporary file beside it, then a rename.
pub fn write_atomic(path: &Path, contents: &[u8]) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::NamedTempFile::new_in(dir).with_context(|| format!("{}: cannot create a file in {}", path.display(), dir.display()))?;
    tmp.write_all(contents).with_context(|| format!("{}: cannot write", path.display()))?;
    tmp.persist(path).map_err(|e| anyhow!("{}: cannot write: {}", path.display(), e.error))?;
    Ok(())
}

/// Print a line to stdout; a closed pipe (`dvrk ... | head`) ends the program quietly.
pub fn print_line(args: std::fmt::Arguments) {
    let mut out = std::io::stdout().lock();
    if let Err(e) = writeln!(out, "{args}") {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("error: cannot write to stdout: {e}");
        std::process::exit(1);
    }
}

/// `println!` that does not panic when stdout is closed.
#[macro_export]
macro_rules! outln {
    () => { $crate::io::print_line(format_args!("")) };
    ($($arg:tt)*) => { $crate::io::print_line(format_args!($($arg)*)) };
}
