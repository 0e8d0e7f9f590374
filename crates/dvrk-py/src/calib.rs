//! Python bindings of `dvrk-calib`: pivot and axis fits on numpy arrays of poses, recordings
//! read into numpy arrays. Conversions only.

use crate::errors::{Error, Result};
use dvrk_calib::{fit_axis, pivot_calibration, AxisMethod, AxisOptions, McapOptions, PivotMethod, PivotOptions};
use dvrk_kin::Pose;
use nalgebra::{Matrix3, Rotation3, Translation3};
use numpy::ndarray::Array3;
use numpy::{AllowTypeChange, IntoPyArray, PyArrayLikeDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Poses from an (N, 4, 4) array; rotations must be orthonormal to 1e-6.
fn poses_from_array(a: &PyArrayLikeDyn<'_, f64, AllowTypeChange>, what: &str) -> Result<Vec<Pose>> {
    let v = a.as_array();
    let s = v.shape();
    if s.len() != 3 || s[1] != 4 || s[2] != 4 {
        return Err(Error::Input(format!("{what}: expected shape (N, 4, 4), got {s:?}")));
    }
    (0..s[0])
        .map(|i| {
            let m = |r: usize, c: usize| v[[i, r, c]];
            if (0..4).any(|r| (0..4).any(|c| !m(r, c).is_finite())) {
                return Err(Error::Input(format!("{what}[{i}]: not finite")));
            }
            let r = Matrix3::from_fn(|r, c| m(r, c));
            let err = (r.transpose() * r - Matrix3::identity()).abs().max();
            if err > 1e-6 || r.determinant() < 0.0 {
                return Err(Error::Input(format!("{what}[{i}]: rotation part is not a rotation (|R^T R - I| = {err:.1e})")));
            }
            Ok(Pose::from_parts(Translation3::new(m(0, 3), m(1, 3), m(2, 3)), Rotation3::from_matrix_unchecked(r)))
        })
        .collect()
}

fn to_py_json<'py>(py: Python<'py>, v: &serde_json::Value) -> Result<Bound<'py, PyAny>> {
    Ok(py.import("json")?.call_method1("loads", (v.to_string(),))?)
}

/// Pivot calibration (paper eq. 3-5) of marker-frame poses (N, 4, 4) in the tracker frame (m).
/// `method`: "one-step" (the paper's stacked system), "two-step" or "sphere". Returns the same
/// dict as `dvrk calib pivot --json`: tip, pivot, rms_per_axis, rms, tip_std, pivot_std,
/// samples, method (m), plus warnings.
#[pyfunction]
#[pyo3(signature = (poses, method="one-step"))]
pub fn pivot<'py>(py: Python<'py>, poses: PyArrayLikeDyn<'py, f64, AllowTypeChange>, method: &str) -> Result<Bound<'py, PyAny>> {
    let method = match method {
        "one-step" => PivotMethod::OneStep,
        "two-step" => PivotMethod::TwoStep,
        "sphere" => PivotMethod::Sphere,
        other => return Err(Error::Input(format!("method = `{other}`: expected one-step, two-step or sphere"))),
    };
    let p = poses_from_array(&poses, "poses")?;
    let fit = py.detach(|| pivot_calibration(&p, &PivotOptions { method, ..Default::default() }))?;
    to_py_json(py, &dvrk_calib::mocap::report_json::pivot_json(&fit))
}

/// Axis of rotation of a `moving` marker cluster about a `reference` cluster, from their poses
/// (N, 4, 4 each, same samples) in the tracker frame (m). `method`: "sara" or "gamage-lasenby".
/// Returns a dict: point (m, in the reference cluster's frame), direction (unit), point_std (m),
/// direction_std (rad), rms (m), samples, warnings.
#[pyfunction]
#[pyo3(signature = (reference, moving, method="sara"))]
pub fn axis<'py>(py: Python<'py>, reference: PyArrayLikeDyn<'py, f64, AllowTypeChange>, moving: PyArrayLikeDyn<'py, f64, AllowTypeChange>, method: &str) -> Result<Bound<'py, PyAny>> {
    let method = match method {
        "sara" => AxisMethod::Sara,
        "gamage-lasenby" => AxisMethod::GamageLasenby,
        other => return Err(Error::Input(format!("method = `{other}`: expected sara or gamage-lasenby"))),
    };
    let (a, b) = (poses_from_array(&reference, "reference")?, poses_from_array(&moving, "moving")?);
    if a.len() != b.len() {
        return Err(Error::Input(format!("reference has {} poses, moving {}: expected the same samples", a.len(), b.len())));
    }
    let fit = py.detach(|| fit_axis(&a, &b, &AxisOptions { method, ..Default::default() }, "axis"))?;
    let v = serde_json::json!({
        "point": [fit.point.x, fit.point.y, fit.point.z],
        "direction": [fit.direction.x, fit.direction.y, fit.direction.z],
        "point_std": fit.point_std(),
        "direction_std": fit.direction_std(),
        "rms": fit.rms,
        "samples": fit.samples,
        "method": fit.method.name(),
        "warnings": fit.warnings,
    });
    to_py_json(py, &v)
}

