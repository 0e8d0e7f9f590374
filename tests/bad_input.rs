//! Bad model files, bad data files and bad flags: a one-line error that names the file, the
//! field and the value; never a panic.

use crate::util::{dvrk_err, tempdir};
use std::path::Path;

/// The shipped PSM model file with one edit.
fn psm_with(dir: &Path, name: &str, from: &str, to: &str) -> String {
    let text = dvrk_kin::load::builtin_text("psm").unwrap();
    assert!(text.contains(from), "the edit applies: {from}");
    let path = dir.join(name);
    std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
    path.to_str().unwrap().to_string()
}

fn assert_one_line(err: &str, must_contain: &[&str]) {
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(err.starts_with("error: "), "{err}");
    for s in must_contain {
        assert!(err.contains(s), "`{s}` missing from: {err}");
    }
}

#[test]
fn bad_model_files_name_file_field_and_value() {
    let dir = tempdir();
    let cases = [
        ("missing.toml", "index = 4\nname = \"pitch_front\"\nparent = 2\n", "index = 4\nname = \"pitch_front\"\n", vec!["missing.toml", "parent"]),
        ("unknown_parent.toml", "index = 6\nname = \"pitch_bottom\"\nparent = 3", "index = 6\nname = \"pitch_bottom\"\nparent = 99", vec!["unknown_parent.toml", "pitch_bottom", "parent", "99"]),
        ("cycle.toml", "index = 1\nname = \"yaw\"\nparent = 0", "index = 1\nname = \"yaw\"\nparent = 2", vec!["cycle.toml", "cycle"]),
        ("nan.toml", "a = 0.516", "a = nan", vec!["nan.toml", "pitch_end", ".a", "NaN"]),
        ("string.toml", "lower = -0.925025", "lower = \"abc\"", vec!["string.toml", "lower", "abc"]),
        ("expr.toml", "theta = \"-q2\"", "theta = \"-q2 + gamma\"", vec!["expr.toml", "theta", "gamma"]),
        ("typo.toml", "upper = 0.24", "uper = 0.24", vec!["typo.toml", "uper"]),
        ("limits.toml", "lower = -1.588", "lower = 2.0", vec!["limits.toml", "outer_yaw", "lower", "2"]),
        ("closure.toml", "partner = 6", "partner = 42", vec!["closure.toml", "c1", "partner", "42"]),
    ];
    for (file, from, to, expect) in cases {
        let path = psm_with(dir.path(), file, from, to);
        let err = dvrk_err(&["model", "check", &path]);
        assert_one_line(&err, &expect);
        // The library gives the same message.
        let lib = dvrk_kin::load(&path, None).unwrap_err().to_string();
        assert!(err.contains(&lib), "{err} vs {lib}");
    }
}

