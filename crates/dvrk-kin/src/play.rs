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
