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
        let k = (PI * cutoff / rate).tan();
        let q = std::f64::consts::FRAC_1_SQRT_2;
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
}
