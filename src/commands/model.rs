//! `dvrk model list|show|check`.

use super::ModelArgs;
use clap::{Args, Subcommand};
use anyhow::Result;
use dvrk_kin::expr::Affine;
use dvrk_kin::spec::Value;
use dvrk_kin::Model;

#[derive(Debug, Subcommand)]
pub enum ModelCommand {
    /// List the built-in models.
    List,
    /// Print a model's DH table, joints, bodies and closures, as the paper prints them.
    Show(ModelArgs),
    /// Closure residual, RCM, closure conditioning over the joint range, serial equivalence.
    Check(CheckArgs),
}

#[derive(Debug, Args)]
pub struct CheckArgs {
    #[command(flatten)]
    pub model: ModelArgs,
    /// Print the report as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Configurations sampled over the joint range.
    #[arg(long, default_value_t = 10_000)]
    pub samples: usize,
}

pub fn list() -> Result<()> {
    crate::outln!("{:<12} {:>6} {:>7}  title", "name", "joints", "frames");
    for name in dvrk_kin::builtin_names() {
        let m = dvrk_kin::load(name, None)?;
        crate::outln!("{:<12} {:>6} {:>7}  {}", name, m.nq(), m.frames.len(), m.title);
    }
    Ok(())
}

/// An affine map as text (`-q2 - 1.861592`), for frames without a written expression.
fn affine_text(a: &Affine, model: &Model) -> String {
    let mut s = String::new();
    for (k, c) in a.joints() {
        let name = if model.parts.is_empty() { format!("q{}", k + 1) } else { model.joints[k].name.clone() };
        let term = match c {
            1.0 => name,
            -1.0 => format!("-{name}"),
            c => format!("{c}*{name}"),
        };
        if s.is_empty() {
            s = term;
        } else if let Some(t) = term.strip_prefix('-') {
            s = format!("{s} - {t}");
        } else {
            s = format!("{s} + {term}");
        }
    }
    if a.offset != 0.0 || s.is_empty() {
        let o = format!("{:.6}", a.offset.abs());
        s = match (s.is_empty(), a.offset < 0.0) {
            (true, true) => format!("-{o}"),
            (true, false) => o,
            (false, true) => format!("{s} - {o}"),
            (false, false) => format!("{s} + {o}"),
        };
    }
    s
}

fn entry(v: Option<&Value>, a: &Affine, model: &Model) -> String {
    match v {
        Some(Value::Expr(e)) => e.clone(),
        Some(Value::Number(x)) => format!("{x}"),
        None => affine_text(a, model),
    }
}

