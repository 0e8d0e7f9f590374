//! Scene files (`models/scenes/*.toml`): which arms, where, with which inertials, gains, armature
//! and damping, and the solver settings. Built-in scenes are compiled in, so `dvrk sim` works on a
//! fresh machine; a path loads a scene from disk.

use crate::camera::CameraParams;
use crate::control::{Gains, Mode};
use crate::error::{Result, SimError};
use crate::inertials::Inertials;
use dvrk_kin::compose::{serial_base_transform, Attach};
use dvrk_kin::{pose_from_rows, FrameRef, Model, Pose};
use serde::Deserialize;

/// Built-in scenes: (name, file text).
const BUILTIN_SCENES: &[(&str, &str)] = &[
    ("psm", include_str!("../../../models/scenes/psm.toml")),
    ("ecm", include_str!("../../../models/scenes/ecm.toml")),
    ("2psm-ecm", include_str!("../../../models/scenes/2psm-ecm.toml")),
    ("3psm", include_str!("../../../models/scenes/3psm.toml")),
    ("full", include_str!("../../../models/scenes/full.toml")),
    ("full-camera", include_str!("../../../models/scenes/full-camera.toml")),
    ("mtm", include_str!("../../../models/scenes/mtm.toml")),
];

/// Built-in inertials: (name, file text).
const BUILTIN_INERTIALS: &[(&str, &str)] = &[
    ("psm", include_str!("../../../models/inertials/psm.toml")),
    ("ecm", include_str!("../../../models/inertials/ecm.toml")),
    ("suj-psm1", include_str!("../../../models/inertials/suj-psm1.toml")),
    ("suj-psm2", include_str!("../../../models/inertials/suj-psm2.toml")),
    ("suj-psm3", include_str!("../../../models/inertials/suj-psm3.toml")),
    ("suj-ecm", include_str!("../../../models/inertials/suj-ecm.toml")),
    ("mtmr", include_str!("../../../models/inertials/mtmr.toml")),
    ("mtml", include_str!("../../../models/inertials/mtml.toml")),
];

/// The built-in inertials `name` (`psm`, `ecm`, `suj-psm1`, ...) checked against `model`.
pub fn builtin_inertials(name: &str, model: &Model) -> Result<Inertials> {
    let (n, text) = BUILTIN_INERTIALS.iter().find(|(n, _)| *n == name).ok_or_else(|| {
        let valid: Vec<&str> = BUILTIN_INERTIALS.iter().map(|(n, _)| *n).collect();
        SimError::field(name, "inertials", format!("no built-in inertials `{name}` (built-in: {})", valid.join(", ")))
    })?;
    Inertials::parse(text, &format!("built-in inertials {n}"), model)
}

/// A model's body inertias ([`Model::bodies`] order): its file's `[[inertials]]` where it gives
/// every body one (an identified model's), else its built-in inertials by model name (psm, ecm,
/// the setup joints); before any payload effect.
pub fn model_inertias(model: &Model) -> Result<Vec<dvrk_kin::BodyInertia>> {
    let from_file: Option<Vec<_>> = (0..model.bodies.len()).map(|b| model.file_inertia(b)).collect();
    match from_file {
        Some(v) if !v.is_empty() => Ok(v),
        _ => builtin_inertials(&model.name, model)?.body_inertias(model),
    }
}

/// Names of the built-in scenes.
pub fn builtin_scenes() -> Vec<&'static str> {
    BUILTIN_SCENES.iter().map(|(n, _)| *n).collect()
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    name: String,
    #[serde(default)]
    title: String,
    /// s
    #[serde(default = "default_dt")]
    dt: f64,
    #[serde(default = "default_iterations")]
    solver_iterations: usize,
    #[serde(default = "default_one")]
    pgs_iterations: usize,
    #[serde(default = "default_one")]
    stabilization_iterations: usize,
    #[serde(default)]
    warmstart_joints: bool,
    /// The physics engine, if the file chooses one (`rapier` or `reduced`).
    #[serde(default)]
    engine: Option<crate::options::Engine>,
    /// m/s^2, world frame
    #[serde(default = "default_gravity", deserialize_with = "dvrk_kin::exact::vec3")]
    gravity: [f64; 3],
    #[serde(default)]
    #[allow(dead_code)]
    notes: String,
    arms: Vec<ArmFile>,
    /// A stereo camera on an arm's tip.
    #[serde(default)]
    camera: Option<CameraParams>,
    /// Hold every carried arm on a fixed base where its carrier (the setup joints) puts it at
    /// the start, as the cart's brakes do ([`Scene::brake_setup_joints`]).
    #[serde(default)]
    brake_setup_joints: bool,
}

