//! Camera parameters (a scene's `[camera]` section) and the pinhole intrinsics they give.

use crate::error::{Result, SimError};
use nalgebra::Vector3;
use serde::Deserialize;

/// Largest image side accepted (px).
pub const MAX_SIDE_PX: u32 = 8192;

/// A stereo endoscope camera. Defaults are the paper's model of the dVRK endoscope (section 4.4,
/// Figure 8): 30 Hz, 800 x 800 per eye, 1.396 rad horizontal field of view, eyes 10 mm either side
/// of the axis, Gaussian image noise sigma 0.007, clip planes 0.02-300 m.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraParams {
    /// The arm whose tip frame carries the camera (`ECM`).
    pub arm: String,
    /// Frames per second of simulated time (Hz).
    #[serde(default = "d_rate")]
    pub rate_hz: f64,
    /// Image width per eye (px).
    #[serde(default = "d_side")]
    pub width: u32,
    /// Image height per eye (px).
    #[serde(default = "d_side")]
    pub height: u32,
    /// Horizontal field of view (rad), in (0, pi).
    #[serde(default = "d_hfov")]
    pub hfov_rad: f64,
    /// Distance of each eye from the camera axis along the optical x axis (m): the stereo
    /// baseline is twice this.
    #[serde(default = "d_baseline")]
    pub baseline_m: f64,
    /// Standard deviation of the Gaussian noise added to each colour channel, as a fraction of
    /// full scale (Gazebo's convention: 0.007 is 1.8 levels of 255).
    #[serde(default = "d_noise")]
    pub noise_sigma: f64,
    /// Near clip plane (m along the optical axis).
    #[serde(default = "d_near")]
    pub clip_near_m: f64,
    /// Far clip plane (m).
    #[serde(default = "d_far")]
    pub clip_far_m: f64,
    /// Seed of the image noise: the same seed gives the same images.
    #[serde(default)]
    pub seed: u64,
}

fn d_rate() -> f64 {
    30.0
}
fn d_side() -> u32 {
    800
}
fn d_hfov() -> f64 {
    1.396
}
fn d_baseline() -> f64 {
    0.01
}
fn d_noise() -> f64 {
    0.007
}
fn d_near() -> f64 {
    0.02
}
fn d_far() -> f64 {
    300.0
}

impl CameraParams {
    /// The paper's camera on arm `arm`.
    pub fn paper(arm: &str) -> CameraParams {
        CameraParams {
            arm: arm.into(),
            rate_hz: d_rate(),
            width: d_side(),
            height: d_side(),
            hfov_rad: d_hfov(),
            baseline_m: d_baseline(),
            noise_sigma: d_noise(),
            clip_near_m: d_near(),
            clip_far_m: d_far(),
            seed: 0,
        }
    }

    /// Reject parameters no camera can have; `file` names the scene in the error, each field as
    /// `camera.<name>`.
    pub fn check(&self, file: &str) -> Result<()> {
        let err = |f: &str, m: String| Err(SimError::field(file, format!("camera.{f}"), m));
        for (f, v) in [("width", self.width), ("height", self.height)] {
            if v == 0 || v > MAX_SIDE_PX {
                return err(f, format!("{v} px is not in 1..={MAX_SIDE_PX}"));
            }
        }
        if !(self.hfov_rad.is_finite() && self.hfov_rad > 0.0 && self.hfov_rad < std::f64::consts::PI) {
            return err("hfov_rad", format!("{} rad is not in (0, pi): a pinhole camera sees less than a half space", self.hfov_rad));
        }
        if !(self.rate_hz.is_finite() && self.rate_hz > 0.0) {
            return err("rate_hz", format!("{} Hz is not a positive frame rate", self.rate_hz));
        }
        if !(self.baseline_m.is_finite() && self.baseline_m >= 0.0) {
            return err("baseline_m", format!("{} m is not a finite non-negative distance", self.baseline_m));
        }
        if !(self.noise_sigma.is_finite() && (0.0..=1.0).contains(&self.noise_sigma)) {
            return err("noise_sigma", format!("{} is not in [0, 1] (a fraction of full scale)", self.noise_sigma));
        }
        if !(self.clip_near_m.is_finite() && self.clip_near_m > 0.0) {
            return err("clip_near_m", format!("{} m is not a positive distance", self.clip_near_m));
        }
        if !(self.clip_far_m.is_finite() && self.clip_far_m > self.clip_near_m) {
            return err("clip_far_m", format!("{} m is not beyond clip_near_m = {} m", self.clip_far_m, self.clip_near_m));
        }
        Ok(())
    }

    /// The pinhole intrinsics of each eye.
    pub fn intrinsics(&self) -> Intrinsics {
        // Square pixels: the vertical field of view follows from the aspect ratio.
        let f = 0.5 * self.width as f64 / (0.5 * self.hfov_rad).tan();
        Intrinsics { width: self.width, height: self.height, fx: f, fy: f, cx: 0.5 * (self.width as f64 - 1.0), cy: 0.5 * (self.height as f64 - 1.0) }
    }
}

/// Pinhole intrinsics (px), ROS `CameraInfo` convention: pixel `(i, j)` (column, row) has its
/// centre at `u = i, v = j`; the optical frame has z forward, x right, y down.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    /// Focal lengths (px).
    pub fx: f64,
    pub fy: f64,
    /// Principal point (px).
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    /// Pixel coordinates `(u, v)` of a point in the optical frame (m), if it is in front.
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        (p.z > 0.0).then(|| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }

    /// The 3x3 camera matrix, row-major.
    pub fn k(&self) -> [f64; 9] {
        [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]
    }
}
