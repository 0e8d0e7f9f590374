//! One output discipline (issue 45): nothing a user has is lost. Each case is one the hostile-input
//! probe found: an output on an input, a failed run replacing outputs, a second output failing
//! after the first was replaced, temporary files left by a signal, directories created, modes.

use crate::util::{dvrk_err, dvrk_ok, tempdir};
use std::path::Path;

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// An output that is an input (or another output) is refused before any work; the input is kept.
#[test]
fn an_output_on_an_input_is_refused_and_the_input_kept() {
    let dir = tempdir();
    let same = dir.path().join("same.csv");
    std::fs::write(&same, "q1,q2,q3,q4,q5,q6,q7\n0,0,0.1,0,0,0,0\n").unwrap();
    let s = same.to_str().unwrap();
    let e = dvrk_err(&["fk", "psm", "--input", s, "--output", s]);
    assert!(e.contains("--output: is the input --input") && e.contains("never overwrites an input"), "{e}");
    // The same file by another name.
    let dotted = format!("{}/./same.csv", dir.path().display());
    let e = dvrk_err(&["fk", "psm", "--input", s, "--output", &dotted]);
    assert!(e.contains("is the input --input"), "{e}");
    assert_eq!(read(&same), b"q1,q2,q3,q4,q5,q6,q7\n0,0,0.1,0,0,0,0\n");
    let model = dir.path().join("p.toml");
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("models/psm.toml"), &model).unwrap();
    let before = read(&model);
    let m = model.to_str().unwrap();
    let e = dvrk_err(&["export", "urdf", m, "-o", m]);
    assert!(e.contains("-o: is the input MODEL"), "{e}");
    assert_eq!(read(&model), before);
    let x = dir.path().join("x.json");
    let e = dvrk_err(&["synth", "hidden-effect", "--seed", "1", "-o", x.with_extension("mcap").to_str().unwrap(), "--answer", x.with_extension("mcap").to_str().unwrap()]);
    assert!(e.contains("--answer: is also the output -o"), "{e}");
    let e = dvrk_err(&["discrepancy", "--model", "psm", "--recording", s, "--report", s]);
    assert!(e.contains("--report: is the input --recording"), "{e}");
    assert_eq!(read(&same), b"q1,q2,q3,q4,q5,q6,q7\n0,0,0.1,0,0,0,0\n");
    assert_eq!(listing(dir.path()), ["p.toml", "same.csv"]);
}

/// A run that goes non-finite exits 1 (with `--json` too) and replaces none of its outputs.
#[test]
fn a_failed_run_replaces_nothing() {
    let dir = tempdir();
    // The PSM scene with a derivative gain its inertia cannot carry (kd dt / I >> 2): it diverges
    // on rapier (the reduced engine's jaw carries both blades' placeholder inertias and its
    // effort limit bounds the oscillation).
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("models/scenes/psm.toml")).unwrap();
    let blow: String = text
        .lines()
        .map(|l| match l {
            l if l.starts_with("kd = ") => "kd = [5000.0, 5000.0, 5000.0, 5000.0, 5000.0, 5000.0, 5000.0]".to_string(),
            l if l.starts_with("armature = ") => "armature = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]".to_string(),
            l => l.to_string(),
        })
        .collect::<Vec<_>>()
        .join("\n");
    let scene = dir.path().join("blow.toml");
    std::fs::write(&scene, format!("engine = \"rapier\"\n{blow}")).unwrap();
    let (out, plot) = (dir.path().join("o.mcap"), dir.path().join("p.png"));
    std::fs::write(&out, "old recording").unwrap();
    std::fs::write(&plot, "old plot").unwrap();
    for json in [false, true] {
        let mut args = vec!["sim", "--scene", scene.to_str().unwrap(), "--duration", "1", "--out", out.to_str().unwrap(), "--plot", plot.to_str().unwrap()];
        if json {
            args.push("--json");
        }
        let e = dvrk_err(&args);
        assert!(e.contains("went non-finite") && e.contains("no output was written"), "{e}");
        assert_eq!(read(&out), b"old recording");
        assert_eq!(read(&plot), b"old plot");
        assert_eq!(listing(dir.path()), ["blow.toml", "o.mcap", "p.png"], "no temporary file left");
    }
}