fn default_dt() -> f64 {
    0.001
}
fn default_iterations() -> usize {
    4
}
fn default_one() -> usize {
    1
}
fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ArmFile {
    name: String,
    model: String,
    inertials: String,
    #[serde(default, deserialize_with = "dvrk_kin::exact::opt_mat4")]
    mount: Option<[[f64; 4]; 4]>,
    kp: Vec<f64>,
    ki: Vec<f64>,
    kd: Vec<f64>,
    /// kg m^2 or kg, per joint
    armature: Vec<f64>,
    /// N·m s/rad or N s/m, every tree joint
    #[serde(default = "default_damping")]
    damping: f64,
    /// `"world"` or the name of an arm listed before this one, which carries this arm.
    #[serde(default = "default_parent")]
    parent: String,
    /// Frame of the parent arm the mount is relative to (paper number or name).
    parent_frame: Option<FrameRef>,
    /// Whether `mount` places frame 0 (`base`) or the serial dVRK base (`serial-base`, the RCM
    /// frame, as the dVRK's `SUJ_tip_to_tool_origin` does).
    #[serde(default)]
    attach: Attach,
    /// How the joints are driven from the start (`pid` or `position`).
    #[serde(default = "default_mode")]
    mode: Mode,
    /// What the arm does in the tracking test (`sine` or `hold`).
    #[serde(default)]
    tracking: Tracking,
    /// Add the model's gravity torque at the measured joints to the PID effort (feed-forward,
    /// as the dVRK's controllers do for the ECM): computed by dvrk-kin's Newton-Euler.
    #[serde(default)]
    gravity_compensation: bool,
    /// Gauss-Seidel sweeps per substep this arm's loops need; the rapier world of its group
    /// (the arm with its carrier and what it carries) uses the largest of its arms. The scene's
    /// `pgs_iterations` when absent.
    pgs_iterations: Option<usize>,
    /// The arm's home in this scene (rad, m per joint): where it starts and what it holds;
    /// the model's home when absent.
    #[serde(default)]
    home: Option<Vec<f64>>,
    #[serde(default)]
    #[allow(dead_code)]
    source: String,
}

fn default_parent() -> String {
    "world".into()
}
fn default_mode() -> Mode {
    Mode::Pid
}

/// What an arm does in the section 4.3 tracking test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Tracking {
    /// The paper's sines ([`crate::trajectory::Trajectory::tracking_test`]).
    #[default]
    Sine,
    /// Hold home (the setup joints, the ECM of the cart scenes).
    Hold,
}

fn default_damping() -> f64 {
    0.1
}

/// One arm of a scene, ready to build.
#[derive(Debug, Clone)]
pub struct Arm {
    pub name: String,
    /// The model, with `base` set to the arm's mount in the world.
    pub model: Model,
    /// The model file's own `base` (the mount is `model.base * original_base^-1`).
    pub original_base: Pose,
    pub inertials: Inertials,
    /// Per actuated joint.
    pub gains: Vec<Gains>,
    /// Reflected drive inertia per actuated joint (kg m^2 or kg).
    pub armature: Vec<f64>,
    /// Viscous damping of every tree joint (N·m s/rad or N s/m).
    pub damping: f64,
    /// The arm carrying this one and the frame (index into its `model.frames`) its mount is on;
    /// `None`: mounted on the world.
    pub parent: Option<(usize, usize)>,
    /// Initial actuator mode of every joint.
    pub mode: Mode,
    /// What the arm does in the tracking test.
    pub tracking: Tracking,
    /// Gauss-Seidel sweeps per substep this arm needs (`None`: the scene's).
    pub pgs_iterations: Option<usize>,
    /// PID efforts get the model's gravity torque added (feed-forward).
    pub gravity_compensation: bool,
    /// Joint positions the simulation starts from (rad, m): home unless set with
    /// [`Scene::set_start`].
    pub start: Vec<f64>,
    /// Setup joints braked ([`Scene::brake_setup_joints`]): the reduced engine holds them where
    /// they start without stepping them (rapier keeps holding them with their drives).
    pub braked: bool,
}

