//! Forward-kinematics speed: every frame of the PSM (17 frames: the paper's 15 plus the wrist-yaw
//! and tool-tip frames) and of the whole cart (SUJ + 3 PSM + ECM, 94 frames), one core.
//! Target: the PSM in under 250 ns. Model, data and inputs are built outside the timed loop.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use dvrk_kin::{compute_frame_placements, frame_jacobian, load, sample_configurations, Data};

fn fk(c: &mut Criterion) {
    for name in ["psm", "ecm", "cart"] {
        let model = load(name, None).expect("built-in model");
        let mut data = Data::new(&model);
        let configs = sample_configurations(&model.joints, 64);
        let mut i = 0;
        c.bench_function(&format!("fk_all_frames/{name}_{}_frames", model.frames.len()), |b| {
            b.iter(|| {
                i = (i + 1) % configs.len();
                compute_frame_placements(&model, &mut data, black_box(&configs[i]));
                black_box(&data.frames[model.tip]);
            })
        });
    }
    let model = load("psm", None).expect("psm");
    let mut data = Data::new(&model);
    let q = model.home();
    compute_frame_placements(&model, &mut data, &q);
    let mut jac = nalgebra::Matrix6xX::zeros(model.nq());
    c.bench_function("jacobian/psm_tip", |b| b.iter(|| frame_jacobian(&model, &data, black_box(model.tip), &mut jac).unwrap()));
}

criterion_group!(benches, fk);
criterion_main!(benches);
