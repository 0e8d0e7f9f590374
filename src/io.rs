//! Input parsing and atomic output for the commands.

use anyhow::{anyhow, bail, Result};
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

/// The largest gravity a `--gravity` flag takes (m/s^2): ten times the Earth's.
pub const MAX_GRAVITY: f64 = 98.1;

/// A `--gravity` flag's `x,y,z` (m/s^2), at most [`MAX_GRAVITY`] in magnitude (beyond, the
/// torques are no arm's, and 1e308 overflowed to NaN N·m).
pub fn parse_gravity(text: &str) -> Result<nalgebra::Vector3<f64>> {
    let g = parse_list("--gravity", text)?;
    let [x, y, z] = g[..] else { bail!("--gravity {text}: three components x,y,z (m/s^2)") };
    let g = nalgebra::Vector3::new(x, y, z);
    if !(g.norm() <= MAX_GRAVITY) {
        bail!("--gravity {text}: its magnitude is at most {MAX_GRAVITY} m/s^2");
    }
    Ok(g)
}

/// Stage `contents` for `path` (written, not yet visible): commit with
/// [`dvrk_kin::atomic::commit_all`] once every output of the command is staged.
pub fn stage(path: &Path, contents: &[u8]) -> Result<dvrk_kin::atomic::Staged> {
    Ok(dvrk_kin::atomic::Staged::write(path, contents)?)
}

/// Check a command's outputs before any work (see [`dvrk_kin::atomic::check_outputs`]) and
/// reserve them ([`dvrk_kin::atomic::reserve`]).
pub fn check_outputs(inputs: &[(&str, &Path)], outputs: &[(&str, Option<&Path>)]) -> Result<()> {
    let outputs: Vec<(&str, &Path)> = outputs.iter().filter_map(|(f, p)| p.map(|p| (*f, p))).collect();
    dvrk_kin::atomic::check_outputs(inputs, &outputs)?;
    // Held until the outputs are committed (or removed at exit): a second run writing one of them
    // is refused at its start.
    for (flag, path) in outputs {
        dvrk_kin::atomic::reserve(path).map_err(|e| anyhow!("{flag}: {e}"))?;
    }
    Ok(())
}

/// Refuse a `--plot` whose image format is unknown (.png and .svg are drawn) before any work.
pub fn check_plot(plot: Option<&Path>) -> Result<()> {
    if let Some(p) = plot {
        dvrk_calib::plot::check_path(p)?;
    }
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
