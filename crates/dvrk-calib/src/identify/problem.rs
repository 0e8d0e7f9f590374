//! The identification problem: the parameters (every body's 10 inertial parameters and the
//! effects of each recorded channel), and the regression `tau_channel = Y theta` over a
//! recording, built from dvrk-kin's closed-loop regressor mapped to the recorded channels.

use crate::filter::{derivative, Butterworth2};
use dvrk_sim::recording::JointLog;
use crate::error::{CalibError, Result};
use dvrk_kin::dynamics::{PARAMETERS_PER_BODY, PARAMETER_NAMES};
use dvrk_kin::{DynamicsData, DynamicsModel, Model};
use nalgebra::{DMatrix, DVector, DVectorView, DVectorViewMut, Vector3};
use serde::Serialize;

/// A per-channel effect term of the regression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectTerm {
    /// Coulomb friction level `fc` (N·m, N) times the smoothed sign of the channel velocity.
    Coulomb,
    /// Constant effort offset (N·m, N): the Coulomb model's asymmetry, sensor zero.
    Offset,
    /// Viscous friction `fv` (N·m s/rad, N s/m) times the channel velocity.
    Viscous,
    /// Reflected motor (rotor) inertia `im` (kg m^2, kg) times the channel acceleration.
    Armature,
    /// Joint spring stiffness `k` (N·m/rad, N/m): effort `k q` (the tool's cables).
    Spring,
    /// Stribeck friction `fs` (N·m, N): the extra breakaway effort at low speed,
    /// `fs tanh(v / vc) exp(-(v / vs)^2)` ([`Processing::stribeck_velocity`] vs).
    Stribeck,
    /// Coulomb friction growing with the square of the channel position, `fq q^2` times the
    /// smoothed velocity sign (N·m/rad^2; N/m^2 for the insertion): cables that tighten as the
    /// joint winds away from its zero.
    Winding,
    /// Presliding (Dahl) friction `fd` (N·m, N) times the Dahl state `z` in [-1, 1], which
    /// follows the channel's position, `dz/dq = (1 - z sgn(dq)) / sigma`
    /// ([`Processing::dahl_displacement_of`] sigma): the cables stretch over the pulleys before
    /// they slip, so after a reversal the friction turns over within a displacement, however
    /// slowly the channel moves, where the Coulomb term's `tanh(v / vc)` turns over within a
    /// velocity.
    Dahl,
    /// A configuration-dependent joint spring's linear term `k1` (N·m/rad, N/m): effort `k1 q`,
    /// either sign (with [`EffectTerm::CableQuadratic`] and [`EffectTerm::CableCubic`], dvrk-kin's
    /// `cable_spring`: the MTM platform's cable).
    CableLinear,
    /// Its quadratic term `k2` (N·m/rad^2, N/m^2): effort `k2 q^2`, either sign.
    CableQuadratic,
    /// Its cubic term `k3` (N·m/rad^3, N/m^3): effort `k3 q^3`, either sign.
    CableCubic,
}

impl EffectTerm {
    /// Every term, in column order.
    pub const ALL: [EffectTerm; 5] = [EffectTerm::Coulomb, EffectTerm::Offset, EffectTerm::Viscous, EffectTerm::Armature, EffectTerm::Spring];

    /// Short parameter name and its unit for a revolute channel.
    pub fn symbol(self) -> &'static str {
        match self {
            EffectTerm::Coulomb => "fc",
            EffectTerm::Offset => "fo",
            EffectTerm::Viscous => "fv",
            EffectTerm::Armature => "im",
            EffectTerm::Spring => "k",
            EffectTerm::Stribeck => "fs",
            EffectTerm::Winding => "fq",
            EffectTerm::Dahl => "fd",
            EffectTerm::CableLinear => "k1",
            EffectTerm::CableQuadratic => "k2",
            EffectTerm::CableCubic => "k3",
        }
    }

    /// Must the parameter be non-negative (physics)?
    pub fn nonnegative(self) -> bool {
        !matches!(self, EffectTerm::Offset | EffectTerm::CableLinear | EffectTerm::CableQuadratic | EffectTerm::CableCubic)
    }
}