/// rapier solver settings of a scene (see `rapier3d::dynamics::IntegrationParameters`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct SolverSettings {
    /// Substeps per time step (`num_solver_iterations`).
    pub iterations: usize,
    /// Biased projected Gauss-Seidel sweeps per substep (`num_internal_pgs_iterations`).
    pub pgs_iterations: usize,
    /// Unbiased sweeps per substep (`num_internal_stabilization_iterations`).
    pub stabilization_iterations: usize,
    /// Warm-start impulse joints from the last step (`warmstart_joints`).
    pub warmstart_joints: bool,
}

/// A scene: arms, gravity and solver settings.
#[derive(Debug, Clone)]
pub struct Scene {
    pub name: String,
    pub title: String,
    /// Time step (s).
    pub dt: f64,
    /// The physics engine the file asks for, if any (a [`crate::SimOptions`] overrides it;
    /// the library's default is rapier, `dvrk sim`'s the reduced engine).
    pub engine: Option<crate::options::Engine>,
    pub solver: SolverSettings,
    /// m/s^2
    pub gravity: [f64; 3],
    pub arms: Vec<Arm>,
    /// The stereo camera, if the scene has one (checked: valid parameters on an arm of the scene).
    pub camera: Option<CameraParams>,
    /// The file (or built-in name) the scene came from, for errors.
    pub file: String,
    /// What loading found odd but not wrong (an inertials file labelled for another model whose
    /// bodies all match): the CLI prints them on stderr.
    pub notes: Vec<String>,
}

impl Scene {
    /// The index of arm `name`, or an error listing the scene's arms.
    pub fn arm_index(&self, name: &str) -> Result<usize> {
        self.arms.iter().position(|a| a.name == name).ok_or_else(|| {
            let names: Vec<&str> = self.arms.iter().map(|a| a.name.as_str()).collect();
            SimError::field(&self.name, "arm", format!("`{name}` is not an arm of the scene (arms: {})", names.join(", ")))
        })
    }

    /// Start arm `arm` at joint positions `q` (rad, m) instead of home: finite, one per joint,
    /// within the limits. An arm that carries others keeps home (their mounts are placed on it
    /// at home).
    pub fn set_start(&mut self, arm: usize, q: &[f64]) -> Result<()> {
        let a = &self.arms[arm];
        let what = format!("{} start configuration", a.name);
        if self.arms.iter().any(|b| b.parent.is_some_and(|(p, _)| p == arm)) {
            return Err(SimError::field(&self.name, what, "the arm carries other arms, which are mounted on it at home; it cannot start elsewhere"));
        }
        if q.len() != a.model.nq() {
            return Err(SimError::field(&self.name, what, format!("{} positions for {} joints", q.len(), a.model.nq())));
        }
        for (j, x) in a.model.joints.iter().zip(q) {
            if !(x.is_finite() && *x >= j.lower - 1e-9 && *x <= j.upper + 1e-9) {
                return Err(SimError::field(&self.name, what, format!("{} = {x} {} is outside its limits [{}, {}]", j.name, j.unit(), j.lower, j.upper)));
            }
        }
        self.arms[arm].start = q.to_vec();
        Ok(())
    }

    /// Start arm `arm` at a recorded configuration `q` (rad, m): a joint up to `slack` (a share
    /// of its range, e.g. [`RECORDED_START_SLACK`]) past a limit starts at the limit, because a
    /// real encoder reads a hair beyond it; further out is refused as [`Scene::set_start`] does.
    pub fn set_start_recorded(&mut self, arm: usize, q: &[f64], slack: f64) -> Result<()> {
        let within: Vec<f64> = self.arms[arm]
            .model
            .joints
            .iter()
            .zip(q)
            .map(|(j, &x)| {
                let s = slack * (j.upper - j.lower);
                if (j.lower - s..=j.upper + s).contains(&x) {
                    x.clamp(j.lower, j.upper)
                } else {
                    x
                }
            })
            .collect();
        self.set_start(arm, &within)
    }

    /// The largest time step (s) every arm's compliant drives allow
    /// ([`crate::effects::max_stable_dt`]); infinite when no drive is compliant.
    pub fn max_stable_dt(&self) -> f64 {
        self.arms.iter().map(|a| crate::effects::max_stable_dt(&a.model, &a.armature)).fold(f64::INFINITY, f64::min)
    }

