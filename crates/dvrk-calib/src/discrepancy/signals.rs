//! From a joint log to the torque channel's inputs: positions low-passed without lag and
//! differentiated twice, efforts low-passed the same way (so measurement and prediction share one
//! bandwidth), both decimated; each joint's effort noise estimated from the raw samples and
//! carried through the same filter to the noise floor of the residual, with what the encoder
//! noise, differentiated twice, makes of the predicted effort.

use dvrk_sim::recording::JointLog;
use crate::error::{CalibError, Result};
use crate::filter::{derivative, Butterworth2};
use dvrk_kin::{DynamicsData, DynamicsModel, Model};
use nalgebra::{DMatrix, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// `[sample][joint]` effort table (N·m, N per unit of a parameter).
pub type Table = Vec<Vec<f64>>;

/// The Coulomb smoothing velocity (rad/s, m/s) of a model's friction that names none.
pub const COULOMB_SMOOTHING_DEFAULT: f64 = 2.0 * dvrk_sim::effects::COULOMB_VELOCITY;

/// How the log is processed.
#[derive(Debug, Clone, PartialEq)]
pub struct Processing {
    /// Low-pass cut-off (Hz): above the excitation (<= 1.3 Hz) and the arm's tracking dynamics,
    /// below where differentiated encoder noise matters.
    pub cutoff: f64,
    /// Rate of the analysed samples (Hz).
    pub rate: f64,
    /// Time dropped at the start (the fade-in, filter edge) and end (filter edge), s.
    pub skip_start: f64,
    pub skip_end: f64,
    /// Fraction of the analysed time, at its end, held out of every fit.
    pub heldout: f64,
}

impl Default for Processing {
    fn default() -> Self {
        Processing { cutoff: 10.0, rate: 100.0, skip_start: 2.0, skip_end: 0.5, heldout: 0.3 }
    }
}

/// The analysed samples, `[sample][joint]`.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// s
    pub t: Vec<f64>,
    /// rad, m; /s; /s^2 (encoder, i.e. motor side)
    pub q: Vec<Vec<f64>>,
    pub qd: Vec<Vec<f64>>,
    pub qdd: Vec<Vec<f64>>,
    /// Filtered measured effort (N·m, N).
    pub effort: Vec<Vec<f64>>,
    /// The raw measured effort at the same samples (N·m, N), for RMS against the noise.
    pub raw_effort: Vec<Vec<f64>>,
    /// Raw effort noise per joint (N·m, N): second differences of the raw samples.
    pub noise: Vec<f64>,
    /// Noise of the filtered, decimated effort per joint (N·m, N): the residual's noise floor
    /// (with the encoder noise's share once [`Prepared::include_encoder_noise`] has run).
    pub floor: Vec<f64>,
    /// Encoder noise per joint (rad, m): fourth differences of the raw positions.
    pub position_noise: Vec<f64>,
    /// RMS of unit white noise at the recording's rate after the analysis' filter and one or two
    /// derivatives (1/s, 1/s^2): how much of the encoder noise reaches `qd` and `qdd`.
    pub derivative_gains: [f64; 2],
    /// Joints that move (the setpoint spans more than 1 mrad or 1 mm): the analysed ones.
    pub active: Vec<usize>,
    /// First held-out sample.
    pub split: usize,
    /// `n_eff / n` of the filtered, decimated noise: how much one analysed sample counts.
    pub noise_fraction: f64,
    /// Sample period (s).
    pub dt: f64,
    /// Velocity at the recording's own rate, low-passed wide (rad/s, m/s; `[joint][raw sample]`):
    /// what a nonlinear signature (friction's sign) is evaluated on before [`Prepared::band`]
    /// takes it to the analysis band, as the measured effort was.
    pub fast_qd: Vec<Vec<f64>>,
    /// The encoder's raw position less its band-filtered one, at the recording's rate (rad, m;
    /// `[joint][raw sample]`): what the band leaves out of the motor's motion (an impact's kink).
    pub motor_detail: Vec<Vec<f64>>,
    /// The raw samples kept (indices into the recording).
    pub keep: Vec<usize>,
    band: Butterworth2,
    pad: usize,
}

impl Prepared {
    /// The recording's own sample period (s): `dt` over the decimation stride.
    pub fn raw_dt(&self) -> f64 {
        self.dt / self.keep.get(1).map_or(1, |s| s - self.keep[0]) as f64
    }

    /// A signal at the recording's rate (`raw[sample]`) through the analysis' filter and
    /// decimation: the value at every analysed sample.
    pub fn band(&self, raw: &[f64]) -> Vec<f64> {
        let f = self.band.filtfilt(raw, self.pad);
        self.keep.iter().map(|&s| f[s]).collect()
    }
}

