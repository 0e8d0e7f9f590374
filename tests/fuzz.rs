//! Fuzz targets, one per parser (issue 45, item 4): model TOML, inertials, scene, dVRK JSON,
//! URDF, the joint CSV readers, the WPI CSV, the MCAP joint-state reader, ROS 1 bags and the MTM motion reader. Each mutates files
//! the parser reads every day (the repository's models, scenes and inertials; exported URDF; a
//! recorded MCAP; the dVRK's own JSON and the WPI recordings where `../shared` has them) with
//! byte edits, deletions, inserted tokens (`nan`, `1e308`, brackets, quotes...), numbers replaced
//! and truncation, and asks one thing: no panic. A parser may refuse the input (it should,
//! mostly), never crash.
//!
//! In the test suite each target runs for [`SMOKE`] (about a minute in all, on bolero's random
//! engine: stable Rust, no instrumentation). Longer on stable: `BOLERO_RANDOM_TEST_TIME_MS=600000
//! cargo test --release --test tests fuzz::model_toml`; coverage-guided with libFuzzer (nightly,
//! cargo-bolero, the instrumented binary run directly): docs/fuzzing.md.

use bolero::check;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Time per target in the test suite.
const SMOKE: Duration = Duration::from_secs(5);

/// What an edit may insert or put in place of a number.
const TOKENS: [&str; 24] = [
    "nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "0", "-0", "99999999999999999999999", "1e999", "\"", "[", "]", "{", "}", ",", "=", "\n",
    "[[", "]]", "<", ">", "\u{0}", "é",
];

/// One mutated input: which seed, the edits `(position, op)`, and where to cut it.
type Input = (u8, Vec<(u16, u8)>, Option<u16>);

/// `seed` edited by `edits` and cut at `cut` (positions wrap around the current length).
fn mutate(seed: &[u8], edits: &[(u16, u8)], cut: Option<u16>) -> Vec<u8> {
    let mut b = seed.to_vec();
    for &(pos, op) in edits {
        if b.is_empty() {
            break;
        }
        let at = pos as usize % b.len();
        let token = TOKENS[(op / 4) as usize % TOKENS.len()].as_bytes();
        match op % 4 {
            0 => b[at] = op,
            1 => {
                b.remove(at);
            }
            2 => {
                b.splice(at..at, token.iter().copied());
            }
            _ => {
                // The number (or word) at `at` replaced by the token.
                let end = (at..b.len()).find(|&i| !(b[i].is_ascii_alphanumeric() || b"+-.".contains(&b[i]))).unwrap_or(b.len());
                b.splice(at..end, token.iter().copied());
            }
        }
    }
    if let Some(c) = cut {
        b.truncate(c as usize % (b.len() + 1));
    }
    b
}

/// Run `parse` on mutated `seeds` for [`SMOKE`]: a panic fails the test with the input.
fn fuzz(seeds: &[Vec<u8>], parse: impl Fn(&[u8]) + std::panic::RefUnwindSafe) {
    assert!(!seeds.is_empty(), "no seed");
    check!().with_type::<Input>().with_test_time(SMOKE).with_shrink_time(Duration::from_secs(20)).for_each(|(s, edits, cut)| {
        let seed = &seeds[*s as usize % seeds.len()];
        parse(&mutate(seed, edits, *cut));
    });
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

/// The files of `dir` whose names end with `ext`.
fn files(dir: &Path, ext: &str) -> Vec<Vec<u8>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir).map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect()).unwrap_or_default();
    v.sort();
    v.into_iter().filter(|p| p.to_string_lossy().ends_with(ext)).map(|p| std::fs::read(p).unwrap()).collect()
}