/// What the regression contains (the default: rigid bodies only).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Terms {
    /// Effect terms added to every channel.
    pub effects: Vec<EffectTerm>,
    /// Channels that get the spring term (the tool's cable-driven joints); others do not.
    pub spring_channels: Vec<usize>,
    /// Model joints that get Coulomb and viscous friction in *joint* velocity as well (their
    /// efforts reach the channels through `to_joint^T`): the tool's wrist and jaw, whose cables
    /// and pulleys rub at the joint while the motors' own friction acts on the actuator channels.
    pub joint_friction: Vec<usize>,
    /// Cross-coupling terms `(channel, source, term)`: channel `channel`'s effort gets `term`
    /// of channel `source`'s motion (spring: its position; viscous: velocity; Coulomb: smoothed
    /// sign), of either sign. The tool's cables run past each other through the shaft.
    pub cross: Vec<(usize, usize, EffectTerm)>,
    /// Channels that get the position-dependent Coulomb term [`EffectTerm::Winding`].
    pub winding_channels: Vec<usize>,
    /// Channels that get the presliding term [`EffectTerm::Dahl`].
    pub dahl_channels: Vec<usize>,
    /// Model joints with a configuration-dependent spring in *joint* position, `(joint, order)`:
    /// `k1 q` (order 1), plus `k2 q^2` (2), plus `k3 q^3` (3), any signs; their efforts reach the
    /// channels through `to_joint^T`. The MTM's platform cable and wrist-pitch spring act on the
    /// joint, not on a motor.
    pub joint_springs: Vec<(usize, usize)>,
}

/// One unknown of the regression.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Param {
    /// Parameter `k` (of [`PARAMETER_NAMES`]) of body `body`.
    Body { body: usize, k: usize },
    /// An effect term of channel `channel`.
    Effect { term: EffectTerm, channel: usize },
    /// A friction term (Coulomb or viscous) in the velocity of model joint `joint`.
    Joint { term: EffectTerm, joint: usize },
    /// A cross-coupling term: channel `channel`'s effort from channel `source`'s motion.
    Cross { term: EffectTerm, channel: usize, source: usize },
}

/// The unknowns, in column order: bodies first (10 each, `Model::bodies` order), then the
/// effects channel by channel.
#[derive(Debug, Clone)]
pub struct Layout {
    pub params: Vec<Param>,
    pub nbodies: usize,
    pub nchannels: usize,
}

impl Layout {
    /// The layout for `model` with `terms` on `nchannels` channels.
    pub fn new(model: &Model, nchannels: usize, terms: &Terms) -> Layout {
        let nb = model.bodies.len();
        let mut params: Vec<Param> = (0..nb).flat_map(|b| (0..PARAMETERS_PER_BODY).map(move |k| Param::Body { body: b, k })).collect();
        for channel in 0..nchannels {
            for &term in &terms.effects {
                if term == EffectTerm::Spring && !terms.spring_channels.contains(&channel) {
                    continue;
                }
                params.push(Param::Effect { term, channel });
            }
        }
        params.extend(terms.winding_channels.iter().map(|&channel| Param::Effect { term: EffectTerm::Winding, channel }));
        params.extend(terms.dahl_channels.iter().map(|&channel| Param::Effect { term: EffectTerm::Dahl, channel }));
        for &joint in &terms.joint_friction {
            params.extend([EffectTerm::Coulomb, EffectTerm::Viscous].map(|term| Param::Joint { term, joint }));
        }
        for &(joint, order) in &terms.joint_springs {
            params.extend([EffectTerm::CableLinear, EffectTerm::CableQuadratic, EffectTerm::CableCubic].into_iter().take(order.min(3)).map(|term| Param::Joint { term, joint }));
        }
        params.extend(terms.cross.iter().map(|&(channel, source, term)| Param::Cross { term, channel, source }));
        Layout { params, nbodies: nb, nchannels }
    }

    /// Number of unknowns.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// True when there is nothing to identify.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// A readable name: `pitch_back_link.mcx`, `outer_yaw.fc`.
    pub fn name(&self, model: &Model, channels: &[String], i: usize) -> String {
        match self.params[i] {
            Param::Body { body, k } => format!("{}.{}", model.bodies[body].name, PARAMETER_NAMES[k]),
            Param::Effect { term, channel } => format!("{}.{}", channels[channel], term.symbol()),
            Param::Joint { term, joint } => format!("{} joint.{}", model.joints[joint].name, term.symbol()),
            Param::Cross { term, channel, source } => format!("{}.{} from {}", channels[channel], term.symbol(), channels[source]),
        }
    }
}