/// Column `k` of a `[sample][joint]` table.
pub(crate) fn column(rows: &[Vec<f64>], k: usize) -> Vec<f64> {
    rows.iter().map(|r| r[k]).collect()
}

/// Filter, differentiate and decimate `log` (which must be evenly sampled).
pub fn prepare(log: &JointLog, p: &Processing) -> Result<Prepared> {
    let n = log.len();
    let dt = log.period();
    if !(dt > 0.0) {
        return Err(CalibError::data("recording", "fewer than two samples"));
    }
    let rate = 1.0 / dt;
    if let Some(i) = log.t.windows(2).position(|w| ((w[1] - w[0]) - dt).abs() > 0.5 * dt) {
        return Err(CalibError::data("recording", format!("uneven sampling: samples {i} and {} are {} s apart, the mean period is {dt} s", i + 1, log.t[i + 1] - log.t[i])));
    }
    if p.cutoff >= 0.45 * rate || p.rate > rate + 1e-9 {
        return Err(CalibError::data("recording", format!("sampled at {rate:.1} Hz: too slow for a {} Hz analysis ({} Hz low-pass)", p.rate, p.cutoff)));
    }
    let span = log.t[n - 1] - log.t[0];
    if span < p.skip_start + p.skip_end + 5.0 {
        return Err(CalibError::data("recording", format!("{span:.1} s long: the analysis needs at least {} s", p.skip_start + p.skip_end + 5.0)));
    }
    let nq = log.names.len();
    let f = Butterworth2::new(p.cutoff, rate);
    let pad = (rate / p.cutoff * 3.0) as usize;
    let stride = ((rate / p.rate).round() as usize).max(1);
    let first = log.t.iter().position(|t| *t - log.t[0] >= p.skip_start).unwrap_or(0);
    let last = log.t.iter().rposition(|t| log.t[n - 1] - *t >= p.skip_end).unwrap_or(n - 1);
    let keep: Vec<usize> = (first..=last).step_by(stride).collect();
    let mut q = vec![vec![0.0; nq]; keep.len()];
    let (mut qd, mut qdd, mut effort, mut raw_effort) = (q.clone(), q.clone(), q.clone(), q.clone());
    let mut noise = vec![0.0; nq];
    let mut position_noise = vec![0.0; nq];
    // Wide enough to keep a friction reversal's sharpness, narrow enough that encoder noise
    // differentiated does not flip the sign at rest.
    let wide = Butterworth2::new((4.0 * p.cutoff).min(0.4 * rate), rate);
    let efforts = log.has_efforts();
    let mut fast_qd = Vec::with_capacity(nq);
    let mut motor_detail = Vec::with_capacity(nq);
    for k in 0..nq {
        let raw_q = column(&log.position, k);
        fast_qd.push(derivative(&wide.filtfilt(&raw_q, pad), dt));
        let qf = f.filtfilt(&raw_q, pad);
        motor_detail.push(raw_q.iter().zip(&qf).map(|(r, f)| r - f).collect());
        let v = derivative(&qf, dt);
        let a = derivative(&v, dt);
        // A recording without efforts (the kinematic channel alone) has zeros here.
        let raw = if efforts { column(&log.effort, k) } else { vec![0.0; n] };
        let ef = f.filtfilt(&raw, pad);
        for (i, &s) in keep.iter().enumerate() {
            q[i][k] = qf[s];
            qd[i][k] = v[s];
            qdd[i][k] = a[s];
            effort[i][k] = ef[s];
            raw_effort[i][k] = raw[s];
        }
        // White noise dominates the second difference at the raw rate (the efforts' own motion
        // changes by ~1e-5 of their size between 1 kHz samples): var(d2) = 6 sigma^2.
        let d2: f64 = raw[first..=last].windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).powi(2)).sum();
        noise[k] = (d2 / (6.0 * (last - first - 1) as f64)).sqrt();
        position_noise[k] = fourth_difference_noise(&raw_q[first..=last]);
    }
    // The filter's noise gain, measured on seeded white noise of the same length.
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let unit = Normal::new(0.0, 1.0).expect("unit normal");
    let white: Vec<f64> = (0..n).map(|_| unit.sample(&mut rng)).collect();
    let wf = f.filtfilt(&white, pad);
    let kept_rms = |x: &[f64]| (keep.iter().map(|&s| x[s] * x[s]).sum::<f64>() / keep.len() as f64).sqrt();
    let gain = kept_rms(&wf);
    let floor: Vec<f64> = noise.iter().map(|s| s * gain).collect();
    let wd = derivative(&wf, dt);
    let derivative_gains = [kept_rms(&wd), kept_rms(&derivative(&wd, dt))];
    let noise_fraction = super::stats::effective_fraction(&[keep.iter().map(|&s| wf[s]).collect()]);
    let active: Vec<usize> = (0..nq)
        .filter(|&k| {
            let (lo, hi) = log.setpoint.iter().fold((f64::MAX, f64::MIN), |(a, b), s| (a.min(s[k]), b.max(s[k])));
            hi - lo > 1e-3 && (noise[k] > 0.0 || !efforts)
        })
        .collect();
    if active.is_empty() {
        return Err(CalibError::data("recording", "no joint moves (every setpoint spans less than 1 mrad / 1 mm, or its effort has no noise to weigh it by)"));
    }
    let split = ((1.0 - p.heldout) * keep.len() as f64).round() as usize;
    let t = keep.iter().map(|&s| log.t[s]).collect();
    Ok(Prepared {
        t,
        q,
        qd,
        qdd,
        effort,
        raw_effort,
        noise,
        floor,
        position_noise,
        derivative_gains,
        active,
        split,
        noise_fraction,
        dt: stride as f64 * dt,
        fast_qd,
        motor_detail,
        keep,
        band: f,
        pad,
    })
}

