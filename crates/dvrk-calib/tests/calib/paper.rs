//! Must-show 1: noise-free synthetic recordings give the model's Table 6 distances and its RCM
//! to 1e-6 m, through the file formats other tools read (MCAP and plain CSV).

use crate::util::{config, distance_to_line, model_table6, psm, scenario, true_axis};
use dvrk_sim::recording::{McapLayout, McapOptions};
use dvrk_calib::mocap::psm_dh::psm_dh;
use dvrk_calib::mocap::synth::SynthMotion;
use dvrk_calib::{calibrate_axes, pivot_calibration, AxesOptions, AxisMethod, PivotMethod, PivotOptions};
use nalgebra::Point3;
use std::path::Path;

#[test]
fn noise_free_axes_give_the_models_table_6_distances() {
    let model = psm();
    let s = scenario(&model, SynthMotion::Q2Sweep, 0.0, 20.0, 0.01);
    // Through an MCAP file, as a tracker would write it.
    let bytes = dvrk_sim::recording::write_mcap_poses(&s.record(7), McapLayout::PoseStamped, "/PSM1/measured_js").unwrap();
    let rec = dvrk_sim::recording::parse_mcap_poses(&bytes, Path::new("q2.mcap"), &McapOptions::default()).unwrap();
    let cfg = config(&s);
    let truth = model_table6(&model);
    for method in [AxisMethod::Sara, AxisMethod::GamageLasenby] {
        let report = calibrate_axes(&rec, &cfg, &AxesOptions { method: Some(method), from_markers: false }).unwrap();
        for (a, b, d) in &truth {
            let got = report.distance(a, b).unwrap();
            eprintln!("{method:?} {a}-{b}: fitted {:.9} m, model {d:.9} m (in {})", got.distance, got.frame);
            assert!((got.distance - d).abs() < 1e-6, "{method:?} {a}-{b}: {} vs {d}", got.distance);
        }
        // The axes in the tracker frame at joint zero lie on the model's, carried by the
        // tracker transform the fit never saw.
        assert_eq!(report.reference_q.as_ref().map(|q| (q[0], q[1])), Some((0.0, 0.0)));
        let mut q0 = model.home();
        q0[..2].fill(0.0);
        for ax in &report.axes {
            let (p, z) = true_axis(&model, &q0, &ax.name);
            let p = (s.options.tracker_from_base * Point3::from(p)).coords;
            let z = s.options.tracker_from_base.rotation * z;
            let d = distance_to_line(&p, &ax.point_tracker.unwrap(), &ax.direction_tracker.unwrap());
            assert!(d < 1e-6, "{method:?} axis {}: {d:e} m off", ax.name);
            assert!(ax.direction_tracker.unwrap().cross(&z).norm() < 1e-9);
        }
        // The DH quantities the model was built from.
        let dh = psm_dh(&report).unwrap();
        let beta = |p: &str| model.spec.parameters[p].value;
        assert!((dh.a6.value - 0.150).abs() < 1e-6 && (dh.a8.value - 0.516).abs() < 1e-6 && (dh.a7.value - 0.1842).abs() < 1e-6);
        assert!((dh.l34.value - 0.096).abs() < 1e-6);
        assert!((dh.beta_difference.value - (beta("beta2") - beta("beta1"))).abs() < 1e-8, "{:?}", dh.beta_difference);
        assert!(dh.beta1_at_reference.map(|b| (b - beta("beta1")).abs() < 1e-8).unwrap_or(false), "{:?}", dh.beta1_at_reference);
    }
}

#[test]
fn noise_free_pivot_gives_the_models_rcm() {
    let model = psm();
    let s = scenario(&model, SynthMotion::Q1Q2Sweep, 0.0, 20.0, 0.01);
    let rcm = s.rcm.unwrap();
    // Through a plain CSV file.
    let text = dvrk_sim::recording::write_plain_csv(&s.record(3));
    let rec = dvrk_sim::recording::parse_plain_csv(&text, Path::new("q1q2.csv")).unwrap();
    let poses = &rec.body("end").unwrap().poses;
    for method in [PivotMethod::OneStep, PivotMethod::TwoStep, PivotMethod::Sphere] {
        let f = pivot_calibration(poses, &PivotOptions { method, ..Default::default() }).unwrap();
        eprintln!("{}: pivot {:.3e} m from the model's RCM, RMS {:.1e} m", method.name(), (f.pivot - rcm).norm(), f.rms);
        assert!((f.pivot - rcm).norm() < 1e-6, "{method:?}");
        // b_tip carries the RCM with the cluster: the same point from the first pose.
        assert!((poses[0] * Point3::from(f.tip) - Point3::from(rcm)).norm() < 1e-6);
        assert!(f.rms < 1e-7 && f.warnings.is_empty());
    }
    // The same from the raw markers (poses re-fitted by our least squares).
    let from_markers = rec.poses("end", None, true).unwrap();
    let f = pivot_calibration(&from_markers.poses, &PivotOptions::default()).unwrap();
    assert!((f.pivot - rcm).norm() < 1e-6);
    // One-step and two-step are the same estimator (two-step eliminates b_post exactly).
    let one = pivot_calibration(poses, &PivotOptions::default()).unwrap();
    let s2 = scenario(&model, SynthMotion::Q1Q2Sweep, 1e-4, 10.0, 0.0);
    let noisy = s2.record(5);
    let p = &noisy.body("end").unwrap().poses;
    let (a, b) = (
        pivot_calibration(p, &PivotOptions { method: PivotMethod::OneStep, ..Default::default() }).unwrap(),
        pivot_calibration(p, &PivotOptions { method: PivotMethod::TwoStep, ..Default::default() }).unwrap(),
    );
    assert!((a.pivot - b.pivot).norm() < 1e-12 && (a.tip - b.tip).norm() < 1e-12, "{:e}", (a.pivot - b.pivot).norm());
    assert_eq!(one.samples, poses.len());
}
