//! The stereo camera sensor: two eyes on an arm's tip frame, rendered at the camera's own rate
//! inside the simulation loop.
//!
//! Camera frame: the tip frame of the carrying arm (the ECM's `endoscope` frame), used as the
//! optical frame of ROS and Foxglove: z forward along the endoscope (out of its tip), x right,
//! y down in the image. The left eye sits at `-baseline_m` along x, the right eye at `+baseline_m`;
//! both look along z (parallel stereo, rectified by construction).

use super::image::{EyeImage, Noise};
use super::params::{CameraParams, Intrinsics};
use super::raster::{BodyMesh, Marker, Renderer};
use crate::error::{Result, SimError};
use crate::geometry::{tessellate, ArmGeometry, ARM_COLORS, SETUP_COLOR};
use crate::sim::Sim;
use dvrk_kin::Pose;
use nalgebra::{Translation3, Vector3};

/// Which eye.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Eye {
    Left,
    Right,
}

impl Eye {
    /// `left` or `right` (topic and file names).
    pub fn name(self) -> &'static str {
        match self {
            Eye::Left => "left",
            Eye::Right => "right",
        }
    }
}


/// A stereo camera on an arm of a running [`Sim`].
#[derive(Debug, Clone)]
pub struct StereoCamera {
    pub params: CameraParams,
    pub intrinsics: Intrinsics,
    /// The carrying arm, the body of its tip frame and the tip frame's placement in that body.
    arm: usize,
    tip_body: usize,
    tip_rel: Pose,
    /// One renderer (scratch buffers) and one noise stream per eye, so the eyes can render on
    /// two threads with the same result.
    renderers: [Renderer; 2],
    noise: [Noise; 2],
    pub left: EyeImage,
    pub right: EyeImage,
    /// Render the two eyes on two threads (rayon).
    pub parallel: bool,
    /// Drawn over both eyes (tool-tip marks).
    pub markers: Vec<Marker>,
    /// Frames captured so far.
    pub frames: u64,
    /// Simulated time of the last frame (s).
    pub time: f64,
    /// Wall time spent rendering (s).
    pub render_seconds: f64,
}

impl StereoCamera {
    /// A camera on `sim`'s arm `params.arm` (checked here; `file` names the scene in errors).
    pub fn new(params: &CameraParams, sim: &Sim, file: &str) -> Result<StereoCamera> {
        params.check(file)?;
        let Some(arm) = sim.arms.iter().position(|a| a.name == params.arm) else {
            let valid: Vec<&str> = sim.arms.iter().map(|a| a.name.as_str()).collect();
            return Err(SimError::field(file, "camera.arm", format!("`{}` is not an arm of the scene (valid: {})", params.arm, valid.join(", "))));
        };
        let m = &sim.arms[arm].model;
        let fk = m.fk(&m.home())?;
        let tip_body = m.frames[m.tip].body;
        let tip_rel = fk[m.bodies[tip_body].frames[0]].inverse() * fk[m.tip];
        let mut meshes = Vec::new();
        let mut colored = 0;
        for (a, state) in sim.arms.iter().enumerate() {
            let g = ArmGeometry::new(&state.model)?;
            let has_rcm = state.model.rcm.is_some();
            let base = if has_rcm && a != arm {
                colored += 1;
                ARM_COLORS[(colored - 1) % ARM_COLORS.len()]
            } else {
                SETUP_COLOR
            };
            for (b, solids) in g.bodies.iter().enumerate() {
                let mut mesh = BodyMesh { arm: a, body: b, vertices: Vec::new(), triangles: Vec::new(), colors: Vec::new() };
                for s in solids {
                    let (v, t) = tessellate(s);
                    let color = s.part.color(base);
                    let off = mesh.vertices.len() as u32;
                    mesh.vertices.extend(v);
                    mesh.colors.extend(std::iter::repeat_n(color, t.len()));
                    mesh.triangles.extend(t.iter().map(|t| t.map(|i| i + off)));
                }
                if !mesh.triangles.is_empty() {
                    meshes.push(mesh);
                }
            }
        }
        let (w, h) = (params.width, params.height);
        Ok(StereoCamera {
            params: params.clone(),
            intrinsics: params.intrinsics(),
            arm,
            tip_body,
            tip_rel,
            renderers: [Renderer::new(meshes.clone()), Renderer::new(meshes)],
            left: EyeImage::new(w, h),
            right: EyeImage::new(w, h),
            markers: Vec::new(),
            // The right eye's stream from another seed (golden-ratio offset).
            noise: [Noise::new(params.noise_sigma, params.seed), Noise::new(params.noise_sigma, params.seed ^ 0x9e37_79b9_7f4a_7c15)],
            parallel: false,
            frames: 0,
            time: f64::NEG_INFINITY,
            render_seconds: 0.0,
        })
    }