#[test]
fn bad_files_and_flags_are_errors_not_panics() {
    let dir = tempdir();
    let d = dir.path();
    let json = d.join("bad.json");
    std::fs::write(&json, "{ \"DH\": { \"joints\": [ { \"name\": \"yaw\", \"alpha\": \"x\" } ] } }").unwrap();
    assert_one_line(&dvrk_err(&["fk", json.to_str().unwrap()]), &["bad.json", "DH.joints[0]"]);
    std::fs::write(&json, "{ not json").unwrap();
    assert_one_line(&dvrk_err(&["fk", json.to_str().unwrap()]), &["bad.json", "not valid JSON"]);
    let missing = d.join("nope.toml");
    assert_one_line(&dvrk_err(&["model", "show", missing.to_str().unwrap()]), &["nope.toml", "psm"]);
    assert_one_line(&dvrk_err(&["fk", "psm", "--q", "1,2,3"]), &["--q", "expected 7, got 3"]);
    assert_one_line(&dvrk_err(&["fk", "psm", "--q", "0,0,0.1,0,0,0,inf"]), &["--q", "inf"]);
    // Issue 63: 1e308 is said as given, never as the NaN it overflowed to.
    assert_one_line(&dvrk_err(&["gc", "--gravity", "1e308,0,0"]), &["--gravity 1e308,0,0", "at most 98.1 m/s^2"]);
    assert_one_line(&dvrk_err(&["identify", "--recording", json.to_str().unwrap(), "--model", "psm", "--gravity", "0,0,-1e308"]), &["--gravity 0,0,-1e308", "at most 98.1 m/s^2"]);
    let out = crate::util::dvrk_within(20.0, &["gc", "--q", "1e308,0,0,0,0,0,0"]);
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && e.contains("note: --q: joint outer_yaw = 1.000000e308: outside its limits"), "{e}");
    assert_one_line(&dvrk_err(&["fk", "psm", "--q", "3,0,0.1,0,0,0,0"]), &["outer_yaw", "3", "limits"]);
    assert_one_line(&dvrk_err(&["ik", "psm", "--pose", "0,0,0,0,0,0,2"]), &["--pose", "norm"]);
    assert_one_line(&dvrk_err(&["ik", "psm", "--pose", "0,0,0,0,0"]), &["--pose", "7"]);
    assert_one_line(&dvrk_err(&["model", "check", "ecm", "--tool", "x.json"]), &["x.json"]);
    assert_one_line(&dvrk_err(&["model", "check", "psm", "--samples", "0"]), &["--samples"]);
    // Issue 45: 10^12 configurations were a 24 TB allocation and an abort.
    assert_one_line(&dvrk_err(&["model", "check", "psm", "--samples", "1000000000000"]), &["--samples = 1.000000e12", "1..=10000000"]);
    // Huge numbers in messages in {:.6e} form, and durations bounded before any allocation.
    assert_one_line(&dvrk_err(&["fk", "psm", "--q", "1e300,0,0.1,0,0,0,0"]), &["outer_yaw = 1.000000e300", "limits"]);
    assert_one_line(&dvrk_err(&["synth", "hidden-effect", "--duration", "1e12", "-o", "/tmp/never.mcap", "--answer", "/tmp/never.json"]), &["duration", "1.000000e12", "1800 s"]);
    // Issue 63 item 6: an address no interface has (TEST-NET-3) was taken and served nowhere.
    assert_one_line(&dvrk_err(&["serve", "--scene", "psm", "--network", "203.0.113.7", "--duration", "0.1"]), &["--network", "203.0.113.7", "no interface of this machine has that address"]);
    assert_one_line(&dvrk_err(&["sim", "--scene", "psm", "--duration", "1e300", "--plot", "/tmp/never.png"]), &["traced samples", "5.000000e301"]);
    let dir = crate::util::tempdir();
    let scene = dir.path().join("tiny-dt.toml");
    let text = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("models/scenes/psm.toml")).unwrap();
    std::fs::write(&scene, text.replace("dt = 0.001", "dt = 1e-12")).unwrap();
    assert_one_line(&dvrk_err(&["sim", "--scene", scene.to_str().unwrap()]), &["tiny-dt.toml", "dt", "1.000000e-12 s is not in [1e-6, 0.1]"]);
    // 30,000 levels of nesting overflowed the stack (exit 134): refused before parsing.
    let deep_json = dir.path().join("deep.json");
    std::fs::write(&deep_json, format!("{}{}", "[".repeat(30000), "]".repeat(30000))).unwrap();
    assert_one_line(&dvrk_err(&["model", "check", deep_json.to_str().unwrap()]), &["deep.json", "nested 30000 levels deep"]);
    // A 30,000-deep TOML array: the toml crate refuses it, and the error echoed the whole 60 kB
    // line (issue 45); now the field and the value's first 80 characters.
    let deep_toml = dir.path().join("deep.toml");
    std::fs::write(&deep_toml, format!("name = \"x\"\nvalue = {}{}\n", "[".repeat(30000), "]".repeat(30000))).unwrap();
    let e = dvrk_err(&["model", "check", deep_toml.to_str().unwrap()]);
    assert_one_line(&e, &["deep.toml", "line 2", "field `value`", "(60000 characters)"]);
    assert!(e.len() < 600, "{} bytes: {}", e.len(), &e[..200]);
    // A file the size of a recording given as a model is refused before it is read whole.
    let big = dir.path().join("big.toml");
    std::fs::File::create(&big).unwrap().set_len(65 << 20).unwrap();
    assert_one_line(&dvrk_err(&["model", "check", big.to_str().unwrap()]), &["big.toml", "68157440 bytes", "at most 67108864 bytes"]);
    let deep_urdf = dir.path().join("deep.urdf");
    std::fs::write(&deep_urdf, format!("<robot name=\"r\">{}{}</robot>", "<a>".repeat(30000), "</a>".repeat(30000))).unwrap();
    assert_one_line(&dvrk_err(&["model", "check", deep_urdf.to_str().unwrap()]), &["deep.urdf", "nested 30001 levels deep"]);
    // A replay row with a NaN setpoint was dropped silently (issue 45): now named.
    let replay = dir.path().join("replay.csv");
    std::fs::write(&replay, "time,q1,q2,q3,q4,q5,q6,q7\n0,0.2,0.1,0.12,0,0,0,0\n0.5,nan,0.1,0.12,0,0,0,0\n1,0.3,0.1,0.12,0,0,0,0\n").unwrap();
    assert_one_line(&dvrk_err(&["sim", "--scene", "psm", "--trajectory", &format!("replay:{}", replay.display())]), &["replay.csv", "line 3", "every joint's setpoint"]);
    // CSV input: a missing column, a word, a NaN.
    for (content, expect) in [
        ("q1,q2,q3\n0,0,0.1\n", vec!["q4", "missing column"]),
        ("q1,q2,q3,q4,q5,q6,q7\n0,0,0.1,0,0,zero,0\n", vec!["line 2", "q6", "zero"]),
        ("q1,q2,q3,q4,q5,q6,q7\n0,0,0.1,0,0,0,0\n0,NaN,0.1,0,0,0,0\n", vec!["line 3", "q2", "NaN"]),
    ] {
        let input = d.join("joints.csv");
        let output = d.join("poses.csv");
        std::fs::write(&input, content).unwrap();
        let err = dvrk_err(&["fk", "psm", "--input", input.to_str().unwrap(), "--output", output.to_str().unwrap()]);
        let mut expect = expect;
        expect.push("joints.csv");
        assert_one_line(&err, &expect);
        assert!(!output.exists(), "no partial output is left behind");
    }
    // Usage errors are clap's (status 2), still no panic.
    dvrk_err(&["fk"]);
    dvrk_err(&["model", "frobnicate"]);
}

