//! `dvrk fk`: every frame at one configuration (table or JSON), or one frame over a CSV.

use clap::Args;
use std::path::PathBuf;
use anyhow::{anyhow, bail, Result};
use dvrk_kin::{compute_frame_placements, pose_to_rows, Data, Model};
use serde_json::json;

#[derive(Debug, Args)]
pub struct FkArgs {
    #[command(flatten)]
    pub model: super::ModelArgs,
    /// Joint positions, comma-separated (rad, m); the model's home when absent.
    #[arg(long, allow_hyphen_values = true)]
    pub q: Option<String>,
    /// Print every frame as JSON.
    #[arg(long)]
    pub json: bool,
    /// `--q` holds actuator positions (encoders), mapped to joints by the model's coupling.
    #[arg(long)]
    pub actuators: bool,
    /// CSV of measured configurations: a header with a column per joint, `qK` or the joint's name
    /// (`outer_yaw`, ...); other columns are ignored. Joints the output frame does not depend on
    /// (a PSM's jaw for the tool tip) may be left out: they are held at their home. Rows past the
    /// model's joint limits are evaluated as measured and counted on stderr.
    #[arg(long, requires = "output")]
    pub input: Option<PathBuf>,
    /// CSV of poses x,y,z,qx,qy,qz,qw (m) of `--frame`, one row per input row.
    #[arg(long, requires = "input")]
    pub output: Option<PathBuf>,
    /// Frame name or paper frame number for `--output` (default: the tool tip).
    #[arg(long)]
    pub frame: Option<String>,
    /// With `--input`: refuse a row outside the model's joint limits instead of counting it.
    #[arg(long, requires = "input")]
    pub strict: bool,
}

pub fn run(args: &FkArgs) -> Result<()> {
    // The flags are checked before the model is loaded.
    let batch_io = match (&args.input, &args.output) {
        (Some(input), Some(output)) => {
            if args.q.is_some() {
                bail!("--q: give either --q or --input, not both");
            }
            crate::io::check_outputs(&[("--input", input), ("MODEL", std::path::Path::new(&args.model.model))], &[("--output", Some(output))])?;
            Some((input, output))
        }
        _ => None,
    };
    // One configuration given as actuator positions: read them now.
    let actuators = match (args.actuators && batch_io.is_none(), args.q.as_deref()) {
        (false, _) => None,
        (true, None) => bail!("--actuators: give the actuator positions with --q"),
        (true, Some(text)) => Some(crate::io::parse_list("--q", text)?),
    };
    let m = super::load(&args.model)?;
    if let Some((input, output)) = batch_io {
        let frame = match &args.frame {
            Some(f) => super::frame_arg(&m, "--frame", f)?,
            None => m.tip,
        };
        return batch(&m, input, output, frame, args.strict);
    }
    let q = match actuators {
        Some(a) => {
            let q = m.joints_from_actuators(&a).map_err(|e| anyhow!("--actuators: {e}"))?;
            m.check_q(&q).map_err(|e| anyhow!("--q (as actuators): {e}"))?;
            q
        }
        None => super::q_arg(&m, "--q", args.q.as_deref())?,
    };
    let mut data = Data::new(&m);
    dvrk_kin::forward_kinematics(&m, &mut data, &q)?;
    let parent_index = |p: Option<usize>| p.map_or(0, |p| m.frames[p].index);
    if args.json {
        let frames: Vec<_> = m
            .frames
            .iter()
            .zip(&data.frames)
            .map(|(f, t)| json!({"index": f.index, "name": f.name, "parent": parent_index(f.parent), "T": pose_to_rows(t)}))
            .collect();
        let closures: Vec<_> = m
            .closures
            .iter()
            .map(|c| {
                let a = data.frames[c.frame] * nalgebra::Point3::from(c.point);
                let b = data.frames[c.partner] * nalgebra::Point3::from(c.partner_point);
                json!({
                    "name": c.name,
                    "frame": m.frames[c.frame].index,
                    "partner": m.frames[c.partner].index,
                    "point": [a.x, a.y, a.z],
                    "partner_point": [b.x, b.y, b.z],
                    "gap_m": (a - b).norm(),
                })
            })
            .collect();
        let mut out = json!({
            "model": m.name,
            "joint_names": m.joints.iter().map(|j| j.name.clone()).collect::<Vec<_>>(),
            "q": q,
            "frames": frames,
            "closures": closures,
        });
        if let Some(p) = dvrk_kin::rcm::pivot_residual(&m, &data) {
            out["pivot_residual_m"] = json!(p);
        }
        crate::outln!("{}", serde_json::to_string(&out)?);
        return Ok(());
    }
    crate::outln!("{:>5}  {:<24} {:>6}  {:>11} {:>11} {:>11}   (position in m, base frame)", "frame", "name", "parent", "x", "y", "z");
    for (f, t) in m.frames.iter().zip(&data.frames) {
        let p = t.translation.vector;
        crate::outln!("{:>5}  {:<24} {:>6}  {:>11.6} {:>11.6} {:>11.6}", f.index, f.name, parent_index(f.parent), p.x, p.y, p.z);
    }
    for c in &m.closures {
        crate::outln!("closure {:<8} gap {:.3e} m", c.name, dvrk_kin::closure_gap(c, &data).norm());
    }
    Ok(())
}

/// One frame's pose for every row of a joints CSV. A joint's column is `qK` or the joint's name;
/// a joint the frame does not depend on (the PSM's jaw for the tool tip) may be absent and is
/// held at its home. Measured rows past the model's limits are evaluated and counted (refused
/// with `strict`).
fn batch(m: &Model, input: &std::path::Path, output: &std::path::Path, frame: usize, strict: bool) -> Result<()> {
    let name = input.display().to_string();
    let dependent = format!("frame {} of model {}", m.frames[frame].name, m.name);
    let mut rows = dvrk_sim::recording::read_joint_rows(input, m, &m.frame_support(frame), &dependent)?;
    if !rows.held.is_empty() {
        eprintln!("note: {name}: frame {} does not depend on {}: held", m.frames[frame].name, rows.held.join(", "));
    }
    let mut tally = dvrk_kin::LimitTally::new(m);
    let mut data = Data::new(m);
    let mut q = m.home();
    let mut out = String::from(dvrk_sim::recording::POSE_ROWS_HEADER);
    while let Some(line) = rows.next_into(&mut q)? {
        if strict {
            m.check_q(&q).map_err(|e| anyhow!("{name}: line {line}: {e} (--strict)"))?;
        }
        tally.add(m, &q);
        compute_frame_placements(m, &mut data, &q);
        let t = &data.frames[frame];
        let p = t.translation.vector;
        let r = nalgebra::UnitQuaternion::from_rotation_matrix(&t.rotation);
        dvrk_sim::recording::push_pose_row(&mut out, [p.x, p.y, p.z], [r.i, r.j, r.k, r.w]);
    }
    dvrk_kin::atomic::write_atomic(output, out.as_bytes())?;
    if let Some(s) = tally.summary(m) {
        eprintln!("note: {name}: {s}");
    }
    Ok(())
}