    /// Replace arm `arm`'s model by `model` (a calibrated copy, say), keeping the arm's mount,
    /// inertials (matched to the new model's bodies by name), gains and armature. The new model
    /// must have the same joints. A model file's own `[[inertials]]` and `[drive]` (an identified
    /// model's) are taken over the arm's (its damping, a raised armature, [`IDENTIFIED_PGS_ITERATIONS`]).
    pub fn set_model(&mut self, arm: usize, mut model: Model) -> Result<()> {
        let a = &self.arms[arm];
        let what = format!("{} model", a.name);
        let names = |m: &Model| m.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>();
        if names(&model) != names(&a.model) {
            return Err(SimError::field(&self.name, what, format!("model `{}` has joints {:?}; the arm has {:?}", model.name, names(&model), names(&a.model))));
        }
        // The arm's base is mount * (the old model's own base): keep the mount.
        let mount = a.model.base * a.original_base.inverse();
        let original_base = model.base;
        model.base = mount * model.base;
        let mut new = a.clone();
        new.start = model.home();
        new.model = model;
        new.original_base = original_base;
        new.take_model_file(self.solver.pgs_iterations);
        new.inertials.check(&format!("{} inertials", new.name), &new.model)?;
        self.arms[arm] = new;
        Ok(())
    }

    /// A built-in scene by name, or a scene file by path.
    pub fn load(name_or_path: &str) -> Result<Scene> {
        if let Some((_, text)) = BUILTIN_SCENES.iter().find(|(n, _)| *n == name_or_path) {
            return Scene::parse(text, &format!("built-in scene {name_or_path}"), None);
        }
        let path = std::path::Path::new(name_or_path);
        if !path.exists() {
            return Err(SimError::field(
                name_or_path,
                "scene",
                format!("no such built-in scene or file (built-in: {})", builtin_scenes().join(", ")),
            ));
        }
        let text = dvrk_kin::load::read_text(path)?;
        Scene::parse(&text, name_or_path, path.parent())
    }