/// How recordings are turned into regressions.
#[derive(Debug, Clone, PartialEq)]
pub struct Processing {
    /// Low-pass cut-off (Hz) of the zero-phase filter applied to velocities (before
    /// differentiating them into accelerations) and to efforts.
    pub cutoff: f64,
    /// Per-channel cut-offs (Hz) overriding `cutoff`; empty: `cutoff` everywhere.
    pub channel_cutoff: Vec<f64>,
    /// Velocity scale of the Coulomb term's smoothed sign, `tanh(qd / v)` (rad/s, m/s).
    pub coulomb_velocity: f64,
    /// Per-channel (and per-joint, for joint friction: joint k uses entry k) Coulomb velocity
    /// scales overriding `coulomb_velocity`; empty: `coulomb_velocity` everywhere.
    pub channel_coulomb_velocity: Vec<f64>,
    /// Velocity below which the Stribeck term acts (rad/s, m/s).
    pub stribeck_velocity: f64,
    /// Presliding displacement `sigma` of the Dahl term (rad, m): the travel after a reversal
    /// over which its friction turns over (to 1 - 1/e).
    pub dahl_displacement: f64,
    /// Per-channel presliding displacements overriding `dahl_displacement`; empty: that everywhere.
    pub channel_dahl_displacement: Vec<f64>,
    /// Gravity in the model's world frame (m/s^2).
    pub gravity: Vector3<f64>,
    /// Samples dropped at each end (filter edge transients).
    pub trim: usize,
    /// Order of the zero-phase Butterworth low-pass (even; 2: the PSM's). A higher order keeps
    /// the band below the cut-off whole and the noise above it out: the MTM's efforts carry
    /// 3..6 Hz content its encoders see too, above the excitation's harmonics.
    pub filter_order: usize,
}

impl Default for Processing {
    fn default() -> Self {
        Processing {
            cutoff: 10.0,
            channel_cutoff: Vec::new(),
            coulomb_velocity: 0.01,
            channel_coulomb_velocity: Vec::new(),
            stribeck_velocity: 0.05,
            dahl_displacement: 0.01,
            channel_dahl_displacement: Vec::new(),
            gravity: Vector3::new(0.0, 0.0, -9.81),
            trim: 100,
            filter_order: 2,
        }
    }
}

impl Processing {
    /// The cut-off (Hz) of channel `c`.
    pub fn cutoff_of(&self, c: usize) -> f64 {
        self.channel_cutoff.get(c).copied().unwrap_or(self.cutoff)
    }

    /// The Coulomb velocity scale (rad/s, m/s) of channel (or joint) `c`.
    pub fn coulomb_velocity_of(&self, c: usize) -> f64 {
        self.channel_coulomb_velocity.get(c).copied().unwrap_or(self.coulomb_velocity)
    }

    /// The presliding displacement (rad, m) of channel `c`.
    pub fn dahl_displacement_of(&self, c: usize) -> f64 {
        self.channel_dahl_displacement.get(c).copied().unwrap_or(self.dahl_displacement)
    }
}

/// Rows per block of a pass over the regression: the block's matrices (channels x rows x
/// parameters, 4 MB for the PSM's 7 channels and 150 parameters) bound the memory, and a block
/// is large enough for the matrix products to run at speed.
const BLOCK_ROWS: usize = 512;

/// A recording as a regression `tau_c = Y_c theta` per channel `c`: the normal equations' matrix
/// `Y_c^T Y_c`, the efforts, and what the rows are computed from. The rows themselves are not
/// kept (10 kB per sample for the PSM: 2.5 GB for a 1 kHz, 5 min recording); a pass over them
/// ([`Regression::predict`], [`Regression::project`]) computes them again in blocks.
#[derive(Debug, Clone)]
pub struct Regression {
    /// Per channel: `Y^T Y` over every row, kept by the first [`Regression::normal_equations`].
    gram: std::sync::OnceLock<Vec<DMatrix<f64>>>,
    /// Per channel: the measured efforts as recorded (N·m, N).
    pub tau: Vec<Vec<f64>>,
    /// Per channel: the efforts through the same zero-phase filter as the velocities.
    pub tau_filtered: Vec<Vec<f64>>,
    /// Per channel: velocity range seen (min, max), for excitation checks.
    pub velocity_range: Vec<(f64, f64)>,
    rows: RowSource,
}

