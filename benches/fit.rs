//! Fitting speed on a 10-minute recording at 120 Hz (72,000 poses), one core. Target: well
//! under a second for each fit, and for reading the MCAP file and fitting together. The
//! recording is synthesised (0.1 mm marker noise, 1 % occlusion) outside the timed loops.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dvrk_sim::recording::{McapLayout, McapOptions};
use dvrk_sim::recording::common_samples;
use dvrk_calib::mocap::synth::{Scenario, SynthMotion, SynthOptions};
use dvrk_calib::{fit_axis, pivot_calibration, AxisMethod, AxisOptions, PivotMethod, PivotOptions};
use dvrk_kin::Pose;
use std::path::Path;

fn fits(c: &mut Criterion) {
    let model = dvrk_kin::load("psm", None).expect("psm");
    let options = SynthOptions { duration: 600.0, occlusion: 0.0, ..Default::default() };
    let pivot_rec = Scenario::new(&model, &options).expect("scenario").record(1);
    let end = pivot_rec.body("end").expect("end").poses.clone();
    assert_eq!(end.len(), 72_000);
    let mut g = c.benchmark_group("calib_72000_poses");
    g.sample_size(10);
    for method in [PivotMethod::OneStep, PivotMethod::TwoStep, PivotMethod::Sphere] {
        let o = PivotOptions { method, ..Default::default() };
        g.bench_function(format!("pivot_{}", method.name()), |b| b.iter(|| pivot_calibration(black_box(&end), &o).expect("fit")));
    }
    let axes_rec = Scenario::new(&model, &SynthOptions { motion: SynthMotion::Q2Sweep, ..options.clone() }).expect("scenario").record(2);
    let (back, bottom) = (axes_rec.body("back").expect("back"), axes_rec.body("bottom").expect("bottom"));
    let (ra, rb): (Vec<Pose>, Vec<Pose>) = common_samples(&[back, bottom]).iter().map(|i| (back.poses[i[0]], bottom.poses[i[1]])).unzip();
    for method in [AxisMethod::Sara, AxisMethod::GamageLasenby] {
        let o = AxisOptions { method, ..Default::default() };
        g.bench_function(format!("axis_{}", method.name()), |b| b.iter(|| fit_axis(black_box(&ra), black_box(&rb), &o, "axis 6").expect("fit")));
    }
    // Reading the file and fitting: an MCAP holding the one pivoting body.
    let mut only_end = pivot_rec.clone();
    only_end.bodies.retain(|b| b.name == "end");
    only_end.joints = None;
    let bytes = dvrk_sim::recording::write_mcap_poses(&only_end, McapLayout::PoseStamped, "/js").expect("mcap");
    g.bench_function("read_mcap_and_pivot", |b| {
        b.iter(|| {
            let rec = dvrk_sim::recording::parse_mcap_poses(black_box(&bytes), Path::new("bench.mcap"), &McapOptions::default()).expect("read");
            pivot_calibration(&rec.bodies[0].poses, &PivotOptions::default()).expect("fit")
        })
    });
    g.finish();
}

criterion_group!(benches, fits);
criterion_main!(benches);