/// Encoder noise (rad, m) of raw positions `q`: the motion's fourth difference between 1 kHz
/// samples is far below the noise's (var = 70 sigma^2); the median keeps a play's rare kinks and
/// an encoder's quantisation steps from inflating it.
fn fourth_difference_noise(q: &[f64]) -> f64 {
    let mut d4: Vec<f64> = q.windows(5).map(|w| (w[4] - 4.0 * w[3] + 6.0 * w[2] - 4.0 * w[1] + w[0]).abs()).collect();
    if d4.is_empty() {
        return 0.0;
    }
    let mid = d4.len() / 2;
    let (_, m, _) = d4.select_nth_unstable_by(mid, f64::total_cmp);
    // Median of |N(0, 70 sigma^2)| = 0.6745 sqrt(70) sigma.
    *m / (0.6745 * 70f64.sqrt())
}

/// Samples [`Prepared::include_encoder_noise`] linearises the prediction at.
const NOISE_SAMPLES: usize = 200;

impl Prepared {
    /// Add to each joint's floor what the encoder noise does to the predicted effort: the noise
    /// differentiated twice, through the arm's inertia (and once, through its damping), is a
    /// residual a perfect model leaves too. It matters where a heavy joint's effort sensor is
    /// good (the insertion: 2 µm of encoder noise is about a third of its floor).
    pub fn include_encoder_noise(&mut self, predictor: &mut Predictor) -> Result<()> {
        let nq = self.floor.len();
        let stride = (self.t.len() / NOISE_SAMPLES).max(1);
        let rows: Vec<usize> = (0..self.t.len()).step_by(stride).collect();
        let pick = |x: &[Vec<f64>]| -> Vec<Vec<f64>> { rows.iter().map(|&i| x[i].clone()).collect() };
        let (q, qd, qdd) = (pick(&self.q), pick(&self.qd), pick(&self.qdd));
        let base = predictor.series_at(&q, &qd, &qdd)?;
        let [gd, gdd] = self.derivative_gains;
        // Per joint k: sum over the noisy joints j of sigma_j^2 times (d tau_k / d qdd_j * gdd)^2
        // and (damping_kj * gd)^2 (the velocity path through the drive's damping only: a Coulomb
        // law's slope at rest is no noise gain).
        let mut added = vec![0.0; nq];
        for j in (0..nq).filter(|&j| self.position_noise[j] > 0.0) {
            let h = 1e-3;
            let bumped: Vec<Vec<f64>> = qdd.iter().map(|r| r.iter().enumerate().map(|(i, v)| if i == j { v + h } else { *v }).collect()).collect();
            let by_acc = predictor.series_at(&q, &qd, &bumped)?;
            for k in 0..nq {
                let inertia_sq = by_acc.iter().zip(&base).map(|(a, b)| ((a[k] - b[k]) / h).powi(2)).sum::<f64>() / rows.len() as f64;
                added[k] += self.position_noise[j].powi(2) * (inertia_sq * gdd * gdd + (predictor.damping[(k, j)] * gd).powi(2));
            }
        }
        for (f, a) in self.floor.iter_mut().zip(added) {
            *f = (*f * *f + a).sqrt();
        }
        Ok(())
    }
}