/// What a regression row is computed from: per channel over the kept samples, the encoder
/// positions, the filtered velocities and accelerations and the Dahl states.
#[derive(Debug, Clone)]
struct RowSource {
    model: Model,
    layout: Layout,
    processing: Processing,
    to_joint: DMatrix<f64>,
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    qdd: Vec<Vec<f64>>,
    dahl: Vec<Vec<f64>>,
}

impl Regression {
    /// Rows (samples) of the regression.
    pub fn len(&self) -> usize {
        self.tau.first().map_or(0, |t| t.len())
    }

    /// Whether it has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Per channel, the normal equations `Y_c^T Y_c` and `Y_c^T v_c` for per-row values `v`
    /// (`[channel][row]`): one pass over the rows, `Y_c^T Y_c` kept for the next call.
    pub fn normal_equations(&self, v: &[Vec<f64>]) -> Result<Vec<(DMatrix<f64>, DVector<f64>)>> {
        if let Some(g) = self.gram.get() {
            return Ok(g.iter().cloned().zip(self.project(v)?).collect());
        }
        let p = self.rows.layout.len();
        let mut gram = vec![DMatrix::zeros(p, p); self.tau.len()];
        let mut yv = vec![DVector::zeros(p); self.tau.len()];
        let mut rows_major = DMatrix::zeros(BLOCK_ROWS, p);
        self.rows.for_each_block(|start, len, blocks| {
            for (((g, o), yt), vc) in gram.iter_mut().zip(yv.iter_mut()).zip(blocks).zip(v) {
                let yt = yt.columns(0, len);
                let mut y = rows_major.rows_mut(0, len);
                yt.transpose_to(&mut y);
                // `gemm` (blocked) rather than `gemm_tr` (a dot product per entry: 4x slower here).
                g.gemm(1.0, &yt, &y, 1.0);
                o.gemv(1.0, &yt, &DVectorView::from_slice(&vc[start..start + len], len), 1.0);
            }
        })?;
        Ok(self.gram.get_or_init(|| gram).iter().cloned().zip(yv).collect())
    }

    /// Per channel, the prediction `Y_c theta` at every row (N·m, N).
    pub fn predict(&self, theta: &DVector<f64>) -> Result<Vec<Vec<f64>>> {
        let mut out = vec![vec![0.0; self.len()]; self.tau.len()];
        self.rows.for_each_block(|start, len, blocks| {
            for (o, yt) in out.iter_mut().zip(blocks) {
                let mut o = DVectorViewMut::from_slice(&mut o[start..start + len], len);
                o.gemv_tr(1.0, &yt.columns(0, len), theta, 0.0);
            }
        })?;
        Ok(out)
    }

    /// Per channel, `Y_c^T v_c` for per-row values `v` (`[channel][row]`).
    pub fn project(&self, v: &[Vec<f64>]) -> Result<Vec<DVector<f64>>> {
        let p = self.rows.layout.len();
        let mut out = vec![DVector::zeros(p); self.tau.len()];
        self.rows.for_each_block(|start, len, blocks| {
            for ((o, yt), vc) in out.iter_mut().zip(blocks).zip(v) {
                o.gemv(1.0, &yt.columns(0, len), &DVectorView::from_slice(&vc[start..start + len], len), 1.0);
            }
        })?;
        Ok(out)
    }
}