    /// Parse a scene file's text; `file` names it in errors, `dir` resolves relative inertials paths.
    pub fn parse(text: &str, file: &str, dir: Option<&std::path::Path>) -> Result<Scene> {
        let f: SceneFile = toml::from_str(text).map_err(|e| SimError::field(file, "(syntax)", dvrk_kin::spec::toml_message(&e, text)))?;
        // Below a microsecond a second of simulated time is a million steps: a typo, not a scene.
        if !(f.dt.is_finite() && (1e-6..=0.1).contains(&f.dt)) {
            return Err(SimError::field(file, "dt", format!("{} s is not in [1e-6, 0.1]", dvrk_kin::fmt_number(f.dt))));
        }
        for (name, v, min) in [
            ("solver_iterations", f.solver_iterations, 1),
            ("pgs_iterations", f.pgs_iterations, 1),
            ("stabilization_iterations", f.stabilization_iterations, 0),
        ] {
            if v < min || v > 1000 {
                return Err(SimError::field(file, name, format!("{v} is not in {min}..=1000")));
            }
        }
        if f.gravity.iter().any(|g| !g.is_finite()) {
            return Err(SimError::field(file, "gravity", format!("{:?} has a non-finite entry", f.gravity)));
        }
        if f.arms.is_empty() {
            return Err(SimError::field(file, "arms", "a scene needs at least one arm"));
        }
        let mut arms = Vec::with_capacity(f.arms.len());
        let mut notes = Vec::new();
        for (i, a) in f.arms.iter().enumerate() {
            let field = |x: &str| format!("arms[{i}] ({}).{x}", a.name);
            // A model path is relative to the scene file, like its inertials path.
            let model_path = match dir.map(|d| d.join(&a.model)) {
                Some(p) if p.is_file() => p.display().to_string(),
                _ => a.model.clone(),
            };
            let mut model = dvrk_kin::load(&model_path, None).map_err(|e| SimError::field(file, field("model"), e.to_string()))?;
            if let Some(h) = &a.home {
                if h.len() != model.nq() {
                    return Err(SimError::field(file, field("home"), format!("has {} entries, model {} has {} joints", h.len(), model.name, model.nq())));
                }
                for (j, x) in model.joints.iter_mut().zip(h) {
                    if !(x.is_finite() && *x >= j.lower && *x <= j.upper) {
                        return Err(SimError::field(file, field("home"), format!("{} = {x} {} is outside its limits [{}, {}]", j.name, j.unit(), j.lower, j.upper)));
                    }
                    j.home = *x;
                }
            }
            let mut mount = match &a.mount {
                Some(m) => pose_from_rows(m, "mount").map_err(|e| SimError::field(file, field("mount"), e.to_string()))?,
                None => Pose::identity(),
            };
            if a.attach == Attach::SerialBase {
                mount *= serial_base_transform(&model).map_err(|e| SimError::field(file, field("attach"), e.to_string()))?.inverse();
            }
            // An arm on another arm: its base sits on the parent's frame at the parent's home
            // configuration (the world pose the sim starts from).
            let parent = if a.parent == "world" {
                None
            } else {
                let Some(pi) = arms.iter().position(|p: &Arm| p.name == a.parent) else {
                    let valid: Vec<&str> = std::iter::once("world").chain(arms.iter().map(|p: &Arm| p.name.as_str())).collect();
                    return Err(SimError::field(file, field("parent"), format!("`{}` is not an arm listed before this one (valid: {})", a.parent, valid.join(", "))));
                };
                let fr = a.parent_frame.as_ref().ok_or_else(|| SimError::field(file, field("parent_frame"), "missing (needed when parent is an arm)"))?;
                let pm = &arms[pi].model;
                let f = pm.frame_id(fr).map_err(|e| SimError::field(file, field("parent_frame"), e.to_string()))?;
                let fk = pm.fk(&pm.home())?;
                mount = fk[f] * mount;
                Some((pi, f))
            };
            let original_base = model.base;
            model.base = mount * model.base;
            let inertials = match BUILTIN_INERTIALS.iter().any(|(n, _)| *n == a.inertials) {
                true => builtin_inertials(&a.inertials, &model)?,
                false => {
                    let p = dir.map(|d| d.join(&a.inertials)).unwrap_or_else(|| a.inertials.clone().into());
                    let text = dvrk_kin::load::read_text(&p)?;
                    let ine = Inertials::parse(&text, &p.display().to_string(), &model)?;
                    // The bodies and frames were checked one by one; a label for another model
                    // is said, not refused (a renamed copy of the arm's own file is legitimate).
                    if ine.model != model.name {
                        notes.push(format!("{}: model = \"{}\", but arm {} is model {}: every body matched, the label does not", p.display(), ine.model, a.name, model.name));
                    }
                    ine
                }
            };
            let n = model.nq();
            for (name, v) in [("kp", &a.kp), ("ki", &a.ki), ("kd", &a.kd), ("armature", &a.armature)] {
                if v.len() != n {
                    return Err(SimError::field(file, field(name), format!("has {} entries, model {} has {n} joints", v.len(), model.name)));
                }
                if let Some(x) = v.iter().find(|x| !x.is_finite() || **x < 0.0) {
                    return Err(SimError::field(file, field(name), format!("{x} is not a finite non-negative number")));
                }
            }
            if let Some(v) = a.pgs_iterations.filter(|v| !(1..=1000).contains(v)) {
                return Err(SimError::field(file, field("pgs_iterations"), format!("{v} is not in 1..=1000")));
            }
            if !a.damping.is_finite() || a.damping < 0.0 {
                return Err(SimError::field(file, field("damping"), format!("{} is not a finite non-negative number", a.damping)));
            }
            let gains = (0..n).map(|k| Gains { kp: a.kp[k], ki: a.ki[k], kd: a.kd[k] }).collect();
            if arms.iter().any(|p| p.name == a.name) {
                return Err(SimError::field(file, field("name"), "two arms have this name"));
            }
            let start = model.home();
            let mut arm = Arm { name: a.name.clone(), model, original_base, inertials, gains, armature: a.armature.clone(), damping: a.damping, parent, mode: a.mode, tracking: a.tracking, pgs_iterations: a.pgs_iterations, gravity_compensation: a.gravity_compensation, start, braked: false };
            arm.take_model_file(f.pgs_iterations);
            arms.push(arm);
        }
        if let Some(c) = &f.camera {
            c.check(file)?;
            if !arms.iter().any(|a| a.name == c.arm) {
                let valid: Vec<&str> = arms.iter().map(|a| a.name.as_str()).collect();
                return Err(SimError::field(file, "camera.arm", format!("`{}` is not an arm of the scene (valid: {})", c.arm, valid.join(", "))));
            }
        }
        let mut scene = Scene { name: f.name, title: f.title, dt: f.dt, engine: f.engine, camera: f.camera, file: file.to_string(), notes, solver: SolverSettings {
                iterations: f.solver_iterations,
                pgs_iterations: f.pgs_iterations,
                stabilization_iterations: f.stabilization_iterations,
                warmstart_joints: f.warmstart_joints,
            },
            gravity: f.gravity, arms };
        if f.brake_setup_joints {
            scene.brake_setup_joints();
        }
        Ok(scene)
    }

