//! Helpers shared by the integration tests: seeded configurations, external data, the binary.

use dvrk_kin::Model;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::PathBuf;
use std::process::{Command, Output};

/// `count` uniformly random configurations within the joint limits (seeded).
pub fn random_configurations(model: &Model, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..count).map(|_| model.joints.iter().map(|j| rng.random_range(j.lower..=j.upper)).collect()).collect()
}

/// A file of `../shared/data/external/`, or `None` (with a note on stderr) when the folder is
/// absent, as on a user's fresh clone.
pub fn external(rel: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/external").join(rel);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: {} is absent (external reference data; CI has it)", p.display());
        None
    }
}

/// The `dvrk` binary under test: this build's, or `DVRK_TEST_BIN` (to show a test fails on an
/// older binary).
pub fn dvrk_bin() -> PathBuf {
    std::env::var_os("DVRK_TEST_BIN").map_or_else(|| PathBuf::from(env!("CARGO_BIN_EXE_dvrk")), PathBuf::from)
}

/// Run the real `dvrk` binary.
pub fn dvrk(args: &[&str]) -> Output {
    Command::new(dvrk_bin()).args(args).output().expect("the dvrk binary runs")
}

/// Run `dvrk` with a time limit: a run still going after `secs` is killed and fails the test
/// (a regression that waits on a FIFO or reads `/dev/zero` cannot hang the suite).
pub fn dvrk_within(secs: f64, args: &[&str]) -> Output {
    use std::process::Stdio;
    let mut child = Command::new(dvrk_bin()).args(args).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("the dvrk binary runs");
    let start = std::time::Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed().as_secs_f64() > secs {
            let _ = child.kill();
            let _ = child.wait();
            panic!("dvrk {args:?} still running after {secs} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().expect("output")
}

/// Stdout of a successful `dvrk` run (fails the test otherwise, showing stderr).
pub fn dvrk_ok(args: &[&str]) -> String {
    let out = dvrk(args);
    assert!(out.status.success(), "dvrk {args:?} failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("utf-8 output")
}

/// Stderr of a failing `dvrk` run; asserts a one-line `error:` message, exit status 1 or 2 and
/// no panic.
pub fn dvrk_err(args: &[&str]) -> String {
    let out = dvrk(args);
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "dvrk {args:?} should fail");
    assert!(matches!(out.status.code(), Some(1) | Some(2)), "dvrk {args:?}: status {:?}: {err}", out.status.code());
    assert!(!err.contains("panicked"), "dvrk {args:?} panicked: {err}");
    err
}

/// A temporary directory for test files.
pub fn tempdir() -> tempfile::TempDir {
    tempfile::tempdir().expect("a temporary directory")
}
