//! What a run measures as it goes, step by step, without allocating: each joint's tracking error
//! and effort, the loop-closure gap, each arm's distance of its insertion axis from its RCM, over
//! the whole run and per tenth of it ([`WindowSummary`]).

use crate::error::Result;
use crate::sim::Sim;
use dvrk_kin::rcm::distance_to_axis;
use dvrk_kin::Pose;
use nalgebra::{Point3, Vector3};
use serde::Serialize;

/// One tenth of a run ([`crate::Summary::windows`]).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct WindowSummary {
    /// s of simulated time
    pub start: f64,
    pub end: f64,
    /// Largest loop-closure gap in the window (m).
    pub max_closure_error: f64,
    /// Largest distance of an insertion axis from its arm's RCM in the window (m).
    pub max_rcm_error: f64,
}

/// Windows of a run ([`crate::Summary::windows`]).
const WINDOWS: u64 = 10;

/// Where each arm's RCM is, to measure its insertion axis against.
pub(crate) struct RcmWatch {
    /// Per arm: its insertion-axis frame, that frame's placement in its body, and the RCM in the
    /// world (m).
    rcms: Vec<Option<(usize, Pose, Vector3<f64>)>>,
    /// An arm carried by another (a PSM on its held SUJ) has its RCM fixed to the carrying body,
    /// which the position-held setup joints let sag slightly: the carrying arm, its body, and
    /// the point in that body's frame (m).
    carriers: Vec<Option<(usize, usize, Vector3<f64>)>>,
}

impl RcmWatch {
    /// The RCMs of `sim`'s arms at home (an arm without one is not watched).
    pub(crate) fn new(sim: &Sim) -> RcmWatch {
        let rcms: Vec<Option<(usize, Pose, Vector3<f64>)>> = sim
            .arms
            .iter()
            .map(|a| {
                let m = &a.model;
                let r = m.rcm.as_ref()?;
                let fk = m.fk(&m.home()).ok()?;
                let body = m.frames[r.frame].body;
                let rel = fk[m.bodies[body].frames[0]].inverse() * fk[r.frame];
                Some((r.frame, rel, (m.base * Point3::from(r.point)).coords))
            })
            .collect();
        let carriers = sim
            .arms
            .iter()
            .zip(&rcms)
            .map(|(a, r)| {
                let (pa, pf) = a.parent?;
                let body = sim.arms[pa].model.frames[pf].body;
                let local = sim.body_pose(pa, body).inverse() * Point3::from(r.as_ref()?.2);
                Some((pa, body, local.coords))
            })
            .collect();
        RcmWatch { rcms, carriers }
    }

    /// Each watched arm's distance of its insertion axis from its RCM now (m), to `each`.
    fn distances(&self, sim: &Sim, mut each: impl FnMut(f64)) {
        for (a, r) in self.rcms.iter().enumerate() {
            if let Some((frame, rel, point)) = r {
                let pose = sim.frame_pose(a, *frame, rel);
                let point = match self.carriers[a] {
                    Some((pa, body, local)) => (sim.body_pose(pa, body) * Point3::from(local)).coords,
                    None => *point,
                };
                each(distance_to_axis(&pose, &point));
            }
        }
    }
}

/// The run's measures so far.
pub(crate) struct Tally {
    steps: u64,
    /// Per joint: the sum of squared tracking errors (rad^2, m^2), the largest error (rad, m)
    /// and the largest |effort| (N·m, N).
    pub(crate) sum_sq: Vec<f64>,
    pub(crate) max_err: Vec<f64>,
    pub(crate) max_eff: Vec<f64>,
    /// Largest loop-closure gap (m), when (s), and the largest over the last tenth (m).
    pub(crate) max_closure: f64,
    pub(crate) max_closure_time: f64,
    pub(crate) final_closure: f64,
    /// Largest RCM distance (m).
    pub(crate) max_rcm: f64,
    pub(crate) windows: Vec<WindowSummary>,
    /// False once any tracking error is not finite.
    pub(crate) finite: bool,
}

impl Tally {
    /// For `n` joints over `steps` steps of `dt` (s).
    pub(crate) fn new(n: usize, steps: u64, dt: f64) -> Tally {
        Tally {
            steps,
            sum_sq: vec![0.0; n],
            max_err: vec![0.0; n],
            max_eff: vec![0.0; n],
            max_closure: 0.0,
            max_closure_time: 0.0,
            final_closure: 0.0,
            max_rcm: 0.0,
            windows: (0..WINDOWS)
                .map(|w| WindowSummary { start: (w * steps / WINDOWS) as f64 * dt, end: ((w + 1) * steps / WINDOWS) as f64 * dt, max_closure_error: 0.0, max_rcm_error: 0.0 })
                .collect(),
            finite: true,
        }
    }

    /// Count step `s` (0-based), which ended at `t` (s).
    pub(crate) fn after_step(&mut self, sim: &Sim, s: u64, t: f64, rcm: &RcmWatch) -> Result<()> {
        for i in 0..self.sum_sq.len() {
            let act = sim.actuator(i)?;
            let e = sim.q()[i] - act.target;
            if !e.is_finite() {
                self.finite = false;
            }
            self.sum_sq[i] += e * e;
            self.max_err[i] = self.max_err[i].max(e.abs());
            self.max_eff[i] = self.max_eff[i].max(act.effort.abs());
        }
        let c = sim.closure_error();
        if c > self.max_closure {
            self.max_closure = c;
            self.max_closure_time = t;
        }
        if s >= self.steps - self.steps / 10 {
            self.final_closure = self.final_closure.max(c);
        }
        let window = &mut self.windows[(s * WINDOWS / self.steps) as usize];
        window.max_closure_error = window.max_closure_error.max(c);
        let max_rcm = &mut self.max_rcm;
        rcm.distances(sim, |d| {
            *max_rcm = max_rcm.max(d);
            window.max_rcm_error = window.max_rcm_error.max(d);
        });
        Ok(())
    }

    /// The windows a run of `done` steps of `dt` (s) reached (a run stopped early, by a signal
    /// or a non-finite state, reports those).
    pub(crate) fn windows_reached(&self, done: u64, dt: f64) -> Vec<WindowSummary> {
        self.windows.iter().copied().filter(|w| w.start < done as f64 * dt).collect()
    }
}