    /// World pose of the camera frame (the carrying arm's tip frame) in `sim` now.
    pub fn camera_pose(&self, sim: &Sim) -> Pose {
        sim.body_pose(self.arm, self.tip_body) * self.tip_rel
    }

    /// Placement of an eye's optical frame in the camera frame (m).
    pub fn eye_offset(&self, eye: Eye) -> Pose {
        let x = match eye {
            Eye::Left => -self.params.baseline_m,
            Eye::Right => self.params.baseline_m,
        };
        Pose::from_parts(Translation3::new(x, 0.0, 0.0), nalgebra::Rotation3::identity())
    }

    /// World pose of an eye's optical frame.
    pub fn eye_pose(&self, sim: &Sim, eye: Eye) -> Pose {
        self.camera_pose(sim) * self.eye_offset(eye)
    }

    /// Pixel `(u, v)` of world point `p` (m) in `eye`, if in front of it (the analytic pinhole).
    pub fn project(&self, sim: &Sim, eye: Eye, p: &Vector3<f64>) -> Option<(f64, f64)> {
        let q = self.eye_pose(sim, eye).inverse() * nalgebra::Point3::from(*p);
        self.intrinsics.project(&q.coords)
    }

    /// Render a frame if the camera is due at `sim.time` (its own rate, `1 / rate_hz`, on the
    /// simulation's clock; the first frame at the first call). True when a frame was rendered.
    pub fn after_step(&mut self, sim: &Sim) -> bool {
        let period = 1.0 / self.params.rate_hz;
        // Half a step of slack: frames land on the step nearest each multiple of the period.
        if self.frames > 0 && sim.time + 0.5 * sim.dt < self.frames as f64 * period {
            return false;
        }
        self.capture(sim);
        true
    }

    /// Render both eyes now (colour with noise, depth).
    pub fn capture(&mut self, sim: &Sim) {
        let start = std::time::Instant::now();
        let clip = (self.params.clip_near_m, self.params.clip_far_m);
        let pose = |a: usize, b: usize| sim.body_pose(a, b);
        let (l, r) = (self.eye_pose(sim, Eye::Left), self.eye_pose(sim, Eye::Right));
        let k = self.intrinsics;
        let markers = &self.markers;
        let [rl, rr] = &mut self.renderers;
        let [nl, nr] = &mut self.noise;
        let (left, right) = (&mut self.left, &mut self.right);
        let mut left_eye = || {
            rl.render(pose, &l, &k, clip, markers, left);
            left.add_noise(nl);
        };
        let mut right_eye = || {
            rr.render(pose, &r, &k, clip, markers, right);
            right.add_noise(nr);
        };
        if self.parallel {
            rayon::join(left_eye, right_eye);
        } else {
            left_eye();
            right_eye();
        }
        self.frames += 1;
        self.time = sim.time;
        self.render_seconds += start.elapsed().as_secs_f64();
    }

    /// The image of `eye`.
    pub fn image(&self, eye: Eye) -> &EyeImage {
        match eye {
            Eye::Left => &self.left,
            Eye::Right => &self.right,
        }
    }
}