impl RowSource {
    /// Every row in blocks of [`BLOCK_ROWS`]: `f(start, len, blocks)`, `blocks[c]`'s first `len`
    /// columns channel `c`'s rows `start..start + len` (transposed: a row is written and read
    /// contiguously, where a column-major block strided every write by the block's height).
    fn for_each_block(&self, mut f: impl FnMut(usize, usize, &[DMatrix<f64>])) -> Result<()> {
        let (model, layout, processing, map) = (&self.model, &self.layout, &self.processing, &self.to_joint);
        let nc = self.q.len();
        let rows = self.q.first().map_or(0, |q| q.len());
        let p = layout.len();
        let inertias = (0..model.bodies.len()).map(|_| dvrk_kin::BodyInertia::new(1.0, [0.0; 3], [[1e-3, 0.0, 0.0], [0.0, 1e-3, 0.0], [0.0, 0.0, 1e-3]])).collect();
        let dm = DynamicsModel::new(model, inertias)?;
        let mut data = DynamicsData::new(model);
        let nq = model.nq();
        let nbp = PARAMETERS_PER_BODY * model.bodies.len();
        let mut yj = DMatrix::zeros(nq, nbp);
        let mut mapped = DMatrix::zeros(nbp, nc);
        let (mut qj, mut qdj, mut qddj) = (vec![0.0; nq], vec![0.0; nq], vec![0.0; nq]);
        let mut y: Vec<DMatrix<f64>> = (0..nc).map(|_| DMatrix::zeros(p, BLOCK_ROWS)).collect();
        let (q, qd_f, qdd_f, dahl) = (&self.q, &self.qd, &self.qdd, &self.dahl);
        let mut start = 0;
        while start < rows {
            let len = BLOCK_ROWS.min(rows - start);
            for yc in y.iter_mut() {
                yc.fill(0.0);
            }
            for r in 0..len {
                let i = start + r;
                for j in 0..nq {
                    qj[j] = (0..nc).map(|c| map[(j, c)] * q[c][i]).sum();
                    qdj[j] = (0..nc).map(|c| map[(j, c)] * qd_f[c][i]).sum();
                    qddj[j] = (0..nc).map(|c| map[(j, c)] * qdd_f[c][i]).sum();
                }
                dvrk_kin::regressor(model, &dm, &mut data, &qj, &qdj, &qddj, &processing.gravity, &mut yj)?;
                // Channel effort = sum over joints of to_joint[j][c] * joint effort.
                mapped.gemm_tr(1.0, &yj, map, 0.0);
                for (c, yc) in y.iter_mut().enumerate() {
                    yc.view_mut((0, r), (nbp, 1)).copy_from(&mapped.column(c));
                }
                for (col, param) in layout.params.iter().enumerate().skip(nbp) {
                    match *param {
                        Param::Effect { term, channel } => {
                            let v = qd_f[channel][i];
                            let vc = processing.coulomb_velocity_of(channel);
                            y[channel][(col, r)] = match term {
                                EffectTerm::Coulomb => (v / vc).tanh(),
                                EffectTerm::Offset => 1.0,
                                EffectTerm::Viscous => v,
                                EffectTerm::Armature => qdd_f[channel][i],
                                EffectTerm::Spring => q[channel][i],
                                EffectTerm::Stribeck => (v / vc).tanh() * (-(v / processing.stribeck_velocity).powi(2)).exp(),
                                EffectTerm::Winding => (v / vc).tanh() * q[channel][i].powi(2),
                                EffectTerm::Dahl => dahl[channel][i],
                                EffectTerm::CableLinear => q[channel][i],
                                EffectTerm::CableQuadratic => q[channel][i].powi(2),
                                EffectTerm::CableCubic => q[channel][i].powi(3),
                            };
                        }
                        Param::Joint { term, joint } => {
                            // A joint force f does virtual work f v_j = sum_c map[j][c] f qd_c.
                            let v = qdj[joint];
                            let f = match term {
                                EffectTerm::Coulomb => (v / processing.coulomb_velocity_of(joint)).tanh(),
                                EffectTerm::CableLinear => qj[joint],
                                EffectTerm::CableQuadratic => qj[joint].powi(2),
                                EffectTerm::CableCubic => qj[joint].powi(3),
                                _ => v,
                            };
                            for (c, yc) in y.iter_mut().enumerate() {
                                yc[(col, r)] = map[(joint, c)] * f;
                            }
                        }
                        Param::Cross { term, channel, source } => {
                            let v = qd_f[source][i];
                            y[channel][(col, r)] = match term {
                                EffectTerm::Coulomb => (v / processing.coulomb_velocity_of(source)).tanh(),
                                EffectTerm::Viscous => v,
                                EffectTerm::Armature => qdd_f[source][i],
                                _ => q[source][i],
                            };
                        }
                        Param::Body { .. } => {}
                    }
                }
            }
            f(start, len, &y);
            start += len;
        }
        Ok(())
    }
}

