//! `dvrk`: inspect, check, evaluate and export dVRK closed-loop models.
//!
//! `main` only turns [`run`] into an exit status and prints the error chain:
//! 0 success, 1 bad input (files, values), 2 bad command line (clap), 3 a check found problems.

mod cli;
mod commands;
mod io;
mod progress;
mod signals;

use clap::Parser;
use std::process::ExitCode;

/// A check ran and found problems (its report was printed): exit status 3.
#[derive(Debug)]
pub struct CheckFailed;

impl std::fmt::Display for CheckFailed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "the check found problems (see the report above)")
    }
}

impl std::error::Error for CheckFailed {}

/// The longest error message printed (characters).
const MAX_MESSAGE_CHARS: usize = 600;

fn main() -> ExitCode {
    // The handler first: a SIGTERM in the process's first milliseconds (issue #63) is then ours
    // (exit 130, nothing staged yet), not the default's 143.
    signals::install();
    let args = cli::Cli::parse();
    let result = commands::run(args);
    // Outputs reserved but not written (an error, or an optional output not produced).
    dvrk_kin::atomic::remove_all_staged();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<CheckFailed>() => {
            eprintln!("error: {e}");
            ExitCode::from(3)
        }
        Err(e) => {
            // A message quoting file content is cut (readers quote short excerpts; this is the net).
            eprintln!("error: {}", dvrk_kin::text_file::excerpt(&one_line(&e), MAX_MESSAGE_CHARS));
            ExitCode::from(1)
        }
    }
}

/// An error and its causes on one line (a launcher's log keeps one line per failure): each cause
/// after a colon, a cause the text already quotes left out, and a cause that starts with the
/// file the context just named ("--recording F" then "F: ...") joined without saying F twice.
fn one_line(e: &anyhow::Error) -> String {
    let mut line = e.to_string();
    for cause in e.chain().skip(1).map(|c| c.to_string()) {
        if line.contains(cause.as_str()) {
            continue;
        }
        let named = line.rsplit(' ').next().unwrap_or_default();
        match cause.strip_prefix(named).and_then(|rest| rest.strip_prefix(": ")) {
            Some(rest) if !named.is_empty() => line = format!("{line}: {rest}"),
            _ => line = format!("{line}: {cause}"),
        }
    }
    line.replace('\n', " ")
}