pub fn show(args: &ModelArgs) -> Result<()> {
    let m = super::load(args)?;
    crate::outln!("{} — {}", m.name, m.title);
    if !m.spec.source.is_empty() {
        crate::outln!("source: {}", m.spec.source);
    }
    crate::outln!("convention: {:?} DH, lengths in m, angles in rad\n", m.spec.convention);
    if !m.spec.parameters.is_empty() {
        crate::outln!("parameters:");
        for (k, p) in &m.spec.parameters {
            crate::outln!("  {k:<18} = {:<22} {:<4} {}", p.value, p.unit, p.source);
        }
        crate::outln!();
    }
    crate::outln!("{:>5}  {:<22} {:<10} {:<5} {:>9} {:>9} {:>22} {:>24}  body", "frame", "name", "succ", "joint", "a[m]", "alpha", "d[m]", "theta[rad]");
    for (i, f) in m.frames.iter().enumerate() {
        let succ: Vec<String> = m.frames.iter().filter(|g| g.parent == Some(i)).map(|g| g.index.to_string()).collect();
        let spec = m.spec.frames.iter().find(|s| s.name == f.name);
        let joint = match f.variable() {
            None => "-",
            Some(_) if matches!(f.joint, dvrk_kin::FrameJoint::Prismatic) => "P",
            Some(_) => "R",
        };
        let (a, alpha) = if f.a.is_nan() {
            ("T".to_string(), "T".to_string())
        } else {
            (spec.map_or(format!("{:.4}", f.a), |s| entry(Some(&s.a), &Affine::constant(0, f.a), &m)), spec.map_or(format!("{:.4}", f.alpha), |s| entry(Some(&s.alpha), &Affine::constant(0, f.alpha), &m)))
        };
        let d = entry(spec.map(|s| &s.d), &f.d, &m);
        let theta = entry(spec.map(|s| &s.theta), &f.theta, &m);
        let (d, theta) = if f.a.is_nan() { ("T".into(), "T".into()) } else { (d, theta) };
        crate::outln!(
            "{:>5}  {:<22} {:<10} {:<5} {:>9} {:>9} {:>22} {:>24}  {}",
            f.index,
            f.name,
            if succ.is_empty() { "-".into() } else { succ.join(",") },
            joint,
            a,
            alpha,
            d,
            theta,
            m.bodies[f.body].name
        );
    }
    crate::outln!("\njoints:");
    for (k, j) in m.joints.iter().enumerate() {
        crate::outln!("  q{:<3} {:<22} {:<9} [{:>9.5}, {:>9.5}] {}  effort limit {} {}", k + 1, j.name, format!("{:?}", j.kind).to_lowercase(), j.lower, j.upper, j.unit(), j.effort_limit, j.effort_unit());
    }
    if !m.closures.is_empty() {
        crate::outln!("\nloop closures (points in m):");
        for c in &m.closures {
            let p = &c.point;
            let q = &c.partner_point;
            crate::outln!("  {:<10} frame {:>3} ({:.4}, {:.4}, {:.4})  ==  frame {:>3} ({:.4}, {:.4}, {:.4})", c.name, m.frames[c.frame].index, p.x, p.y, p.z, m.frames[c.partner].index, q.x, q.y, q.z);
        }
    }
    if let Some(r) = &m.rcm {
        crate::outln!("\nRCM: z axis of frame {} passes through ({:.6}, {:.6}, {:.6}) m", m.frames[r.frame].index, r.point.x, r.point.y, r.point.z);
    }
    if !m.spec.notes.trim().is_empty() {
        crate::outln!("\nnotes:\n{}", m.spec.notes.trim_end());
    }
    Ok(())
}

pub fn check(args: &CheckArgs) -> Result<()> {
    // The library's own check, before the model is loaded (Python's Model.check takes the same).
    dvrk_kin::check::check_samples(args.samples).map_err(|e| anyhow::anyhow!("--{e}"))?;
    let m = super::load(&args.model)?;
    let c = dvrk_kin::check::check_model(&m, args.samples)?;
    if args.json {
        crate::outln!("{}", serde_json::to_string(&c)?);
    } else {
        crate::outln!("model {}: {} frames, {} joints, {} bodies; {} configurations over the joint range", c.model, c.frames, c.joints, c.bodies, c.samples);
        if let Some(r) = c.max_closure_residual_m {
            crate::outln!("  loop-closure residual   max {:.3e} m over {} closures", r, m.closures.len());
        }
        if let (Some(p), Some(r)) = (c.rcm, c.max_pivot_residual_m) {
            crate::outln!("  RCM                     ({:.6}, {:.6}, {:.6}) m in the base frame", p[0], p[1], p[2]);
            crate::outln!("  pivot residual          max {:.3e} m (insertion axis to RCM)", r);
        }
        if let Some(k) = &c.conditioning {
            crate::outln!("  closure conditioning    sigma_min {:.4e} m/rad at home, worst {:.4e} m/rad (rank {}) at q = {:?}", k.sigma_min_home, k.sigma_min_worst, k.rank, k.worst_q);
        }
        if let Some(s) = &c.serial_equivalence {
            crate::outln!("  serial equivalence      vs {}: max {:.3e} m, {:.3e} rad (constant base transform)", s.serial_model, s.max_position_error_m, s.max_orientation_error_rad);
        }
        if c.ok {
            crate::outln!("ok");
        } else {
            for p in &c.problems {
                crate::outln!("problem: {p}");
            }
        }
    }
    if c.ok {
        Ok(())
    } else {
        Err(crate::CheckFailed.into())
    }
}
