//! Zero-phase low-pass filtering and differentiation of sampled signals (for accelerations
//! from measured velocities, and for filtering efforts the same way).

use std::f64::consts::PI;

/// A second-order Butterworth low-pass section (bilinear transform, prewarped).
#[derive(Debug, Clone, Copy)]
pub struct Butterworth2 {
    b: [f64; 3],
    a: [f64; 2],
}

impl Butterworth2 {
    /// Cut-off `cutoff` (Hz) at sample rate `rate` (Hz); `cutoff < rate / 2`.
    pub fn new(cutoff: f64, rate: f64) -> Butterworth2 {
        Butterworth2::section(cutoff, rate, std::f64::consts::FRAC_1_SQRT_2)
    }

    /// One second-order section of quality factor `q` (1/sqrt(2) alone is a Butterworth filter).
    fn section(cutoff: f64, rate: f64, q: f64) -> Butterworth2 {
        let k = (PI * cutoff / rate).tan();
        let norm = 1.0 / (1.0 + k / q + k * k);
        let b0 = k * k * norm;
        Butterworth2 { b: [b0, 2.0 * b0, b0], a: [2.0 * (k * k - 1.0) * norm, (1.0 - k / q + k * k) * norm] }
    }

    /// Filter `x` forward in place, starting from the steady state of its first value.
    fn run(&self, x: &mut [f64]) {
        let Some(&x0) = x.first() else { return };
        let (mut x1, mut x2, mut y1, mut y2) = (x0, x0, x0, x0);
        for v in x.iter_mut() {
            let y = self.b[0] * *v + self.b[1] * x1 + self.b[2] * x2 - self.a[0] * y1 - self.a[1] * y2;
            (x2, x1, y2, y1) = (x1, *v, y1, y);
            *v = y;
        }
    }

    /// Zero-phase filtering (forward, then backward: the squared magnitude response, no lag),
    /// with the ends padded by odd reflection over `pad` samples to tame edge transients.
    pub fn filtfilt(&self, x: &[f64], pad: usize) -> Vec<f64> {
        let n = x.len();
        if n < 2 {
            return x.to_vec();
        }
        let pad = pad.min(n - 1);
        let mut y = Vec::with_capacity(n + 2 * pad);
        y.extend((1..=pad).rev().map(|i| 2.0 * x[0] - x[i]));
        y.extend_from_slice(x);
        y.extend((1..=pad).map(|i| 2.0 * x[n - 1] - x[n - 1 - i]));
        self.run(&mut y);
        y.reverse();
        self.run(&mut y);
        y.reverse();
        y[pad..pad + n].to_vec()
    }
}

/// A Butterworth low-pass of even order (cut-off in Hz at `rate` Hz), as cascaded second-order
/// sections: the order-`2m` filter's poles in pairs, section `k` of quality factor
/// `1 / (2 cos((2k - 1) pi / 4m))`.
#[derive(Debug, Clone)]
pub struct Butterworth {
    sections: Vec<Butterworth2>,
}

impl Butterworth {
    /// `order` must be even and at least 2; `cutoff < rate / 2`.
    pub fn new(order: usize, cutoff: f64, rate: f64) -> Butterworth {
        let m = (order / 2).max(1);
        let sections = (1..=m).map(|k| Butterworth2::section(cutoff, rate, 1.0 / (2.0 * ((2 * k - 1) as f64 * PI / (4 * m) as f64).cos()))).collect();
        Butterworth { sections }
    }

    /// Zero-phase filtering ([`Butterworth2::filtfilt`] section by section: the cascade is
    /// linear and time-invariant, so the order does not matter).
    pub fn filtfilt(&self, x: &[f64], pad: usize) -> Vec<f64> {
        self.sections.iter().fold(x.to_vec(), |y, s| s.filtfilt(&y, pad))
    }
}

/// Derivative of `x` sampled every `dt` seconds: central differences, one-sided at the ends.
pub fn derivative(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return vec![0.0; n];
    }
    (0..n)
        .map(|i| match i {
            0 => (x[1] - x[0]) / dt,
            i if i == n - 1 => (x[n - 1] - x[n - 2]) / dt,
            i => (x[i + 1] - x[i - 1]) / (2.0 * dt),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_slow_sines_without_lag_and_stops_fast_ones() {
        let rate = 200.0;
        let f = Butterworth2::new(10.0, rate);
        let t: Vec<f64> = (0..2000).map(|i| i as f64 / rate).collect();
        let slow: Vec<f64> = t.iter().map(|t| (2.0 * PI * 1.0 * t).sin()).collect();
        let fast: Vec<f64> = t.iter().map(|t| (2.0 * PI * 60.0 * t).sin()).collect();
        let ys = f.filtfilt(&slow, 100);
        let yf = f.filtfilt(&fast, 100);
        // 1 Hz at a 10 Hz cut-off: |H|^2 = 1 / (1 + (1/10)^4) = 0.9999; no phase shift.
        let err = ys.iter().zip(&slow).skip(200).take(1600).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err < 2e-4, "{err}");
        // 60 Hz: |H|^2 = 1 / (1 + 6^4) = 7.7e-4 (the prewarped filter attenuates a bit more).
        let amp = yf.iter().skip(200).take(1600).map(|v| v.abs()).fold(0.0, f64::max);
        assert!(amp < 8e-4, "{amp}");
        // The derivative of the filtered slow sine is 2 pi cos.
        let d = derivative(&ys, 1.0 / rate);
        let err = d.iter().zip(&t).skip(200).take(1600).map(|(d, t)| (d - 2.0 * PI * (2.0 * PI * t).cos()).abs()).fold(0.0, f64::max);
        assert!(err < 2e-3 * 2.0 * PI, "{err}");
    }

    /// The sixth-order filter's zero-phase gain is |H|^2 = 1 / (1 + (f/fc)^12) (analog; the
    /// prewarped digital one is within a percent here): 1/2 at the cut-off, 1/(1 + 2^12) at twice.
    #[test]
    fn sixth_order_gain_is_half_at_the_cutoff_and_falls_as_the_twelfth_power() {
        let rate = 200.0;
        let f = Butterworth::new(6, 17.0, rate);
        let gain = |hz: f64| {
            let x: Vec<f64> = (0..4000).map(|i| (2.0 * PI * hz * i as f64 / rate).sin()).collect();
            let y = f.filtfilt(&x, 200);
            let (num, den) = y.iter().zip(&x).skip(500).take(3000).fold((0.0, 0.0), |(n, d), (y, x)| (n + y * x, d + x * x));
            num / den
        };
        assert!((gain(17.0) - 0.5).abs() < 0.01, "{}", gain(17.0));
        assert!((gain(3.0) - 1.0).abs() < 1e-6, "{}", gain(3.0));
        let g2 = gain(34.0);
        assert!(g2 > 0.0 && g2 < 1.3 / 4097.0, "{g2}");
    }
}