/// Read a recording (MCAP, Motive CSV, plain CSV) into numpy arrays: a dict with `bodies`
/// (name -> {"t": (N,) s, "poses": (N, 4, 4) m, "frame_id"}), `joints` (None or {"names",
/// "t": (M,), "q": (M, n) rad/m}) and `warnings`.
#[pyfunction]
#[pyo3(signature = (path, topics=None))]
pub fn read_recording<'py>(py: Python<'py>, path: PathBuf, topics: Option<Vec<String>>) -> Result<Bound<'py, PyDict>> {
    let options = McapOptions { topics: topics.unwrap_or_default(), joint_topic: None };
    let rec = py.detach(|| dvrk_calib::read_recording(&path, &options))?;
    let bodies = PyDict::new(py);
    for b in &rec.bodies {
        let mut arr = Array3::<f64>::zeros((b.poses.len(), 4, 4));
        for (i, p) in b.poses.iter().enumerate() {
            let h = p.to_homogeneous();
            for r in 0..4 {
                for c in 0..4 {
                    arr[[i, r, c]] = h[(r, c)];
                }
            }
        }
        let d = PyDict::new(py);
        d.set_item("t", b.t.clone().into_pyarray(py))?;
        d.set_item("poses", arr.into_pyarray(py))?;
        d.set_item("frame_id", &b.frame_id)?;
        bodies.set_item(&b.name, d)?;
    }
    let out = PyDict::new(py);
    out.set_item("bodies", bodies)?;
    match &rec.joints {
        Some(j) => {
            let n = j.names.len();
            let flat: Vec<f64> = j.q.iter().flat_map(|row| row.iter().copied()).collect();
            let q = numpy::ndarray::Array2::from_shape_vec((j.q.len(), n), flat).map_err(|e| Error::Input(e.to_string()))?;
            let d = PyDict::new(py);
            d.set_item("names", j.names.clone())?;
            d.set_item("t", j.t.clone().into_pyarray(py))?;
            d.set_item("q", q.into_pyarray(py))?;
            out.set_item("joints", d)?;
        }
        None => out.set_item("joints", py.None())?,
    }
    out.set_item("warnings", rec.warnings.clone())?;
    Ok(out)
}

/// Dynamic identification (`dvrk identify`) of a model from a joint recording with efforts: the
/// JSON summary as a dict (`relative_error`, `rigid_body_only`, `validation` with
/// `validate`, `ablation`, `effects`, `bodies`, `warnings`, `notes`, ...). `recording` and
/// `validate` are wpi-csv files, or MCAP / ROS 1 bags with `/<arm>/measured_js` (the jaw on
/// its own topic or not); `format` "auto" tells the format from the file. The prior is the
/// model's built-in inertials. `ablation=False` skips the ablation (most of the time: 12 of 14 s
/// on the WPI PSM; no `ablation` in the dict).
#[pyfunction]
#[pyo3(signature = (recording, model="psm", format="auto", validate=None, arm="PSM1", ablation=true))]
pub fn identify<'py>(py: Python<'py>, recording: PathBuf, model: &str, format: &str, validate: Option<PathBuf>, arm: &str, ablation: bool) -> Result<Bound<'py, PyAny>> {
    use dvrk_calib::identify::{summary, IdentifyOptions};
    use dvrk_calib::identify::read_log;
    let m = dvrk_calib::dvrk_kin::load(model, None)?;
    let summary = py.detach(|| -> Result<serde_json::Value> {
        let prior = dvrk_sim::scene::builtin_inertials(&m.name, &m)?.body_inertias(&m)?;
        let resolved = dvrk_sim::recording::resolve_format(&recording, format)?;
        let (rec, notes) = read_log(&recording, format, &m, arm)?;
        let held_out = validate.as_ref().map(|v| read_log(v, resolved, &m, arm).map(|r| r.0)).transpose()?;
        let options = IdentifyOptions::for_recording(&m, resolved);
        let ablation = if ablation { summary::Ablation::Rows } else { summary::Ablation::Skipped };
        let mut r = summary::run_with(&m, &prior, &rec, held_out.as_ref(), &options, &recording.display().to_string(), resolved, ablation, &mut |_| {})?;
        r.summary["notes"] = serde_json::json!(notes);
        Ok(r.summary)
    })?;
    to_py_json(py, &summary)
}