    /// Brake the setup joints: every arm carried by another is held on a fixed base where its
    /// carrier puts it at the carrier's start (a carrier always starts at home), instead of
    /// riding on the carrier's position-held joints; the carriers stay where they start (the
    /// reduced engine does not step them; rapier's drives hold them, carrying nothing). Each
    /// arm is then a small tree of its own: the real cart's braked setup joints, and cheaper to
    /// step. Returns how many arms it released (0: nothing is carried).
    pub fn brake_setup_joints(&mut self) -> usize {
        let carriers: Vec<usize> = self.arms.iter().filter_map(|a| a.parent.map(|(p, _)| p)).collect();
        for &c in &carriers {
            self.arms[c].braked = true;
        }
        for arm in self.arms.iter_mut().filter(|a| a.parent.is_some()) {
            // `model.base` is already the arm's world pose at its carrier's home.
            arm.parent = None;
        }
        carriers.len()
    }
}

/// Share of a joint's range a recording's first sample may lie past a limit and still be
/// replayed from the limit ([`Scene::set_start_recorded`]): the WPI recording `two` starts with
/// the jaw at 1.39659 rad against the model's 1.39626.
pub const RECORDED_START_SLACK: f64 = 0.01;

/// Gauss-Seidel sweeps per substep at least, for an arm whose model file brings its own
/// `[[inertials]]` (an identified model). Identified bodies can be far lighter than CAD ones
/// (WPI `one`: a few grams on a parallelogram link), and the loop closures then converge more
/// slowly. Measured on WPI `two` (torque replay, feedback 0.3): the identified yaw locks for
/// 198, 0 and 0 of 6000 samples at 16, 20 and 30 sweeps (RMS 0.040, 0.0072, 0.0072 rad), the
/// CAD yaw for 53, 3 and 0; 30 leaves a margin and costs no measurable time on one arm.
pub const IDENTIFIED_PGS_ITERATIONS: usize = 30;

impl Arm {
    /// Take over what the arm's model file brings of its own (an identified model's): its
    /// `[[inertials]]` over the arm's (matched by body name), its `[drive]` (the damping replaces
    /// the arm's; the motor inertias raise the armature and never lower it, because the scene's
    /// armature is also the explicit PID's stability floor, kd dt / armature <= 0.25, see the
    /// scene files; efforts predicted from the model take its own), and at least
    /// [`IDENTIFIED_PGS_ITERATIONS`] sweeps when it brings inertials (`scene_sweeps`: the
    /// scene's, for an arm that sets none).
    pub(crate) fn take_model_file(&mut self, scene_sweeps: usize) {
        let spec = &self.model.spec;
        self.inertials = self.inertials.with_model(&self.model);
        if let Some(d) = &spec.drive {
            self.damping = d.damping;
            for (a, m) in self.armature.iter_mut().zip(&d.armature) {
                *a = a.max(*m);
            }
        }
        if !spec.inertials.is_empty() {
            self.pgs_iterations = Some(self.pgs_iterations.unwrap_or(scene_sweeps).max(IDENTIFIED_PGS_ITERATIONS));
        }
    }
}

impl Scene {
    /// The solver settings a sim built on this scene with `options` uses.
    pub fn solver_settings(&self, options: &crate::options::SimOptions) -> SolverSettings {
        let s = self.solver;
        SolverSettings {
            iterations: options.solver_iterations.unwrap_or(s.iterations),
            pgs_iterations: options.pgs_iterations.unwrap_or(s.pgs_iterations),
            stabilization_iterations: options.stabilization_iterations.unwrap_or(s.stabilization_iterations),
            warmstart_joints: options.warmstart_joints.unwrap_or(s.warmstart_joints),
        }
    }
}
