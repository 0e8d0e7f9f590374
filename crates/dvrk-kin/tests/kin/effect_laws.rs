//! The effect laws computed along a motion: a drive's motion play and the presliding (Dahl) state.

use dvrk_kin::effects::motion_play;
use dvrk_kin::presliding::{dahl_state, dahl_step};


/// A triangle wave of amplitude 1 through play 0.1: the link trails by 0.1 on each ramp, holds
/// for 0.2 of motor travel after each reversal, and reaches the amplitude less the play.
#[test]
fn a_triangle_wave_is_delayed_by_the_gap_after_each_reversal() {
    let motor: Vec<f64> = (0..=400).map(|i| { let x = i as f64 / 100.0; if x <= 1.0 { x } else if x <= 3.0 { 2.0 - x } else { x - 4.0 } }).collect();
    let (mut link, mut side) = (vec![0.0; motor.len()], vec![0.0; motor.len()]);
    motion_play(0.1, &motor, &mut link, &mut side);
    // Rising from 0: centred until the motor is 0.1 up, then 0.1 behind.
    assert_eq!(side[5], 0.0);
    assert!((link[50] - 0.4).abs() < 1e-12 && side[50] == 1.0);
    // Peak at 1.0 (i = 100): the link at 0.9, held while the motor falls to 0.8 (i = 120).
    assert!((link[100] - 0.9).abs() < 1e-12);
    assert!((link[115] - 0.9).abs() < 1e-12 && side[115] == 1.0);
    assert!((link[150] - 0.6).abs() < 1e-12 && side[150] == -1.0);
    // The trough at -1.0: the link reaches -0.9.
    assert!((link[300] + 0.9).abs() < 1e-12);
    // No play: the link is the motor.
    motion_play(0.0, &motor, &mut link, &mut side);
    assert!(link.iter().zip(&motor).all(|(l, m)| l == m));
}


/// From rest, a ramp's state is the closed form `1 - exp(-q / sigma)`; after a reversal it
/// falls toward -1 from where it was, and never leaves [-1, 1] however large a step.
#[test]
fn the_state_is_the_closed_form_along_a_ramp_and_turns_over_at_a_reversal() {
    let sigma = 0.01;
    let q: Vec<f64> = (0..=100).map(|i| i as f64 * 1e-3).collect();
    let z = dahl_state(&q, sigma);
    for (x, zi) in q.iter().zip(&z) {
        assert!((zi - (1.0 - (-x / sigma).exp())).abs() < 1e-12, "{x}: {zi}");
    }
    let top = *z.last().unwrap();
    let back = dahl_step(top, -0.005, sigma);
    assert!((back - (-1.0 + (top + 1.0) * (-0.5f64).exp())).abs() < 1e-12);
    assert_eq!(dahl_step(0.3, 1e9, sigma), 1.0);
    assert_eq!(dahl_step(0.3, 0.0, sigma), 0.3);
}