/// A command with two outputs checks both before any work: the second's bad directory leaves the
/// first as it was. Outputs never create directories, and a directory is not a file.
#[test]
fn two_outputs_are_all_or_nothing_and_no_directory_is_made() {
    let dir = tempdir();
    let rec = dir.path().join("rec.mcap");
    std::fs::write(&rec, "keep me").unwrap();
    let missing = dir.path().join("no/such/answer.json");
    let e = dvrk_err(&["synth", "hidden-effect", "--seed", "1", "-o", rec.to_str().unwrap(), "--answer", missing.to_str().unwrap()]);
    assert!(e.contains("--answer") && e.contains("does not exist (outputs never create directories)"), "{e}");
    assert_eq!(read(&rec), b"keep me");
    assert!(!dir.path().join("no").exists());
    let e = dvrk_err(&["sim", "--scene", "psm", "--duration", "0.1", "--out", dir.path().to_str().unwrap()]);
    assert!(e.contains("--out") && e.contains("is a directory"), "{e}");
    assert_eq!(listing(dir.path()), ["rec.mcap"]);
    // Both outputs of a good run appear, with one mode.
    let (mcap, answer) = (dir.path().join("h.mcap"), dir.path().join("h.json"));
    dvrk_ok(&["synth", "hidden-effect", "--seed", "1", "--duration", "6", "-o", mcap.to_str().unwrap(), "--answer", answer.to_str().unwrap()]);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&mcap), mode(&answer));
        let sim = dir.path().join("s.mcap");
        dvrk_ok(&["sim", "--scene", "psm", "--duration", "0.1", "--out", sim.to_str().unwrap()]);
        assert_eq!(mode(&sim), mode(&answer));
        assert_eq!(mode(&sim) & 0o600, 0o600);
    }
}

/// SIGINT during `dvrk sim --out` stops the run: the recording is finished, valid and shorter,
/// said on stderr, and no temporary file is left.
#[cfg(unix)]
#[test]
fn a_signal_finishes_the_recording_and_leaves_no_temporary_file() {
    let dir = tempdir();
    let out = dir.path().join("long.mcap");
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_dvrk"))
        .args(["sim", "--scene", "psm", "--duration", "600", "--out", out.to_str().unwrap(), "--json"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the run is under way (its temporary file exists), then interrupt it.
    let started = std::time::Instant::now();
    while listing(dir.path()).is_empty() && started.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let kill = std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("stopping after this step"), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let duration = v["duration"].as_f64().unwrap();
    assert!(duration > 0.0 && duration < 600.0, "{duration}");
    assert!(v["notes"].as_array().unwrap().iter().any(|n| n.as_str().unwrap().starts_with("stopped at")), "{}", v["notes"]);
    assert_eq!(listing(dir.path()), ["long.mcap"], "no temporary file left");
    // Valid: our reader takes it, with about 100 samples per simulated second.
    let rec = dvrk_calib::read_recording(&out, &dvrk_calib::McapOptions { topics: vec!["/PSM1/measured_cp".into()], joint_topic: None }).unwrap();
    let n = rec.body("/PSM1/measured_cp").unwrap().len() as f64;
    assert!((n - 100.0 * duration).abs() <= 2.0, "{n} samples for {duration} s");
}

/// SIGINT during a command that cannot stop early removes its unfinished outputs.
#[cfg(unix)]
#[test]
fn a_signal_to_another_command_leaves_nothing_half_written() {
    let dir = tempdir();
    let out = dir.path().join("big.mcap");
    let answer = dir.path().join("big.json");
    // A long synthetic recording: the signal lands while it is generated or written.
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_dvrk"))
        .args(["synth", "hidden-effect", "--seed", "3", "--duration", "600", "-o", out.to_str().unwrap(), "--answer", answer.to_str().unwrap()])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    std::process::Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    assert!(listing(dir.path()).is_empty(), "{:?}", listing(dir.path()));
}

fn mkfifo(p: &Path) {
    assert!(std::process::Command::new("mkfifo").arg(p).status().unwrap().success());
}

/// Issue 63 item 2: an output through a symbolic link replaces the link's target and keeps the
/// link (it used to replace the link with a file, its target left as it was).
#[cfg(unix)]
#[test]
fn a_symlinked_output_replaces_its_target_and_keeps_the_link() {
    let dir = tempdir();
    let (real, link) = (dir.path().join("real.urdf"), dir.path().join("link.urdf"));
    std::fs::write(&real, "old").unwrap();
    std::os::unix::fs::symlink("real.urdf", &link).unwrap();
    dvrk_ok(&["export", "urdf", "psm", "-o", link.to_str().unwrap()]);
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link is kept");
    assert_eq!(std::fs::read_link(&link).unwrap(), Path::new("real.urdf"));
    assert!(std::fs::read_to_string(&real).unwrap().starts_with("<?xml"), "its target is replaced");
    // A recorder's --out alike.
    let (real, link) = (dir.path().join("real.mcap"), dir.path().join("link.mcap"));
    std::fs::write(&real, "old").unwrap();
    std::os::unix::fs::symlink("real.mcap", &link).unwrap();
    dvrk_ok(&["sim", "--scene", "psm", "--duration", "0.01", "--out", link.to_str().unwrap()]);
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link is kept");
    assert!(std::fs::read(&real).unwrap().starts_with(b"\x89MCAP"), "its target is replaced");
    assert_eq!(listing(dir.path()), ["link.mcap", "link.urdf", "real.mcap", "real.urdf"], "no temporary file left");
}

/// A FIFO, a socket or a device (here through a link to /dev/null) as an output is refused with
/// one line and left as it is (renaming over it replaced it with a file; as root, /dev/full).
#[cfg(unix)]
#[test]
fn a_fifo_socket_or_device_output_is_refused() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempdir();
    let fifo = dir.path().join("out.urdf");
    mkfifo(&fifo);
    let e = dvrk_err(&["export", "urdf", "psm", "-o", fifo.to_str().unwrap()]);
    assert!(e.contains("-o: is a FIFO") && e.contains("not a regular file") && e.trim_end().lines().count() == 1, "{e}");
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo(), "the FIFO is left as it was");
    let sock = dir.path().join("out.mcap");
    let _listener = std::os::unix::net::UnixListener::bind(&sock).unwrap();
    let e = dvrk_err(&["sim", "--scene", "psm", "--duration", "0.01", "--out", sock.to_str().unwrap()]);
    assert!(e.contains("--out: is a socket"), "{e}");
    assert!(std::fs::metadata(&sock).unwrap().file_type().is_socket());
    let dev = dir.path().join("dev.json");
    std::os::unix::fs::symlink("/dev/null", &dev).unwrap();
    let e = dvrk_err(&["synth", "hidden-effect", "--seed", "1", "--duration", "1", "-o", dir.path().join("h.mcap").to_str().unwrap(), "--answer", dev.to_str().unwrap()]);
    assert!(e.contains("--answer: is a character device (the link's target /dev/null)"), "{e}");
    assert!(std::fs::symlink_metadata(&dev).unwrap().file_type().is_symlink());
    // The recorders' --out as well (the probe's `serve --out /dev/full` made the device a file;
    // a device is reached here through a link, so a regression cannot replace /dev/null itself).
    let fifo = dir.path().join("rec.mcap");
    mkfifo(&fifo);
    let e = dvrk_err(&["sim", "--scene", "psm", "--duration", "0.01", "--out", fifo.to_str().unwrap()]);
    assert!(e.contains("--out: is a FIFO"), "{e}");
    let dev_mcap = dir.path().join("dev.mcap");
    std::os::unix::fs::symlink("/dev/null", &dev_mcap).unwrap();
    let e = dvrk_err(&["serve", "--scene", "psm", "--domain", "232", "--duration", "0.05", "--out", dev_mcap.to_str().unwrap()]);
    assert!(e.contains("--out: is a character device (the link's target /dev/null)"), "{e}");
    let e = dvrk_err(&["serve", "--scene", "psm", "--domain", "232", "--duration", "0.05", "--out", fifo.to_str().unwrap()]);
    assert!(e.contains("--out: is a FIFO"), "{e}");
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo() && std::fs::symlink_metadata(&dev_mcap).unwrap().file_type().is_symlink());
    assert_eq!(listing(dir.path()), ["dev.json", "dev.mcap", "out.mcap", "out.urdf", "rec.mcap"], "nothing written");
}