/// A dVRK file that is not what the flag takes (issue 45): the PSM's arm file given as its tool
/// (three joints too; taken as a tool, the yaw's limits became the roll's and the tool length
/// 0), and a tool file whose coupling does not fit the model's four tool joints (dropped without
/// a word when the coupling was built).
#[test]
fn a_dvrk_file_given_for_the_wrong_flag_is_named() {
    let Some(arm) = crate::util::external("dvrk-config/PSM.json") else { return };
    assert_one_line(&dvrk_err(&["model", "check", "psm", "--tool", arm.to_str().unwrap()]), &["PSM.json", "DH.joints[2].type", "an arm's file"]);
    let dir = tempdir();
    let tool = dir.path().join("three-by-three.json");
    let joint = |d: f64| format!("{{\"alpha\": -1.5708, \"A\": 0.0, \"theta\": 0.0, \"D\": {d}, \"type\": \"revolute\", \"qmin\": -1.0, \"qmax\": 1.0}}");
    std::fs::write(
        &tool,
        format!(
            "{{\"DH\": {{\"convention\": \"modified\", \"joints\": [{}, {}, {}]}}, \"coupling\": {{\"ActuatorToJointPosition\": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}}}}",
            joint(0.4162),
            joint(0.0),
            joint(0.0)
        ),
    )
    .unwrap();
    assert_one_line(&dvrk_err(&["model", "check", "psm", "--tool", tool.to_str().unwrap()]), &["three-by-three.json", "coupling.ActuatorToJointPosition", "3x3", "4 joints"]);
}

/// A fixed-size figure with an extra entry (issue 45): serde read a 4-row inertia as its first
/// three rows, and a 4-number centre of mass as its first three, without a word.
#[test]
fn an_extra_row_or_number_is_named() {
    let dir = tempdir();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let inertials = std::fs::read_to_string(root.join("models/inertials/psm.toml")).unwrap();
    let row = "[-0.00000728309, -0.000485862533, 0.008249296431]]";
    assert!(inertials.contains(row));
    let file = dir.path().join("four-rows.toml");
    std::fs::write(&file, inertials.replacen(row, "[-0.00000728309, -0.000485862533, 0.008249296431], [1.0, 2.0, 3.0]]", 1)).unwrap();
    let scene = dir.path().join("scene.toml");
    let text = std::fs::read_to_string(root.join("models/scenes/psm.toml")).unwrap();
    std::fs::write(&scene, text.replace("inertials = \"psm\"", &format!("inertials = {:?}", file.display().to_string()))).unwrap();
    assert_one_line(&dvrk_err(&["sim", "--scene", scene.to_str().unwrap(), "--duration", "0.1"]), &["four-rows.toml", "field `inertia`", "4 rows of [3, 3, 3, 3] numbers where a 3x3 matrix has 3 rows of 3"]);
    let model = psm_with(dir.path(), "extra.toml", "point = [0.150, 0.0, 0.0]", "point = [0.150, 0.0, 0.0, 1.0]");
    assert_one_line(&dvrk_err(&["model", "check", &model]), &["extra.toml", "4 numbers where a 3-vector has 3"]);
}

