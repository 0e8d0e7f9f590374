//! The JSON contracts of `dvrk calib pivot --json` and `dvrk calib axes --json` (other tools
//! script against them: keys are only ever added), and reading the axes result back for
//! `dvrk calib apply`. Metres, radians, in the recording's frames.

use crate::mocap::apply::PsmUpdate;
use crate::mocap::axis_distances::AxesReport;
use crate::error::{CalibError, Result};
use crate::mocap::pivot::PivotFit;
use crate::mocap::psm_dh::{Estimate, PsmDh};
use nalgebra::Vector3;
use serde_json::{json, Value};
use std::path::Path;

fn v3(v: &Vector3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

fn opt3(v: &Option<Vector3<f64>>) -> Value {
    v.as_ref().map_or(Value::Null, v3)
}

/// `{"tip", "pivot", "rms_per_axis", "rms", "tip_std", "pivot_std", "samples", "method"}` and,
/// added: `rms_distance`, `outliers`, `motion_range_deg`, `warnings`.
pub fn pivot_json(fit: &PivotFit) -> Value {
    json!({
        "tip": v3(&fit.tip),
        "pivot": v3(&fit.pivot),
        "rms_per_axis": fit.rms_per_axis,
        "rms": fit.rms,
        "tip_std": fit.tip_std(),
        "pivot_std": fit.pivot_std(),
        "samples": fit.samples,
        "method": fit.method.name(),
        "rms_distance": fit.rms_distance,
        "outliers": fit.outliers,
        "motion_range_deg": fit.motion.ranges_deg(),
        "warnings": fit.warnings,
    })
}

fn est(e: &Estimate) -> Value {
    json!({"value": e.value, "std": e.std})
}

/// The axes result: each axis (tracker frame at the reference instant, and in its two clusters'
/// frames), the distance table, and the PSM DH parameters when the seven axes are present.
pub fn axes_json(report: &AxesReport, dh: Option<&PsmDh>) -> Value {
    let table6 = ["3-4", "3-6", "4-c1", "6-c1", "3-7", "6-8", "7-c2", "6-7"];
    let axes: Vec<Value> = report
        .axes
        .iter()
        .map(|a| {
            json!({
                "name": a.name,
                "reference": a.reference,
                "moving": a.moving,
                "point": opt3(&a.point_tracker),
                "direction": opt3(&a.direction_tracker),
                "in_plane": opt3(&a.in_plane),
                "std": a.fit.point_std(),
                "direction_std": a.fit.direction_std(),
                "point_in_reference": v3(&a.fit.point),
                "direction_in_reference": v3(&a.fit.direction),
                "point_in_moving": v3(&a.fit.point_moving),
                "direction_in_moving": v3(&a.fit.direction_moving),
                "rms": a.fit.rms,
                "samples": a.fit.samples,
                "outliers": a.fit.outliers,
                "range_deg": a.fit.motion.ranges[0].to_degrees(),
                "wobble_deg": a.fit.motion.ranges[1].to_degrees(),
            })
        })
        .collect();
    let distances: Vec<Value> = report
        .distances
        .iter()
        .map(|d| {
            let label = format!("{}-{}", d.a, d.b);
            let flipped = format!("{}-{}", d.b, d.a);
            json!({
                "axes": [d.a, d.b],
                "distance": d.distance,
                "std": d.std,
                "frame": d.frame,
                "table6": table6.contains(&label.as_str()) || table6.contains(&flipped.as_str()),
            })
        })
        .collect();
    let dh = dh.map_or(Value::Null, |d| {
        json!({
            "l34": est(&d.l34),
            "a6": est(&d.a6),
            "a7": est(&d.a7),
            "a8": est(&d.a8),
            "l67": est(&d.l67),
            "beta_difference": est(&d.beta_difference),
            "mismatch": d.mismatch.iter().map(|(k, v)| (k.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
            "beta1_at_reference": d.beta1_at_reference,
        })
    });
    json!({
        "recording": report.source,
        "method": report.method.name(),
        "reference_time": report.reference_time,
        "reference_q": report.reference_q,
        "plane_normal": opt3(&report.plane_normal),
        "axes": axes,
        "distances": distances,
        "dh": dh,
        "warnings": report.warnings,
    })
}

/// The PSM update in an axes result (`dvrk calib axes --json`); `path` names it in errors.
pub fn psm_update_from_json(text: &str, path: &Path) -> Result<PsmUpdate> {
    let v: Value = serde_json::from_str(text).map_err(|e| CalibError::file(path, format!("line {}: not JSON: {e}", e.line())))?;
    let dh = v.get("dh").filter(|d| !d.is_null()).ok_or_else(|| {
        CalibError::file(path, "field `dh` is missing or null: the axes result needs the seven PSM axes (3, 4, 6, 7, 8, c1, c2)")
    })?;
    let get = |k: &str| -> Result<f64> {
        let x = dh.get(k).and_then(|e| e.get("value")).ok_or_else(|| CalibError::file(path, format!("field `dh.{k}.value` is missing")))?;
        x.as_f64().filter(|x| x.is_finite()).ok_or_else(|| CalibError::file(path, format!("field `dh.{k}.value` = {x} is not a finite number")))
    };
    Ok(PsmUpdate {
        l34: get("l34")?,
        a6: get("a6")?,
        a7: get("a7")?,
        a8: get("a8")?,
        beta_difference: get("beta_difference")?,
        source: path.display().to_string(),
    })
}
