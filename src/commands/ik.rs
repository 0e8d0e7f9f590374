//! `dvrk ik`: joint positions that put the tip at a pose.

use clap::Args;
use anyhow::{anyhow, bail, Result};
use dvrk_kin::{inverse_kinematics, IkOptions, Pose};
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use serde_json::json;

#[derive(Debug, Args)]
pub struct IkArgs {
    #[command(flatten)]
    pub model: super::ModelArgs,
    /// Target pose of the tip in the model's base frame: x,y,z (m), qx,qy,qz,qw.
    #[arg(long, allow_hyphen_values = true)]
    pub pose: String,
    /// Start configuration, comma-separated (default: home).
    #[arg(long, allow_hyphen_values = true)]
    pub seed: Option<String>,
    /// Frame to place (default: the tool tip).
    #[arg(long)]
    pub frame: Option<String>,
    /// Print the solution as JSON.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &IkArgs) -> Result<()> {
    // The pose's flags are checked before the model is loaded.
    let v = crate::io::parse_list("--pose", &args.pose)?;
    if v.len() != 7 {
        bail!("--pose: expected 7 numbers x,y,z,qx,qy,qz,qw, got {}", v.len());
    }
    let quat = Quaternion::new(v[6], v[3], v[4], v[5]);
    let norm = quat.norm();
    if (norm - 1.0).abs() > 1e-3 {
        bail!("--pose: quaternion ({}, {}, {}, {}) has norm {norm:.6}, expected 1", v[3], v[4], v[5], v[6]);
    }
    let rot = UnitQuaternion::from_quaternion(quat).to_rotation_matrix();
    let target = Pose::from_parts(Translation3::new(v[0], v[1], v[2]), rot);
    let m = super::load(&args.model)?;
    let seed = super::q_arg(&m, "--seed", args.seed.as_deref())?;
    let frame = args.frame.as_deref().map(|f| super::frame_arg(&m, "--frame", f)).transpose()?;
    let opts = IkOptions { frame, ..Default::default() };
    let sol = inverse_kinematics(&m, &target, &seed, &opts).map_err(|e| anyhow!("{e}"))?;
    if args.json {
        crate::outln!(
            "{}",
            serde_json::to_string(&json!({
                "model": m.name,
                "joint_names": m.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
                "q": sol.q,
                "position_error_m": sol.position_error,
                "orientation_error_rad": sol.orientation_error,
                "iterations": sol.iterations,
            }))?
        );
    } else {
        for (j, x) in m.joints.iter().zip(&sol.q) {
            crate::outln!("{:<22} {:>12.6} {}", j.name, x, j.unit());
        }
        crate::outln!("position error {:.3e} m, orientation error {:.3e} rad", sol.position_error, sol.orientation_error);
    }
    Ok(())
}
