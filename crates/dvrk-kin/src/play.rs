//! Play by motion direction: a cable or gear drive with little load keeps its link where it was
//! when the motor reverses, until the motor has crossed the gap (the `motion_play` effect). The
//! link follows the motor through the play (hysteresis) operator of half-width `b`; unlike the
//! load-side play (`backlash`, the link on the side its load pushes), it depends on the motion's
//! history, not on the configuration, so it acts on a trajectory, not on a pose.

/// The link's positions behind a drive with play of half-width `b` (rad, or m on a prismatic
/// joint) on the motor's positions `motor` (sampled in time order), into `link`; `side` gets the
/// side of the gap the motor last pushed from: +1 rising (the link at `motor - b`), -1 falling
/// (at `motor + b`), 0 before the first contact (the link starts centred on the motor). The
/// derivative of the link's position by `b` is `-side` (the switch times' shift is second order).
pub fn motion_play(b: f64, motor: &[f64], link: &mut [f64], side: &mut [f64]) {
    let Some(&first) = motor.first() else { return };
    let (mut at, mut s) = (first, 0.0);
    for ((m, l), sd) in motor.iter().zip(link.iter_mut()).zip(side.iter_mut()) {
        if *m > at + b {
            at = m - b;
            s = 1.0;
        } else if *m < at - b {
            at = m + b;
            s = -1.0;
        }
        *l = at;
        *sd = s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