/// The nominal effort of an arm (N·m, N): dvrk-kin's inverse dynamics with the model's effects,
/// plus what the simulated drive adds (the armature: reflected motor inertia, and the joint
/// damping of every tree joint, `C^T d C qd` through the frame variables).
pub struct Predictor {
    pub model: Model,
    dm: DynamicsModel,
    data: DynamicsData,
    /// The drives' reflected motor inertia on the joints read: `diag(a)`, or `B^T diag(a) B`
    /// under a coupling error (the motors sit on the true joints `B q`).
    armature: DMatrix<f64>,
    /// `a` (kg m^2, kg): the model's own drive's ([`dvrk_kin::DriveSpec`]) if it has one, else
    /// the arm's.
    motor: Vec<f64>,
    damping: DMatrix<f64>,
    gravity: Vector3<f64>,
    velocity_scale: f64,
}

impl Predictor {
    /// For `model` on arm `arm` of a scene with `gravity` (m/s^2, world).
    pub fn new(model: &Model, arm: &dvrk_sim::scene::Arm, gravity: [f64; 3]) -> Result<Predictor> {
        let inertias = arm.inertials.body_inertias(model).map_err(|e| CalibError::context("inertials", e))?;
        let inertias = dvrk_kin::effects::effect_inertias(model, &model.effects, &inertias)?;
        let dm = DynamicsModel::new(model, inertias)?;
        let nq = model.nq();
        let mut damping = DMatrix::zeros(nq, nq);
        // One tree joint per body (the joint that attaches its first frame): frames inside a
        // body move with it and carry no joint of their own.
        for b in &model.bodies {
            if let Some(v) = model.frames[b.frames[0]].variable() {
                let c = nalgebra::DVector::from_column_slice(&v.coef);
                damping += arm.damping * &c * c.transpose();
            }
        }
        // The tree joints' damping above follows the frames, which a coupling error already maps.
        // An identified model's efforts include its own drive; the arm's armature may sit above
        // it as the explicit PID's stability floor (`dvrk_sim::Scene::set_model`).
        let motor = model.spec.drive.as_ref().map_or_else(|| arm.armature.clone(), |d| d.armature.clone());
        let mut armature = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&motor));
        if let Some(b) = model.coupling_error_map() {
            armature = b.transpose() * armature * b;
        }
        Ok(Predictor {
            model: model.clone(),
            data: DynamicsData::new(model),
            dm,
            armature,
            motor,
            damping,
            gravity: Vector3::from(gravity),
            velocity_scale: COULOMB_SMOOTHING_DEFAULT,
        })
    }

    /// The reflected motor inertia per joint its efforts include (kg m^2, kg).
    pub fn armature(&self) -> &[f64] {
        &self.motor
    }

    /// The dynamics it evaluates: the arm's inertias with the model's payloads.
    pub fn dynamics(&self) -> &DynamicsModel {
        &self.dm
    }

    /// The predicted effort at every sample of `prep`, `[sample][joint]`.
    pub fn series(&mut self, prep: &Prepared) -> Result<Vec<Vec<f64>>> {
        self.series_at(&prep.q, &prep.qd, &prep.qdd)
    }

    /// The predicted effort at states `q`, `qd`, `qdd` (`[sample][joint]`), `[sample][joint]`.
    pub fn series_at(&mut self, q: &[Vec<f64>], qd: &[Vec<f64>], qdd: &[Vec<f64>]) -> Result<Vec<Vec<f64>>> {
        let nq = self.model.nq();
        let mut out = Vec::with_capacity(q.len());
        let mut tau = vec![0.0; nq];
        for i in 0..q.len() {
            dvrk_kin::dynamics::actuator_effort(&self.model, &self.dm, &mut self.data, &q[i], &qd[i], &qdd[i], &self.gravity, self.velocity_scale, &mut tau)?;
            let d = &self.damping * nalgebra::DVector::from_column_slice(&qd[i]) + &self.armature * nalgebra::DVector::from_column_slice(&qdd[i]);
            out.push((0..nq).map(|k| tau[k] + d[k]).collect());
        }
        Ok(out)
    }
}

// The workflow's residuals, shifts and norms.

pub(super) fn residual(prep: &Prepared, pred: &Table, filtered: bool) -> Table {
    sub(if filtered { &prep.effort } else { &prep.raw_effort }, pred)
}

/// `a - b`, element by element.
pub(super) fn sub(a: &Table, b: &Table) -> Table {
    a.iter().zip(b).map(|(x, y)| x.iter().zip(y).map(|(u, v)| u - v).collect()).collect()
}

