//! `dvrk gc`: gravity compensation from a model (dvrk-calib's gravity module): the efforts that
//! hold the arm still at a configuration, and, with a recording, how they compare with its
//! efforts where it moves slowest.

use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct GcArgs {
    /// Model (built-in name or file): an identified one (`dvrk identify -o`) carries its own
    /// inertials and effects; `mtmr-wpi` is the MTMR identified on the WPI recordings.
    #[arg(long, default_value = "mtmr-wpi")]
    pub model: String,
    /// Joint positions (rad, m), comma-separated: print the holding torque there (home when absent).
    #[arg(long, allow_hyphen_values = true)]
    pub q: Option<String>,
    /// A joint recording with efforts: compare the holding torque with its efforts at its
    /// slowest samples, per recorded channel.
    #[arg(long)]
    pub recording: Option<PathBuf>,
    /// Recording format (as `dvrk identify`'s: auto, wpi-csv, mcap, bag).
    #[arg(long, default_value = "auto")]
    pub format: String,
    /// Arm whose /<ARM>/measured_js an MCAP or bag recording carries.
    #[arg(long, default_value = "MTMR")]
    pub arm: String,
    /// The fraction of the recording's samples, slowest first, compared.
    #[arg(long, default_value_t = 0.02)]
    pub slowest: f64,
    /// Gravity in the model's base frame (m/s^2), `x,y,z`.
    #[arg(long, default_value = "0,0,-9.81", allow_hyphen_values = true)]
    pub gravity: String,
    /// Also write the holding torque as the dVRK console's MTM gravity-compensation file
    /// (gc-MTMR.json, version 2.0: the console's own regressor, fitted to the model's holding
    /// torque over poses through its joint limits; the fit's residual is printed).
    #[arg(long)]
    pub console_file: Option<PathBuf>,
    /// Poses the console file is fitted over.
    #[arg(long, default_value_t = 2000)]
    pub poses: usize,
    /// The arm's name in the console file (ARM_NAME); MTMR or MTML from the model's name when absent.
    #[arg(long)]
    pub arm_name: Option<String>,
    /// Print the result as one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub fn run(args: &GcArgs) -> Result<()> {
    let mut inputs: Vec<(&str, &std::path::Path)> = vec![("--model", std::path::Path::new(&args.model))];
    inputs.extend(args.recording.as_deref().map(|p| ("--recording", p)));
    crate::io::check_outputs(&inputs, &[("--console-file", args.console_file.as_deref())])?;
    let gravity = crate::io::parse_gravity(&args.gravity)?;
    let model = dvrk_kin::load(&args.model, None).with_context(|| format!("--model {}", args.model))?;
    // An identified model file carries its inertials; a built-in one has them in models/inertials.
    let inertials = dvrk_sim::scene::builtin_inertials(&model.name, &model).map(|i| i.with_model(&model));
    let inertias = match inertials {
        Ok(i) => i.body_inertias(&model)?,
        Err(e) => bail!("--model {}: no inertials ({e}); identify it first (`dvrk identify -o`)", args.model),
    };
    let q = match &args.q {
        Some(text) => {
            let q = crate::io::parse_list("--q", text)?;
            if q.len() != model.nq() {
                bail!("--q {text}: {} values for model {}'s {} joints", q.len(), model.name, model.nq());
            }
            // A pose past the limits is evaluated as given (the console's fit samples past them),
            // and said.
            if let Err(e) = model.check_q(&q) {
                eprintln!("note: --q: {e}: evaluated as given");
            }
            q
        }
        None => model.home().to_vec(),
    };
    let tau = dvrk_calib::gravity::torque(&model, inertias.clone(), &q, &gravity).with_context(|| format!("--q {:?}", q))?;
    let console = match &args.console_file {
        Some(path) => {
            let arm = match &args.arm_name {
                Some(a) => a.clone(),
                None if model.name.to_ascii_lowercase().starts_with("mtml") => "MTML".into(),
                None => "MTMR".into(),
            };
            let source = format!("dvrk-twin {} `dvrk gc --model {}`: the model's holding torque, fitted", env!("CARGO_PKG_VERSION"), args.model);
            let file = dvrk_calib::gravity::console_file::fit(&model, inertias.clone(), &gravity, args.poses, &arm, &source).map_err(|e| anyhow::anyhow!("--console-file {}: {e}", path.display()))?;
            let mut text = serde_json::to_string_pretty(&file)?;
            text.push('\n');
            Some((path, file, crate::io::stage(path, text.as_bytes()).with_context(|| format!("--console-file {}", path.display()))?))
        }
        None => None,
    };
    let check = match &args.recording {
        Some(path) => {
            let (rec, notes) = dvrk_sim::recording::read_joint_log_parts(path, &args.format, &model, &args.arm, dvrk_sim::recording::Parts::Measured)
                .with_context(|| format!("--recording {}", path.display()))?;
            for n in notes.iter().filter(|_| !args.json) {
                eprintln!("note: {n}");
            }
            Some(dvrk_calib::gravity::check_slow_samples(&model, inertias, &rec, &gravity, args.slowest).with_context(|| format!("--recording {}", path.display()))?)
        }
        None => None,
    };
    let console = match console {
        Some((path, file, staged)) => {
            dvrk_kin::atomic::commit_all(vec![staged])?;
            Some((path, file.fit))
        }
        None => None,
    };
    if args.json {
        let joints: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
        let fit = console.as_ref().map(|(p, f)| serde_json::json!({ "file": p.display().to_string(), "fit": f }));
        println!("{}", serde_json::json!({ "model": model.name, "q": q, "joints": joints, "holding_torque": tau, "slowest_samples": check, "console_file": fit }));
        return Ok(());
    }
    println!("holding torque of {} at q = {q:?} (gravity {:?} m/s^2):", model.name, [gravity.x, gravity.y, gravity.z]);
    for (j, t) in model.joints.iter().zip(&tau) {
        println!("  {:<20} {t:>10.4} {}", j.name, if j.kind == dvrk_kin::JointType::Prismatic { "N" } else { "N·m" });
    }
    if let Some((p, f)) = &console {
        println!("wrote {} (the console's regressor fitted over {} poses; residual per joint, N·m):", p.display(), f.poses);
        println!("  {:<20} {:>12} {:>12} {:>12}", "joint", "torque rms", "residual rms", "residual max");
        for (j, jt) in model.joints.iter().enumerate() {
            println!("  {:<20} {:>12.5} {:>12.2e} {:>12.2e}", jt.name, f.torque_rms[j], f.residual_rms[j], f.residual_max[j]);
        }
    }
    if let Some(c) = check {
        println!("against the recording's {} slowest samples (every channel within {:.2}x its RMS velocity):", c.samples, c.speed_ratio);
        println!("  {:<28} {:>12} {:>12} {:>10}", "channel", "measured rms", "error rms", "relative");
        for (i, name) in c.channels.iter().enumerate() {
            println!("  {name:<28} {:>12.4} {:>12.4} {:>10.3}", c.measured_rms[i], c.error_rms[i], c.relative_error[i]);
        }
    }
    Ok(())
}