fn shared(rel: &str) -> Option<PathBuf> {
    let p = root().join("../shared/data/external").join(rel);
    p.exists().then_some(p)
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A scratch file the path-based readers read: rewritten for every input.
struct Scratch {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl Scratch {
    fn new(name: &str) -> Scratch {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        Scratch { _dir: dir, path }
    }
    fn with(&self, bytes: &[u8]) -> &Path {
        std::fs::write(&self.path, bytes).unwrap();
        &self.path
    }
}

#[test]
fn model_toml() {
    let seeds = files(&root().join("models"), ".toml");
    fuzz(&seeds, |b| {
        let _ = dvrk_kin::load::load_toml_text(&text(b), Path::new("fuzz.toml"), None, None);
    });
}

#[test]
fn inertials_toml() {
    let model = dvrk_kin::load("psm", None).unwrap();
    let seeds = files(&root().join("models/inertials"), ".toml");
    fuzz(&seeds, |b| {
        let _ = dvrk_sim::inertials::Inertials::parse(&text(b), "fuzz.toml", &model);
    });
}

#[test]
fn scene_toml() {
    let dir = root().join("models/scenes");
    let seeds = files(&dir, ".toml");
    fuzz(&seeds, |b| {
        let _ = dvrk_sim::Scene::parse(&text(b), "fuzz.toml", Some(&dir));
    });
}

#[test]
fn dvrk_json() {
    let Some(dir) = shared("dvrk-config") else {
        eprintln!("skipped: ../shared/data/external/dvrk-config is absent");
        return;
    };
    let seeds = files(&dir, ".json");
    fuzz(&seeds, |b| {
        if let Ok(json) = dvrk_kin::dvrk_json::parse_json(&text(b), Path::new("fuzz.json")) {
            let _ = dvrk_kin::dvrk_json::serial_spec_from_json(&json, "fuzz").map(dvrk_kin::Model::compile);
        }
    });
}

#[test]
fn urdf() {
    let seeds: Vec<Vec<u8>> = ["psm", "ecm", "mtmr"].iter().map(|m| dvrk_kin::urdf::export_urdf(&dvrk_kin::load(m, None).unwrap()).unwrap().into_bytes()).collect();
    fuzz(&seeds, |b| {
        let _ = dvrk_kin::urdf::import_urdf_str(&text(b), "fuzz");
    });
}

/// A joint CSV as `dvrk discrepancy` reads it: time, setpoints, positions, efforts of the PSM.
fn joint_csv_seed() -> Vec<u8> {
    let model = dvrk_kin::load("psm", None).unwrap();
    let names: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    let mut s = String::from("time");
    for kind in ["setpoint", "position", "effort"] {
        for n in &names {
            s += &format!(",{kind}_{n}");
        }
    }
    s.push('\n');
    for i in 0..40 {
        s += &format!("{}", i as f64 * 0.005);
        for k in 0..3 * names.len() {
            s += &format!(",{}", 0.01 * ((i * 7 + k * 3) % 11) as f64);
        }
        s.push('\n');
    }
    s.into_bytes()
}

#[test]
fn joint_csv() {
    let model = dvrk_kin::load("psm", None).unwrap();
    let scratch = Scratch::new("log.csv");
    fuzz(&[joint_csv_seed()], |b| {
        let _ = dvrk_sim::recording::read_joint_log_csv(scratch.with(b), &model);
    });
}

#[test]
fn wpi_csv() {
    let model = dvrk_kin::load("psm", None).unwrap();
    let mut seeds = vec![(0..40).map(|i| (0..21).map(|k| format!("{}", 0.001 * (i * 3 + k) as f64)).collect::<Vec<_>>().join(",") + "\n").collect::<String>().into_bytes()];
    if let Some(p) = shared("wpi-dvrk-dynamics/psm_one_results.csv") {
        let t = std::fs::read_to_string(p).unwrap();
        seeds.push(t.lines().take(60).collect::<Vec<_>>().join("\n").into_bytes());
    }
    let scratch = Scratch::new("wpi.csv");
    fuzz(&seeds, |b| {
        let path = scratch.with(b);
        let _ = dvrk_calib::discrepancy::read_log(path, "wpi-csv", &model, "PSM1");
        let _ = dvrk_sim::recording::read_wpi_csv(path, &model);
    });
}

#[test]
fn pose_csv() {
    let seed = b"t,x,y,z,qx,qy,qz,qw\n0,0.1,0.2,0.3,0,0,0,1\n0.01,0.1,0.2,0.31,0,0,0.01,1\n0.02,0.1,0.21,0.3,0.01,0,0,1\n".to_vec();
    let scratch = Scratch::new("poses.csv");
    fuzz(&[seed], |b| {
        let path = scratch.with(b);
        let _ = dvrk_sim::recording::read_plain_csv(path);
        let _ = dvrk_sim::recording::read_motive_csv(path);
    });
}

#[test]
fn mcap_joint_states() {
    let model = dvrk_kin::load("psm", None).unwrap();
    // A short recording of the PSM scene, as `dvrk sim --out` writes it.
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("seed.mcap");
    let scene = dvrk_sim::Scene::load("psm").unwrap();
    let options = dvrk_sim::RunOptions { duration: 0.05, trajectory: dvrk_sim::run::TrajectoryKind::Sine, sim: Default::default() };
    dvrk_sim::run_recorded(&scene, &options, Some(&dvrk_sim::RecordOptions { path: rec.clone(), rate: 200.0 }), |_| {}).unwrap();
    let seed = std::fs::read(&rec).unwrap();
    let scratch = Scratch::new("fuzz.mcap");
    fuzz(&[seed], |b| {
        let path = scratch.with(b);
        let _ = dvrk_calib::discrepancy::read_log(path, "mcap", &model, "PSM1");
        let _ = dvrk_calib::identify::read_log(path, "mcap", &model, "PSM1");
        let _ = dvrk_calib::read_recording(path, &Default::default());
    });
}

#[test]
fn mcap_mtm_motion() {
    // The MTM scene recorded as `dvrk sim --out` writes it: /MTMR/measured_cp, its joints and
    // gripper; what `dvrk teleop --mtm` reads (read_mtm), mutated.
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("seed.mcap");
    let scene = dvrk_sim::Scene::load("mtm").unwrap();
    let options = dvrk_sim::RunOptions { duration: 0.05, trajectory: dvrk_sim::run::TrajectoryKind::Hold, sim: Default::default() };
    dvrk_sim::run_recorded(&scene, &options, Some(&dvrk_sim::RecordOptions { path: rec.clone(), rate: 200.0 }), |_| {}).unwrap();
    let seed = std::fs::read(&rec).unwrap();
    assert!(dvrk_sim::recording::read_mtm(&rec, None).is_ok_and(|l| l.arm == "MTMR" && l.len() == 10), "the seed reads");
    let scratch = Scratch::new("mtm.mcap");
    fuzz(&[seed], |b| {
        let path = scratch.with(b);
        let _ = dvrk_sim::recording::read_mtm(path, None);
        let _ = dvrk_sim::recording::read_mtm(path, Some("MTML"));
    });
}

#[test]
fn ros1_bags() {
    // ROS 1 bags as the dVRK records them (uncompressed, bz2 and lz4 chunks), written by the
    // Python `rosbags` package from a second of a real WPI recording (dvrk-calib's layout
    // fixtures), read by the bag reader's every path (chunks, connections, index, decompression).
    let Some(wpi) = shared("wpi-dvrk-dynamics/insertion-payload/one_no_weight_results.csv") else {
        eprintln!("SKIPPED: ../shared's WPI recordings are not here");
        return;
    };
    let python = std::process::Command::new("python3").args(["-c", "import mcap_ros2, rosbags, numpy"]).output().is_ok_and(|o| o.status.success());
    if !python {
        eprintln!("SKIPPED: python3 with rosbags, mcap-ros2-support and numpy is not available (bash scripts/test.sh installs them)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let script = root().join("crates/dvrk-calib/tests/calib/writers/dvrk_layouts.py");
    let out = std::process::Command::new("python3").arg(&script).arg(&wpi).arg(dir.path()).arg("1").output().unwrap();
    assert!(out.status.success(), "the bag writer failed: {}", String::from_utf8_lossy(&out.stderr));
    let seeds = files(dir.path(), ".bag");
    assert!(seeds.len() >= 4, "{} bags", seeds.len());
    let model = dvrk_kin::load("psm", None).unwrap();
    let scratch = Scratch::new("fuzz.bag");
    fuzz(&seeds, |b| {
        let path = scratch.with(b);
        let _ = dvrk_calib::identify::read_log(path, "bag", &model, "PSM1");
        let _ = dvrk_calib::read_recording(path, &Default::default());
        let _ = dvrk_sim::recording::read_mtm(path, None);
    });
}
