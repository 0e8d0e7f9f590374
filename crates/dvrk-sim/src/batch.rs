//! Many independent copies of a scene stepped together ([`BatchSim`]): a reinforcement-learning
//! run's thousand PSMs, a sweep of gains or payloads as one batch. Each copy is a whole [`Sim`]
//! (its own model, state and workspace: nothing shared), the copies step in parallel on a rayon
//! pool of the caller's size, and the commands and states live in flat copy-major arrays
//! (`n x nq`, copy `c`'s joint `j` at `c * nq + j`) allocated once: a step allocates nothing.

use crate::control::{Gains, Mode};
use crate::error::{Result, SimError};
use crate::scene::Scene;
use crate::sim::{Engine, Sim, SimOptions};
use rayon::prelude::*;
use std::sync::Arc;

/// `n` copies of a scene and their flat command and state arrays.
pub struct BatchSim {
    /// Per copy: the scene it is built from (its start configuration and model: what a reset
    /// rebuilds); shared until a copy's start or model changes (then that copy's own).
    scenes: Vec<Arc<Scene>>,
    /// Per copy and arm: the start a reset without one goes back to (the scene's own).
    default_start: Vec<Vec<Vec<f64>>>,
    options: SimOptions,
    sims: Vec<Sim>,
    pool: rayon::ThreadPool,
    nq: usize,
    /// Measured joint positions (rad, m), velocities (rad/s, m/s) and the efforts applied at the
    /// last step (N·m, N), `n x nq`.
    q: Vec<f64>,
    qd: Vec<f64>,
    effort: Vec<f64>,
    /// Commands read at every [`BatchSim::step`], `n x nq`: position targets (rad, m) and their
    /// velocity feed-forward (rad/s, m/s) for joints in PID or position mode, efforts (N·m, N)
    /// for joints in effort mode.
    target: Vec<f64>,
    target_velocity: Vec<f64>,
    effort_command: Vec<f64>,
}

