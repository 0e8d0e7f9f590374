//! Identification of a synthetic PSM recording with known parameters (must-show 2): efforts
//! computed with the regressor from a physically consistent perturbation of the CAD inertials
//! plus known friction, offsets, armature and springs, with seeded Gaussian effort noise; over
//! 100 trials each parameter group's estimates fall inside their reported 95% intervals in at
//! least 90% of trials (and not in all of them: the intervals are not inflated either).
//! Also the excitation warnings (must-show 4) on trajectories that move too little.

use crate::util::psm;
use dvrk_calib::filter::Butterworth2;
use dvrk_calib::identify::problem::{regression, EffectTerm, Layout, Param};
use dvrk_sim::recording::parse_wpi_csv;
use dvrk_calib::identify::{identify_regression, IdentifyOptions, JointLog};
use dvrk_kin::dynamics::PARAMETERS_PER_BODY;
use nalgebra::DVector;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;
use std::path::Path;

/// A Fourier excitation of the PSM's 7 recorded channels (wpi-csv layout: tool channels in
/// actuator space), `seconds` at 200 Hz, `amplitude` scaling each channel's motion (0: still).
pub fn fourier_recording(seconds: f64, amplitude: [f64; 7]) -> JointLog {
    let model = psm();
    // Centre (rad, m) and per-channel base frequency (Hz) of five harmonics.
    let centre = [0.0, 0.0, 0.15, 0.0, 0.0, 0.0, 0.3];
    let scale = [0.5, 0.5, 0.06, 1.0, 0.4, 0.4, 0.3];
    let f0 = [0.10, 0.13, 0.11, 0.17, 0.19, 0.23, 0.29];
    let n = (seconds * 200.0) as usize;
    let mut text = String::new();
    for i in 0..n {
        let t = i as f64 / 200.0;
        let (mut q, mut qd) = ([0.0; 7], [0.0; 7]);
        for c in 0..7 {
            q[c] = centre[c];
            for k in 1..=5 {
                let (w, phase, a) = (2.0 * PI * f0[c] * k as f64, 0.7 * (k * (c + 1)) as f64, amplitude[c] * scale[c] / k as f64);
                q[c] += a * (w * t + phase).sin() / 2.0;
                qd[c] += a * w * (w * t + phase).cos() / 2.0;
            }
        }
        let row: Vec<String> = q.iter().chain(&qd).map(|v| format!("{v:.12}")).chain((0..7).map(|_| "0".to_string())).collect();
        text += &row.join(",");
        text.push('\n');
    }
    parse_wpi_csv(&text, Path::new("fourier.csv"), &model).unwrap()
}

