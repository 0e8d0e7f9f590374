//! Helpers: the PSM, synthetic scenarios, and the true axes of a model.

use dvrk_calib::mocap::axes_config::AxesConfig;
use dvrk_calib::mocap::synth::{Scenario, SynthMotion, SynthOptions};
use dvrk_kin::{FrameRef, Model, Pose};
use nalgebra::{Point3, Vector3};
use std::path::Path;

/// Discrepancy options (no tracking replay) that analyse one candidate, the yaw's viscous
/// friction, for tests that read only the residual before any effect: the model with its
/// inertias refitted, which the search over the candidates leaves as it is (the same figures
/// to the last digit, measured on the WPI PSM: `identify.rs`).
pub fn residual_before_only() -> dvrk_calib::discrepancy::Options {
    let only = dvrk_kin::effects::EffectSpec { name: "viscous_friction".into(), joint: Some("outer_yaw".into()), link: None, actuator: None, parameters: Default::default(), source: String::new() };
    dvrk_calib::discrepancy::Options { tracking: false, only: Some(only), ..Default::default() }
}

pub fn psm() -> Model {
    dvrk_kin::load("psm", None).expect("built-in psm")
}

/// A scenario of `model` with the given motion, noise (m), length (s) and occlusion rate.
pub fn scenario(model: &Model, motion: SynthMotion, noise: f64, duration: f64, occlusion: f64) -> Scenario {
    Scenario::new(model, &SynthOptions { motion, noise, duration, occlusion, ..Default::default() }).expect("scenario")
}

/// The axes configuration the synthetic tracker writes for its clusters.
pub fn config(s: &Scenario) -> AxesConfig {
    AxesConfig::from_toml(&s.axes_config_toml(), Path::new("markers.toml")).expect("synth config parses")
}

/// The true axis `name` (Table 6 label) of `model` at `q`, in the model's base frame: a point
/// and the unit direction (frame origins and closure points on the z axes of their frames).
pub fn true_axis(model: &Model, q: &[f64], name: &str) -> (Vector3<f64>, Vector3<f64>) {
    let poses = model.fk(q).expect("fk");
    let frame = |i: i64| -> Pose { poses[model.frame_id(&FrameRef::Index(i)).expect("frame")] };
    let closure = |c: &str| {
        let c = model.closures.iter().find(|x| x.name == c).expect("closure");
        (poses[c.frame] * Point3::from(c.point)).coords
    };
    let (p, f) = match name {
        "c1" => (closure("c1"), frame(4)),
        "c2" => (closure("c2"), frame(7)),
        n => {
            let i: i64 = n.parse().expect("axis label");
            (frame(i).translation.vector, frame(i))
        }
    };
    (p, f.rotation.matrix().column(2).into_owned())
}

/// The model's Table 6 distances at q1 = q2 = 0, computed from its kinematics alone (as
/// tests/paper_tables.rs does): planar distances between the axes' points.
pub fn model_table6(model: &Model) -> Vec<(&'static str, &'static str, f64)> {
    let mut q = model.home();
    q[0] = 0.0;
    q[1] = 0.0;
    let (_, z) = true_axis(model, &q, "3");
    let planar = |a: &str, b: &str| {
        let v = true_axis(model, &q, a).0 - true_axis(model, &q, b).0;
        (v - z * z.dot(&v)).norm()
    };
    [("3", "4"), ("3", "6"), ("4", "c1"), ("6", "c1"), ("3", "7"), ("6", "8"), ("7", "c2"), ("6", "7")]
        .into_iter()
        .map(|(a, b)| (a, b, planar(a, b)))
        .collect()
}

/// Distance from point `p` to the line through `g` along unit `h`.
pub fn distance_to_line(p: &Vector3<f64>, g: &Vector3<f64>, h: &Vector3<f64>) -> f64 {
    let v = p - g;
    (v - h * h.dot(&v)).norm()
}