impl BatchSim {
    /// `n` copies of `scene` on `threads` worker threads (0: one per core), each at the scene's
    /// start, holding it. The engine is `options`' or the scene's, the reduced one when neither
    /// says.
    pub fn new(scene: &Scene, n: usize, options: &SimOptions, threads: usize) -> Result<BatchSim> {
        if n == 0 {
            return Err(SimError::value("batch size", 0.0, "must be at least 1"));
        }
        let mut options = options.clone();
        options.engine = options.engine.or(scene.engine).or(Some(Engine::Reduced));
        // Each copy is one task: a copy's own arm groups do not fan out again.
        options.parallel = false;
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| SimError::value("batch threads", threads as f64, e.to_string()))?;
        let first = Sim::new(scene, &options)?;
        let nq = first.nq();
        let mut sims = Vec::with_capacity(n);
        sims.push(first);
        let rest: Vec<Result<Sim>> = pool.install(|| (1..n).into_par_iter().map(|_| Sim::new(scene, &options)).collect());
        for s in rest {
            sims.push(s?);
        }
        let mut batch = BatchSim {
            scenes: vec![Arc::new(scene.clone()); n],
            default_start: vec![scene.arms.iter().map(|a| a.start.clone()).collect(); n],
            options,
            sims,
            pool,
            nq,
            q: vec![0.0; n * nq],
            qd: vec![0.0; n * nq],
            effort: vec![0.0; n * nq],
            target: vec![0.0; n * nq],
            target_velocity: vec![0.0; n * nq],
            effort_command: vec![0.0; n * nq],
        };
        for c in 0..n {
            batch.read(c);
            batch.hold(c);
        }
        Ok(batch)
    }

    /// Number of copies.
    pub fn n(&self) -> usize {
        self.sims.len()
    }

    /// Joints per copy.
    pub fn nq(&self) -> usize {
        self.nq
    }

    /// Time step (s).
    pub fn dt(&self) -> f64 {
        self.sims[0].dt
    }

    /// Worker threads stepping the copies.
    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// The engine every copy runs on.
    pub fn engine(&self) -> Engine {
        self.sims[0].engine()
    }

    /// Measured joint positions (rad, m), `n x nq`, copy-major.
    pub fn q(&self) -> &[f64] {
        &self.q
    }

    /// Measured joint velocities (rad/s, m/s), `n x nq`.
    pub fn qd(&self) -> &[f64] {
        &self.qd
    }

    /// Efforts the drives applied at the last step (N·m, N), `n x nq`.
    pub fn effort(&self) -> &[f64] {
        &self.effort
    }

    /// Position targets (rad, m), `n x nq`, read at each step (clamped to the limits there).
    pub fn target_mut(&mut self) -> &mut [f64] {
        &mut self.target
    }

    /// Velocity feed-forward of the targets (rad/s, m/s), `n x nq`.
    pub fn target_velocity_mut(&mut self) -> &mut [f64] {
        &mut self.target_velocity
    }

    /// Effort commands of joints in effort mode (N·m, N), `n x nq` (clamped at the effort limits).
    pub fn effort_command_mut(&mut self) -> &mut [f64] {
        &mut self.effort_command
    }

    /// Copy `c`'s simulation (its time, poses, energy...).
    pub fn sim(&self, c: usize) -> Result<&Sim> {
        self.sims.get(c).ok_or_else(|| SimError::value("copy", c as f64, format!("the batch has {} copies", self.n())))
    }

    fn check_copy(&self, c: usize) -> Result<()> {
        self.sim(c).map(|_| ())
    }

    /// Copy `c`'s state into the flat arrays.
    fn read(&mut self, c: usize) {
        let r = c * self.nq..(c + 1) * self.nq;
        read_into(&self.sims[c], &mut self.q[r.clone()], &mut self.qd[r.clone()], &mut self.effort[r]);
    }

    /// Copy `c`'s commands: hold where it is, no effort.
    fn hold(&mut self, c: usize) {
        let r = c * self.nq..(c + 1) * self.nq;
        self.target[r.clone()].copy_from_slice(&self.q[r.clone()]);
        self.target_velocity[r.clone()].fill(0.0);
        self.effort_command[r].fill(0.0);
    }

    /// Apply the command arrays and advance every copy `k` steps, in parallel; then the state
    /// arrays hold the result. A non-finite command is refused (naming copy and joint) before any
    /// copy moves; a copy whose state stops being finite stops there and is named (the others
    /// have stepped).
    pub fn step(&mut self, k: usize) -> Result<()> {
        let nq = self.nq;
        for (name, a) in [("target", &self.target), ("target_velocity", &self.target_velocity), ("effort_command", &self.effort_command)] {
            if let Some(i) = a.iter().position(|x| !x.is_finite()) {
                return Err(SimError::value(format!("batch {name}[{}, {}]", i / nq, i % nq), a[i], "must be finite"));
            }
        }
        let (sims, q, qd, effort) = (&mut self.sims, &mut self.q, &mut self.qd, &mut self.effort);
        let (target, velocity, command) = (&self.target, &self.target_velocity, &self.effort_command);
        self.pool.install(|| {
            sims.par_iter_mut()
                .zip(q.par_chunks_mut(nq))
                .zip(qd.par_chunks_mut(nq))
                .zip(effort.par_chunks_mut(nq))
                .enumerate()
                .try_for_each(|(c, (((sim, q), qd), effort))| {
                    let r = c * nq..(c + 1) * nq;
                    for (j, ((p, v), f)) in target[r.clone()].iter().zip(&velocity[r.clone()]).zip(&command[r]).enumerate() {
                        sim.set_target(j, *p, *v)?;
                        sim.set_effort(j, *f)?;
                    }
                    for _ in 0..k {
                        sim.step();
                        // A diverged copy stops where it diverged and is named.
                        if let Err(e) = sim.check_finite() {
                            read_into(sim, q, qd, effort);
                            return Err(match e {
                                SimError::Diverged { time, message } => SimError::Diverged { time, message: format!("batch copy {c}: {message}") },
                                other => other,
                            });
                        }
                    }
                    read_into(sim, q, qd, effort);
                    Ok(())
                })
        })
    }

    /// World pose of frame `frame` (position in the arm's [`dvrk_kin::Model::frames`]) of arm
    /// `arm` in every copy, as row-major 4x4 homogeneous matrices (m) into `out` (`n x 16`):
    /// the simulated link's, on the true joints.
    pub fn frame_poses(&self, arm: usize, frame: usize, out: &mut [f64]) -> Result<()> {
        let model = &self.sims[0].arms.get(arm).ok_or_else(|| SimError::value("arm", arm as f64, format!("the scene has {} arms", self.sims[0].arms.len())))?.model;
        if frame >= model.frames.len() {
            return Err(SimError::value("frame", frame as f64, format!("arm {arm} has {} frames", model.frames.len())));
        }
        if out.len() != 16 * self.n() {
            return Err(SimError::value("frame_poses output length", out.len() as f64, format!("expected 16 x {} copies", self.n())));
        }
        // The frame's constant placement in its body, from copy 0's model (a per-copy model that
        // moves the frame within its body, a link_length there, is not followed).
        let fk = model.fk(&model.home())?;
        let rel = fk[model.bodies[model.frames[frame].body].frames[0]].inverse() * fk[frame];
        let sims = &self.sims;
        self.pool.install(|| {
            out.par_chunks_mut(16).zip(sims.par_iter()).for_each(|(o, sim)| {
                let h = sim.frame_pose(arm, frame, &rel).to_homogeneous();
                for (i, x) in o.iter_mut().enumerate() {
                    *x = h[(i / 4, i % 4)];
                }
            })
        });
        Ok(())
    }

    /// Rebuild copy `c` from its scene, at `start` (rad, m, one per scene joint: every arm's,
    /// scene order) or, without one, the scene's own start; holding it (time 0, controllers
    /// and drives at rest).
    pub fn reset(&mut self, c: usize, start: Option<&[f64]>) -> Result<()> {
        self.check_copy(c)?;
        match start {
            Some(q) => {
                if q.len() != self.nq {
                    return Err(SimError::value(format!("batch reset copy {c} start"), q.len() as f64, format!("positions given; the scene has {} joints", self.nq)));
                }
                let scene = Arc::make_mut(&mut self.scenes[c]);
                let mut off = 0;
                for a in 0..scene.arms.len() {
                    let n = scene.arms[a].model.nq();
                    scene.set_start(a, &q[off..off + n])?;
                    off += n;
                }
            }
            // (A shared scene is at its own start already: no copy of it.)
            None if self.scenes[c].arms.iter().zip(&self.default_start[c]).any(|(a, q)| a.start != *q) => {
                let scene = Arc::make_mut(&mut self.scenes[c]);
                for (arm, q) in scene.arms.iter_mut().zip(&self.default_start[c]) {
                    arm.start.clone_from(q);
                }
            }
            None => {}
        }
        self.sims[c] = Sim::new(&self.scenes[c], &self.options)?;
        self.read(c);
        self.hold(c);
        Ok(())
    }

    /// Give copy `c`'s arm `arm` another model (a payload, friction, a calibrated copy: any
    /// model file's effects; [`Scene::set_model`]) and rebuild the copy at its start.
    pub fn set_model(&mut self, c: usize, arm: usize, model: dvrk_kin::Model) -> Result<()> {
        self.check_copy(c)?;
        if arm >= self.scenes[c].arms.len() {
            return Err(SimError::value("arm", arm as f64, format!("the scene has {} arms", self.scenes[c].arms.len())));
        }
        Arc::make_mut(&mut self.scenes[c]).set_model(arm, model)?;
        self.default_start[c][arm].clone_from(&self.scenes[c].arms[arm].start);
        self.reset(c, None)
    }

    /// PID gains of copy `c`'s joint `j`.
    pub fn set_gains(&mut self, c: usize, j: usize, gains: Gains) -> Result<()> {
        self.check_copy(c)?;
        self.sims[c].set_gains(j, gains)
    }

    /// Drive mode of copy `c`'s joint `j` (effort mode reads [`BatchSim::effort_command_mut`]).
    pub fn set_mode(&mut self, c: usize, j: usize, mode: Mode) -> Result<()> {
        self.check_copy(c)?;
        self.sims[c].set_mode(j, mode)
    }
}

fn read_into(sim: &Sim, q: &mut [f64], qd: &mut [f64], effort: &mut [f64]) {
    q.copy_from_slice(sim.q());
    qd.copy_from_slice(sim.qd());
    for (j, f) in effort.iter_mut().enumerate() {
        *f = sim.effort(j).unwrap_or(f64::NAN);
    }
}