/// A figure no robot has that still passes every check (a 1e306 kg counterweight) made the MJCF
/// export write a cable's stiffness="inf" with exit 0 (issue 45): now one line naming the
/// element, and no file.
#[test]
fn an_overflowing_figure_is_not_exported() {
    let dir = tempdir();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let inertials = std::fs::read_to_string(root.join("models/inertials/psm.toml")).unwrap();
    let at = inertials.find("name = \"counterweight_link\"").unwrap();
    let mass = at + inertials[at..].find("mass = ").unwrap();
    let end = mass + inertials[mass..].find('\n').unwrap();
    let file = dir.path().join("heavy.toml");
    std::fs::write(&file, format!("{}mass = 1e306{}", &inertials[..mass], &inertials[end..])).unwrap();
    let scene = dir.path().join("scene.toml");
    let text = std::fs::read_to_string(root.join("models/scenes/psm.toml")).unwrap();
    std::fs::write(&scene, text.replace("inertials = \"psm\"", &format!("inertials = {:?}", file.display().to_string()))).unwrap();
    let out = dir.path().join("psm.xml");
    assert_one_line(&dvrk_err(&["export", "mjcf", scene.to_str().unwrap(), "-o", out.to_str().unwrap()]), &["MJCF export", "stiffness=\"inf\"", "cable:counterweight_link"]);
    assert!(!out.exists());
}

/// Issue 43 (validate before load): a `--plot` whose format is unknown is refused before the
/// recording is read, so the error names the flag, not whatever the recording holds.
#[test]
fn serve_and_fk_check_their_flags_before_loading_the_scene_or_model() {
    // Neither the scene nor the model exists: the flag's error must come first, naming it.
    assert_one_line(&dvrk_err(&["serve", "--scene", "no-such-scene", "--domain", "300"]), &["--domain 300", "must be in 0..="]);
    assert_one_line(&dvrk_err(&["fk", "no-such-model", "--actuators"]), &["--actuators", "--q"]);
}

/// Issue 63: a rate that is not one sample every whole number of time steps was served or
/// recorded at the nearest whole number (`--rate 300` at 1 ms steps: every 3 steps, 333.3 Hz,
/// with nothing said). It is refused, naming the rates on either side; rates that divide are
/// served as asked.
#[test]
fn a_rate_the_time_step_does_not_divide_is_refused_with_the_rates_on_either_side() {
    let dir = crate::util::tempdir();
    let out = dir.path().join("r.mcap");
    let o = out.to_str().unwrap();
    assert_one_line(&dvrk_err(&["sim", "--scene", "psm", "--duration", "0.05", "--out", o, "--rate", "300"]), &["300", "333.333 Hz (every 3 steps)", "250 Hz (every 4 steps)"]);
    assert!(!out.exists());
    assert_one_line(&dvrk_err(&["sim", "--scene", "psm", "--duration", "0.05", "--out", o, "--rate", "700"]), &["700", "1000 Hz (every step)", "500 Hz (every 2 steps)"]);
    assert_one_line(&dvrk_err(&["sim", "--scene", "psm", "--duration", "0.05", "--out", o, "--rate", "150"]), &["150", "166.667 Hz (every 6 steps)", "142.857 Hz (every 7 steps)"]);
    // Before any DDS participant starts: the serve loop's check comes first.
    assert_one_line(&dvrk_err(&["serve", "--scene", "psm", "--domain", "231", "--duration", "0.05", "--rate", "300"]), &["publishing rate (Hz) = 300", "333.333 Hz", "250 Hz"]);
    assert_one_line(&dvrk_err(&["serve", "--scene", "psm", "--domain", "231", "--duration", "0.05", "--rate", "700"]), &["publishing rate (Hz) = 700", "1000 Hz", "500 Hz"]);
    crate::util::dvrk_ok(&["sim", "--scene", "psm", "--duration", "0.05", "--out", o, "--rate", "250"]);
    assert!(out.exists());
}

#[test]
fn synth_mocap_checks_its_flags_before_loading_the_model() {
    let dir = crate::util::tempdir();
    let out = dir.path().join("m.mcap");
    let o = out.to_str().unwrap();
    // The model does not exist: each flag's error must come first, naming the flag.
    assert_one_line(&dvrk_err(&["synth", "mocap", "--model", "no-such-model", "--layout", "pose", "-o", o]), &["--layout", "`pose`"]);
    assert_one_line(&dvrk_err(&["synth", "mocap", "--model", "no-such-model", "--noise-mm=-1", "-o", o]), &["--noise-mm", "-1"]);
    assert_one_line(&dvrk_err(&["synth", "mocap", "--model", "no-such-model", "--noise-mm", "1e308", "-o", o]), &["--noise-mm", "1.000000e308", "[0, 100] mm"]);
    // A rate whose sample count no integer holds: said in the user's figures (was "18446744073709551615 samples").
    assert_one_line(&dvrk_err(&["synth", "mocap", "--rate", "1e308", "-o", o]), &["20 s at 1.000000e308 Hz", "more than this tool writes"]);
    let txt = dir.path().join("m.txt");
    assert_one_line(&dvrk_err(&["synth", "mocap", "--model", "no-such-model", "-o", txt.to_str().unwrap()]), &["m.txt", "unknown format `.txt`"]);
    assert!(!out.exists());
}