/// Build the regression of `rec` for `model`: filtered velocities, accelerations by
/// differentiation, dvrk-kin's joint-space regressor mapped to the channels (`to_joint^T Y`),
/// then the effect columns in channel coordinates.
pub fn regression(model: &Model, rec: &JointLog, layout: &Layout, processing: &Processing) -> Result<Regression> {
    let nc = rec.names.len();
    let n = rec.len();
    if n <= 2 * processing.trim + 10 {
        return Err(CalibError::data(&rec.source, format!("{n} samples; {} are trimmed at the ends for the filter", 2 * processing.trim)));
    }
    let rate = rec.rate().ok_or_else(|| CalibError::data(&rec.source, format!("sample times do not advance ({} s to {} s)", rec.t[0], rec.t[n - 1])))?;
    let dt = 1.0 / rate;
    for c in 0..nc {
        let fc = processing.cutoff_of(c);
        if !(fc > 0.0 && fc < 0.45 * rate) {
            // The rate is the average over the whole recording: a gap in the stamps (a paused
            // logger) brings it down, which the message says rather than "(0, 0.0) Hz".
            let gap = rec.t.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
            let f = dvrk_kin::fmt_number;
            return Err(CalibError::field(
                "cutoff",
                format!(
                    "{} Hz (channel {}) is not in (0, {}) Hz: the recording averages {} Hz ({n} samples over {} s; the longest gap between two stamps is {} s)",
                    f(fc),
                    rec.names[c],
                    f(0.45 * rate),
                    f(rate),
                    f(rec.t[n - 1] - rec.t[0]),
                    f(gap)
                ),
            ));
        }
        let vc = processing.coulomb_velocity_of(c);
        if !(vc > 0.0 && vc.is_finite()) {
            return Err(CalibError::field("coulomb_velocity", format!("{vc} (channel {}) must be positive", rec.names[c])));
        }
        let sigma = processing.dahl_displacement_of(c);
        if !(sigma > 0.0 && sigma.is_finite()) {
            return Err(CalibError::field("dahl_displacement", format!("{sigma} (channel {}) must be positive", rec.names[c])));
        }
    }
    // Each channel through its own cut-off: the insertion's effort carries real 10..20 Hz
    // content that the wrist's noisier velocities do not.
    let column = |m: &Vec<Vec<f64>>, c: usize| m.iter().map(|r| r[c]).collect::<Vec<f64>>();
    let filtered = |m: &Vec<Vec<f64>>, c: usize| {
        let fc = processing.cutoff_of(c);
        let pad = (3.0 * rate / fc) as usize;
        if processing.filter_order == 2 {
            Butterworth2::new(fc, rate).filtfilt(&column(m, c), pad)
        } else {
            crate::filter::Butterworth::new(processing.filter_order, fc, rate).filtfilt(&column(m, c), pad)
        }
    };
    let qd_f: Vec<Vec<f64>> = (0..nc).map(|c| filtered(&rec.velocity, c)).collect();
    let qdd_f: Vec<Vec<f64>> = qd_f.iter().map(|v| derivative(v, dt)).collect();
    let tau_f: Vec<Vec<f64>> = (0..nc).map(|c| filtered(&rec.effort, c)).collect();
    // The presliding state along the recorded (unfiltered: encoder) positions, where asked for.
    // The Dahl state over the whole recording, before the trim, so the trimmed ends forget the start.
    let dahl: Vec<Vec<f64>> = (0..nc).map(|c| if layout.params.contains(&Param::Effect { term: EffectTerm::Dahl, channel: c }) { dvrk_kin::presliding::dahl_state(&column(&rec.position, c), processing.dahl_displacement_of(c)) } else { Vec::new() }).collect();
    let keep = processing.trim..n - processing.trim;
    let trimmed = |v: &Vec<f64>| v[keep.clone()].to_vec();
    let rows = RowSource {
        model: model.clone(),
        layout: layout.clone(),
        processing: processing.clone(),
        to_joint: rec.joint_map(),
        q: (0..nc).map(|c| trimmed(&column(&rec.position, c))).collect(),
        qd: qd_f.iter().map(trimmed).collect(),
        qdd: qdd_f.iter().map(trimmed).collect(),
        dahl: dahl.iter().map(|d| if d.is_empty() { Vec::new() } else { trimmed(d) }).collect(),
    };
    let velocity_range = qd_f.iter().map(|v| v[keep.clone()].iter().fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(*x), b.max(*x)))).collect();
    Ok(Regression {
        gram: std::sync::OnceLock::new(),
        tau: (0..nc).map(|c| rec.effort[keep.clone()].iter().map(|r| r[c]).collect()).collect(),
        tau_filtered: tau_f.iter().map(|v| v[keep.clone()].to_vec()).collect(),
        velocity_range,
        rows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PSM moving every joint on its own sine for 1300 samples at 200 Hz (three blocks, the
    /// last partial), efforts arbitrary.
    fn recording(model: &Model) -> JointLog {
        let nq = model.nq();
        let n = 2 * BLOCK_ROWS + 276;
        let t: Vec<f64> = (0..n).map(|i| i as f64 / 200.0).collect();
        let wave = |j: usize, t: f64| 0.2 * (1.0 + 0.3 * j as f64) * (t * (1.0 + 0.4 * j as f64)).sin();
        let dwave = |j: usize, t: f64| 0.2 * (1.0 + 0.3 * j as f64) * (1.0 + 0.4 * j as f64) * (t * (1.0 + 0.4 * j as f64)).cos();
        let mid = |j: usize| 0.5 * (model.joints[j].lower + model.joints[j].upper);
        JointLog {
            source: "sines".into(),
            position: t.iter().map(|&s| (0..nq).map(|j| mid(j) + 0.1 * wave(j, s)).collect()).collect(),
            velocity: t.iter().map(|&s| (0..nq).map(|j| 0.1 * dwave(j, s)).collect()).collect(),
            effort: t.iter().map(|&s| (0..nq).map(|j| (s * (j + 1) as f64).cos()).collect()).collect(),
            names: model.joints.iter().map(|j| j.name.clone()).collect(),
            t,
            ..JointLog::default()
        }
    }

    /// A recording whose stamps jump by a day in the middle (a paused logger) averages a rate far
    /// below its filter's: the error says so, with the gap, not "(0, 0.0) Hz" (issue 63 item 6).
    #[test]
    fn a_gap_in_the_stamps_is_named_when_the_cutoff_does_not_fit() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let mut rec = recording(&model);
        let half = rec.len() / 2;
        for t in &mut rec.t[half..] {
            *t += 86_400.0;
        }
        let layout = Layout::new(&model, rec.names.len(), &Terms::default());
        let e = regression(&model, &rec, &layout, &Processing::default()).unwrap_err().to_string();
        assert!(e.contains("10 Hz (channel outer_yaw) is not in (0, 0.00676") && e.contains("the recording averages 0.01503") && e.contains("the longest gap between two stamps is 86400.00"), "{e}");
    }

    #[test]
    fn the_block_passes_agree_with_each_other_across_block_edges() {
        let model = dvrk_kin::load("psm", None).unwrap();
        let rec = recording(&model);
        let layout = Layout::new(&model, rec.names.len(), &Terms::default());
        let reg = regression(&model, &rec, &layout, &Processing::default()).unwrap();
        assert_eq!(reg.len(), rec.len() - 2 * Processing::default().trim);
        let theta = DVector::from_fn(layout.len(), |i, _| ((i * 7919) % 101) as f64 / 101.0 - 0.5);
        // `Y^T (Y theta)` by a prediction pass then a projection pass, and `(Y^T Y) theta` from
        // the normal equations' pass.
        let predicted = reg.predict(&theta).unwrap();
        let projected = reg.project(&predicted).unwrap();
        let normal = reg.normal_equations(&predicted).unwrap();
        for ((g, yv), pr) in normal.iter().zip(&projected) {
            let scale = pr.amax().max(1e-12);
            assert!((g * &theta - pr).amax() < 1e-9 * scale, "{}", (g * &theta - pr).amax() / scale);
            assert!((yv - pr).amax() < 1e-9 * scale);
        }
        // The second call reuses `Y^T Y` and still projects.
        let again = reg.normal_equations(&reg.tau_filtered).unwrap();
        assert!((&again[0].0 - &normal[0].0).amax() == 0.0 && again[0].1.amax() > 0.0);
    }
}
