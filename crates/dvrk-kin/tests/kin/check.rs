//! `dvrk model check` on models that compile but no robot has: a joint that moves nothing, a
//! length of 1e308 m (issue 45). The built-in models pass.

use dvrk_kin::check::check_model;
use dvrk_kin::load::{builtin_text, load_toml_text};
use std::path::Path;

fn psm_edited(from: &str, to: &str) -> dvrk_kin::Model {
    let text = builtin_text("psm").unwrap();
    assert!(text.contains(from), "{from}");
    load_toml_text(&text.replacen(from, to, 1), Path::new("psm-edited.toml"), None, None).unwrap()
}

#[test]
fn a_joint_that_drives_no_frame_is_a_problem() {
    let m = psm_edited("theta = \"q1 + pi/2\"", "theta = \"pi/2\"");
    let c = check_model(&m, 50).unwrap();
    assert!(!c.ok && c.problems.iter().any(|p| p == "joint `outer_yaw` drives no frame (no frame's theta or d depends on it)"), "{:?}", c.problems);
    assert!(check_model(&dvrk_kin::load("psm", None).unwrap(), 50).unwrap().ok);
}

#[test]
fn a_length_no_dvrk_has_is_a_problem() {
    let m = psm_edited("theta = \"q1 + pi/2\"", "theta = \"q1 + pi/2\"\nd = 1e308");
    let c = check_model(&m, 50).unwrap();
    assert!(!c.ok && c.problems.iter().any(|p| p.contains("m from the base (a dVRK arm reaches about 1 m")), "{:?}", c.problems);
}