#[test]
fn calib_refuses_a_plot_format_before_reading_the_recording() {
    let dir = crate::util::tempdir();
    let junk = dir.path().join("r.csv");
    std::fs::write(&junk, "not a recording").unwrap();
    let config = dir.path().join("axes.toml");
    std::fs::write(&config, "not read either").unwrap();
    let (r, c, jpg) = (junk.to_str().unwrap(), config.to_str().unwrap(), dir.path().join("p.jpg"));
    let jpg = jpg.to_str().unwrap();
    assert_one_line(&dvrk_err(&["calib", "pivot", "--recording", r, "--plot", jpg]), &["p.jpg", "--plot", "unknown image format"]);
    assert_one_line(&dvrk_err(&["calib", "axes", "--recording", r, "--config", c, "--plot", jpg]), &["p.jpg", "--plot", "unknown image format"]);
}

/// Issue 63 item 3: inputs that never end or never start (`/dev/zero`, a FIFO) are refused at
/// once with one line naming the file, by every reader (they grew to GBs, or waited forever).
#[cfg(unix)]
#[test]
fn a_device_or_fifo_input_is_refused_at_once() {
    let dir = tempdir();
    let fifo = dir.path().join("in.fifo");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let report = dir.path().join("r.json");
    let (out_csv, out_mcap) = (dir.path().join("o.csv"), dir.path().join("o.mcap"));
    let (out_csv, out_mcap) = (out_csv.to_str().unwrap(), out_mcap.to_str().unwrap());
    for input in ["/dev/zero", fifo.to_str().unwrap()] {
        let replay = format!("replay:{input}");
        let cases: Vec<Vec<&str>> = vec![
            vec!["identify", "--recording", input, "--model", "psm"],
            vec!["fk", "psm", "--input", input, "--output", out_csv],
            vec!["gc", "--recording", input],
            vec!["calib", "pivot", "--recording", input],
            vec!["teleop", "--mtm", input, "--scene", "psm", "--out", out_mcap],
            vec!["sim", "--scene", "psm", "--trajectory", &replay, "--duration", "0.01"],
            vec!["discrepancy", "--model", "psm", "--recording", input, "--report", report.to_str().unwrap()],
            vec!["sim", "--scene", input, "--duration", "0.01"],
            vec!["serve", "--scene", input],
            vec!["model", "check", input],
            vec!["fk", input, "--q", "0"],
        ];
        for args in &cases {
            let out = crate::util::dvrk_within(5.0, args);
            let e = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{args:?}: {e}");
            assert!(e.contains(input) && e.contains("not a regular file") && !e.contains("panicked"), "{args:?}: {e}");
        }
    }
}

/// A recording that is one long line (a file of zeros or of one character) is refused after
/// its first MiB, and an error never quotes more than a short excerpt of the file (the whole
/// header line used to be repeated: 1 GB to stderr).
#[test]
fn a_long_line_is_refused_and_quoted_short() {
    let dir = tempdir();
    let report = dir.path().join("r.json");
    let endless = dir.path().join("endless.csv");
    std::fs::write(&endless, vec![b'a'; 3 << 20]).unwrap();
    let wide = dir.path().join("wide.csv");
    std::fs::write(&wide, format!("time,{}\n0,1\n", (0..60_000).map(|k| format!("x{k}")).collect::<Vec<_>>().join(","))).unwrap();
    for (file, format, want) in [(&endless, "auto", "line 1 is longer than 1048576 bytes"), (&endless, "csv", "line 1 is longer than 1048576 bytes"), (&wide, "csv", "the header is: time,x0,x1")] {
        let out = crate::util::dvrk_within(5.0, &["discrepancy", "--model", "psm", "--recording", file.to_str().unwrap(), "--format", format, "--report", report.to_str().unwrap()]);
        let e = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{}", &e[..e.len().min(300)]);
        assert!(e.len() < 400, "a short message, not {} bytes: {}", e.len(), &e[..300]);
        assert_one_line(&e, &[file.to_str().unwrap(), want]);
    }
}