/// The discrepancy workflow (`dvrk discrepancy`) on a recording of `arm` (`format` "auto": told
/// from the file; "mcap" or "bag": `/<arm>/setpoint_js`, `/<arm>/measured_js` with efforts, the
/// jaw on `/<arm>/jaw/...` or not; "wpi-csv"; "csv": `time`, `q1..qN`,
/// `tau1..tauN`, optional `setpoint1..setpointN`), repeated: each named effect added to the model
/// and the analysis run again, up to `max_rounds`. `plot` (.png or .svg): the residual before and
/// after against time, velocity, load and position per moving joint. The report as a dict
/// (`verdict`, `channel`, `effects`, `candidates`, `rms_before`, `rms_after`, `rms_heldout_before`,
/// `rms_heldout_after`, `noise_floor`, `steps`, `kinematic`, ...). `marker_topic` and
/// `marker_link` (frame name or paper number) add the kinematic channel.
#[pyfunction]
#[pyo3(signature = (recording, model="psm", arm="PSM1", tracking=true, format="auto", max_rounds=4, plot=None, marker_topic=None, marker_link=None))]
#[allow(clippy::too_many_arguments)]
pub fn discrepancy<'py>(
    py: Python<'py>,
    recording: PathBuf,
    model: &str,
    arm: &str,
    tracking: bool,
    format: &str,
    max_rounds: usize,
    plot: Option<PathBuf>,
    marker_topic: Option<String>,
    marker_link: Option<String>,
) -> Result<Bound<'py, PyAny>> {
    use dvrk_calib::discrepancy::{from_file, plot as residual_plot, Options};
    use dvrk_calib::plot::check_path;
    let m = dvrk_calib::dvrk_kin::load(model, None)?;
    if let Some(p) = &plot {
        check_path(p)?;
        // The CLI's output discipline: never over an input, never into a missing directory.
        dvrk_calib::dvrk_kin::atomic::check_outputs(&[("recording", &recording)], &[("plot", p)])?;
    }
    let marker = match (marker_topic, marker_link) {
        (Some(topic), Some(link)) => Some(from_file::MarkerSource { topic, link }),
        (None, None) => None,
        _ => return Err(Error::Input("marker_topic and marker_link go together (the pose topic and the link its marker is on)".into())),
    };
    let report = py.detach(|| -> Result<serde_json::Value> {
        let out = from_file::run(&recording, format, &m, arm, marker.as_ref(), &Options { tracking, ..Default::default() }, max_rounds)?;
        if let Some(p) = &plot {
            let image = residual_plot::figure(&out.residuals, &recording.display().to_string())?.encode(p)?;
            dvrk_calib::dvrk_kin::atomic::write_atomic(p, &image)?;
        }
        serde_json::to_value(&out.report).map_err(|e| Error::Input(e.to_string()))
    })?;
    to_py_json(py, &report)
}

/// `dvrk synth hidden-effect`: simulate a recording of the `scene` arm (built-in `psm` or `ecm`)
/// with hidden physical effects (`effect`: a vocabulary name, two joined by `+`, `none`, `random`
/// or `random-pair`) and write it to `path` (plain CSV when it ends in .csv, MCAP otherwise);
/// returns the answer (`effects`: each with its parameters and effect-to-noise ratio;
/// `marker_topic` when `marker_link` adds a tracker on that link). `engine`: the truth's,
/// `rapier` (shares no dynamics code with the analysis) or `reduced` (about 16x faster).
#[pyfunction]
#[pyo3(signature = (path, effect="random", seed=1, scene="psm", duration=30.0, marker_link=None, engine="rapier"))]
#[allow(clippy::too_many_arguments)]
pub fn synth_hidden_effect<'py>(py: Python<'py>, path: PathBuf, effect: &str, seed: u64, scene: &str, duration: f64, marker_link: Option<String>, engine: &str) -> Result<Bound<'py, PyAny>> {
    use dvrk_calib::discrepancy::generate::MarkerOptions;
    use dvrk_calib::discrepancy::{hidden_effect, Hidden, HiddenOptions};
    use dvrk_sim::recording;
    let hidden: Hidden = effect.parse().map_err(|e: String| Error::Input(format!("effect: {e}")))?;
    let marker = marker_link.map(|link| MarkerOptions { link, ..Default::default() });
    let engine = dvrk_sim::Engine::from_name(engine).ok_or_else(|| Error::Input(format!("engine: {engine:?}: rapier or reduced")))?;
    dvrk_calib::dvrk_kin::atomic::check_outputs(&[], &[("path", &path)])?;
    let answer = py.detach(|| -> Result<serde_json::Value> {
        let h = hidden_effect(scene, &HiddenOptions { hidden, seed, duration, marker, engine, ..Default::default() })?;
        let bytes = match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("csv") => dvrk_sim::recording::write_joint_log_csv(&h.log).into_bytes(),
            _ => recording::write_joint_log_mcap(&h.log, &dvrk_sim::Scene::load(scene)?.arms[0].name)?,
        };
        dvrk_calib::dvrk_kin::atomic::write_atomic(&path, &bytes)?;
        serde_json::to_value(&h.answer).map_err(|e| Error::Input(e.to_string()))
    })?;
    to_py_json(py, &answer)
}