/// Two runs writing one `--out` at once: the second is refused at its start (both used to exit 0
/// and one recording vanished).
#[cfg(unix)]
#[test]
fn a_second_writer_of_the_same_output_is_refused() {
    let dir = tempdir();
    let out = dir.path().join("run.mcap");
    let first = std::process::Command::new(crate::util::dvrk_bin())
        .args(["sim", "--scene", "psm", "--duration", "600", "--out", out.to_str().unwrap(), "--json"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while listing(dir.path()).is_empty() && started.elapsed().as_secs() < 30 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let second = crate::util::dvrk_within(20.0, &["sim", "--scene", "psm", "--duration", "0.1", "--out", out.to_str().unwrap()]);
    // Through a symlink too: the same target.
    let link = dir.path().join("link.mcap");
    std::os::unix::fs::symlink(&out, &link).unwrap();
    let third = crate::util::dvrk_within(20.0, &["export", "urdf", "psm", "-o", link.to_str().unwrap()]);
    std::process::Command::new("kill").args(["-KILL", &first.id().to_string()]).status().unwrap();
    let mut first = first;
    first.wait().unwrap();
    for (run, what) in [(second, "sim --out"), (third, "export -o through a link")] {
        let e = String::from_utf8_lossy(&run.stderr).to_string();
        assert_eq!(run.status.code(), Some(1), "{what}: {e}");
        assert!(e.contains("another process is writing it now") && e.trim_end().lines().count() == 1, "{what}: {e}");
    }
    // The killed run's temporary file is not locked any more: the next run takes it over.
    dvrk_ok(&["export", "urdf", "psm", "-o", out.to_str().unwrap()]);
    assert_eq!(listing(dir.path()), ["link.mcap", "run.mcap"], "the stale temporary file was taken over");
}