/// `a += b`, element by element.
pub(super) fn add(a: &mut Table, b: &Table) {
    for (x, e) in a.iter_mut().zip(b) {
        for (u, v) in x.iter_mut().zip(e) {
            *u += v;
        }
    }
}

/// Half-width (samples) of the windowed-sinc kernel [`shifted`] interpolates with.
pub(super) const SHIFT_LOBES: isize = 16;

/// Kaiser window parameter of that kernel.
pub(super) const SHIFT_KAISER_BETA: f64 = 9.0;

/// The modified Bessel function I0 (its power series; converged for the window's arguments).
pub(super) fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term) = (1.0, 1.0);
    for k in 1..40 {
        term *= 0.5 * x / k as f64;
        sum += term * term;
    }
    sum
}

/// `base` shifted by `tau` seconds later (the measured stream lags the link by `tau`). Between
/// samples by a Kaiser-windowed sinc, the prediction being band-limited well below the
/// analysis rate's Nyquist. The Lanczos window it replaced converged slowly: an 8 ms latency
/// (0.8 of a 100 Hz sample) came out 8.121 ms with 6 lobes, 8.058 with 16, 8.030 with 64; this
/// kernel gives 8.032 with 16 (seed 1011; 10 ms, a whole sample, 10.006 either way). Past the
/// ends the series is continued by its point reflection about the end sample (value and slope
/// kept): held ends made the last half second of a 10 ms latency's held-out residual 4 times
/// its RMS (1.20x the floor overall, seed 11).
pub(super) fn shifted(base: &Table, dt: f64, tau: f64) -> Table {
    let n = base.len() as isize;
    let x = tau / dt;
    let i0 = x.floor() as isize;
    let s = x - i0 as f64;
    let sinc = |v: f64| if v.abs() < 1e-12 { 1.0 } else { (std::f64::consts::PI * v).sin() / (std::f64::consts::PI * v) };
    let window = |d: f64| bessel_i0(SHIFT_KAISER_BETA * (1.0 - (d / SHIFT_LOBES as f64).powi(2)).max(0.0).sqrt()) / bessel_i0(SHIFT_KAISER_BETA);
    // Weights of samples i + i0 + m, m in (-a, a]; normalised so a constant stays constant.
    let taps: Vec<(isize, f64)> = (1 - SHIFT_LOBES..=SHIFT_LOBES).map(|m| (m, sinc(s - m as f64) * window(s - m as f64))).collect();
    let total: f64 = taps.iter().map(|t| t.1).sum();
    (0..n)
        .map(|i| {
            let mut row = vec![0.0; base[0].len()];
            for &(m, w) in &taps {
                let j = i + i0 + m;
                // x(end + d) = 2 x(end) - x(end - d), at either end.
                let (edge, mirror) = if j < 0 {
                    (0, (-j).min(n - 1))
                } else if j > n - 1 {
                    (n - 1, (2 * (n - 1) - j).max(0))
                } else {
                    (j, j)
                };
                let (e, src) = (&base[edge as usize], &base[mirror as usize]);
                for ((r, x), y) in row.iter_mut().zip(e).zip(src) {
                    *r += w / total * if edge == mirror { *y } else { 2.0 * x - y };
                }
            }
            row
        })
        .collect()
}

/// RMS (noise-normalised: each joint's band-limited residual over its noise floor in the band)
/// over the active joints: 1 at the noise floor.
pub(super) fn normalised_rms(prep: &Prepared, r: &Table, range: std::ops::Range<usize>) -> f64 {
    let n = (range.len() * prep.active.len()).max(1) as f64;
    (range.flat_map(|i| prep.active.iter().map(move |&k| (i, k))).map(|(i, k)| (r[i][k] / prep.floor[k]).powi(2)).sum::<f64>() / n).sqrt()
}

/// RMS of the raw (unfiltered) effort residual of prediction `pred`, each joint over its raw
/// effort noise, over the active joints: 1 at the sensor's noise floor.
pub(super) fn raw_rms(prep: &Prepared, pred: &Table, range: std::ops::Range<usize>) -> f64 {
    let r = residual(prep, pred, false);
    let n = (range.len() * prep.active.len()).max(1) as f64;
    (range.flat_map(|i| prep.active.iter().map(move |&k| (i, k))).map(|(i, k)| (r[i][k] / prep.noise[k]).powi(2)).sum::<f64>() / n).sqrt()
}

/// RMS of column `k` of `r` (N·m, N) over the samples `range`.
pub(super) fn rms(r: &Table, k: usize, range: std::ops::Range<usize>) -> f64 {
    let n = range.len().max(1) as f64;
    (range.map(|i| r[i][k] * r[i][k]).sum::<f64>() / n).sqrt()
}