#[test]
fn synthetic_recordings_are_identified_within_their_95_percent_intervals() {
    let model = psm();
    let cad = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let rec = fourier_recording(30.0, [1.0; 7]);
    let options = IdentifyOptions::full(vec![3, 4, 5, 6]);
    let layout = Layout::new(&model, 7, &options.terms);
    let mut reg = regression(&model, &rec, &layout, &options.processing).unwrap();
    // The truth: every body's CAD parameters scaled by a factor in [0.8, 1.2] (a positive
    // multiple of a pseudo-inertia stays positive semidefinite), effects of the real arm's size.
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut truth = DVector::zeros(layout.len());
    for (b, ine) in cad.iter().enumerate() {
        let s = rng.random_range(0.8..1.2);
        for (k, v) in ine.parameters().iter().enumerate() {
            truth[b * PARAMETERS_PER_BODY + k] = s * v;
        }
    }
    let size = [0.5, 0.5, 0.5, 0.005, 0.02, 0.02, 0.02];
    for (i, p) in layout.params.iter().enumerate() {
        if let Param::Effect { term, channel } = *p {
            truth[i] = size[channel]
                * match term {
                    EffectTerm::Coulomb => 0.2,
                    EffectTerm::Offset => -0.1,
                    EffectTerm::Viscous => 0.3,
                    EffectTerm::Armature => 0.02,
                    _ => 0.1,
                };
        }
    }
    let clean: Vec<DVector<f64>> = reg.predict(&truth).unwrap().into_iter().map(DVector::from_vec).collect();
    // Effort noise per channel: about 3% of each channel's effort (N·m, N).
    let sd: Vec<f64> = clean.iter().map(|c| 0.03 * c.norm() / (c.len() as f64).sqrt()).collect();
    let (n, trim) = (rec.len(), options.processing.trim);
    let filter = Butterworth2::new(options.processing.cutoff, 200.0);
    let groups = ["inertial (identifiable)", "friction", "offsets", "armature", "springs"];
    let group_of = |p: &Param| match p {
        Param::Body { .. } => 0,
        Param::Effect { term: EffectTerm::Coulomb | EffectTerm::Viscous, .. } => 1,
        Param::Effect { term: EffectTerm::Offset, .. } => 2,
        Param::Effect { term: EffectTerm::Armature, .. } => 3,
        _ => 4,
    };
    let (mut inside, mut total) = ([0usize; 5], [0usize; 5]);
    let start = std::time::Instant::now();
    for trial in 0..100u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + trial);
        for c in 0..7 {
            let noise: Vec<f64> = (0..n).map(|_| Normal::new(0.0, sd[c]).unwrap().sample(&mut rng)).collect();
            let filtered = filter.filtfilt(&noise, (3.0 * 200.0 / options.processing.cutoff) as usize);
            reg.tau[c] = (0..n - 2 * trim).map(|r| clean[c][r] + noise[trim + r]).collect();
            reg.tau_filtered[c] = (0..n - 2 * trim).map(|r| clean[c][r] + filtered[trim + r]).collect();
        }
        let id = identify_regression(&model, &cad, &reg, layout.clone(), &rec.names, &options).unwrap();
        for (i, (e, p)) in id.estimates.iter().zip(&layout.params).enumerate() {
            let g = group_of(p);
            // Inertial parameters the recording does not determine are the prior's, not the data's.
            if g == 0 && !e.identifiable {
                continue;
            }
            total[g] += 1;
            if (e.value - truth[i]).abs() <= 1.96 * e.std {
                inside[g] += 1;
            }
        }
    }
    let coverage: Vec<f64> = inside.iter().zip(&total).map(|(i, t)| *i as f64 / (*t).max(1) as f64).collect();
    eprintln!("95% interval coverage over 100 trials ({:.1} s):", start.elapsed().as_secs_f64());
    for (g, name) in groups.iter().enumerate() {
        eprintln!("  {name:<26} {:.3} of {}", coverage[g], total[g]);
    }
    for (g, name) in groups.iter().enumerate() {
        assert!(total[g] >= 100, "{name}: {} estimates", total[g]);
        assert!((0.90..=0.99).contains(&coverage[g]), "{name}: coverage {:.3}", coverage[g]);
    }
}

/// A recording with the efforts of noise alone around the motion `amplitude` describes.
fn noisy(amplitude: [f64; 7]) -> JointLog {
    let mut rec = fourier_recording(10.0, amplitude);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for row in rec.effort.iter_mut() {
        for v in row.iter_mut() {
            *v = Normal::new(0.0, 0.01).unwrap().sample(&mut rng);
        }
    }
    rec
}

#[test]
fn a_still_arm_is_an_error_and_one_moving_joint_names_what_is_unidentifiable() {
    let model = psm();
    let cad = dvrk_sim::scene::builtin_inertials("psm", &model).unwrap().body_inertias(&model).unwrap();
    let options = IdentifyOptions::full(vec![3, 4, 5, 6]);
    let e = dvrk_calib::identify::identify(&model, &cad, &noisy([0.0; 7]), &options).unwrap_err().to_string();
    assert!(e.starts_with("fourier.csv: no excitation: no channel's velocity range exceeds 0.001"), "{e}");
    // Only the yaw moves: every other channel is named, with its effect parameters.
    let (id, _) = dvrk_calib::identify::identify(&model, &cad, &noisy([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), &options).unwrap();
    let still: Vec<&str> = id.warnings.iter().filter(|w| w.name == "channel_not_excited").map(|w| w.message.split('`').nth(1).unwrap()).collect();
    assert_eq!(still, ["outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch actuator", "outer_wrist_yaw actuator", "jaw actuator"]);
    let pitch = id.warnings.iter().find(|w| w.message.contains("`outer_pitch`")).unwrap();
    assert_eq!(pitch.parameters, ["outer_pitch.fc", "outer_pitch.fo", "outer_pitch.fv", "outer_pitch.im"]);
    let un = id.warnings.iter().find(|w| w.name == "parameters_unidentifiable").unwrap();
    for p in ["outer_pitch.fc", "outer_pitch.fv", "jaw actuator.k", "outer_insertion.im"] {
        assert!(un.parameters.iter().any(|q| q == p), "{p} not in {:?}", un.parameters);
    }
    // The yaw's own friction is identified.
    assert!(!un.parameters.iter().any(|q| q == "outer_yaw.fc" || q == "outer_yaw.fv"), "{:?}", un.parameters);
}
