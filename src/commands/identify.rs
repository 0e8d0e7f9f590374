//! `dvrk identify`: inertial parameters and effects of a model from a joint recording with
//! efforts (dvrk-calib's identify module), a JSON or text summary, a model-update file.

use anyhow::{bail, Context, Result};
use clap::Args;
use dvrk_calib::identify::{output, report, IdentifyOptions};
use dvrk_calib::identify::read_log;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// Joint recording with efforts.
    #[arg(long)]
    pub recording: PathBuf,
    /// Recording format: auto (told from the file), wpi-csv (WPI-AIM
    /// dvrk_dynamics_identification: q, qd, tau of 7 joints at 200 Hz, tool channels 5..7 in
    /// actuator space), mcap or bag (sensor_msgs/JointState with efforts on /<ARM>/measured_js
    /// and the jaw on /<ARM>/jaw/measured_js, as the dVRK records, or all joints on one topic;
    /// joint space).
    #[arg(long, default_value = "auto")]
    pub format: String,
    /// Arm whose /<ARM>/measured_js an MCAP recording carries.
    #[arg(long, default_value = "PSM1")]
    pub arm: String,
    /// Model (built-in name or file); its CAD inertials are the prior.
    #[arg(long, default_value = "psm")]
    pub model: String,
    /// Inertials file of the prior (models/inertials format); the built-in ones of --model when absent.
    #[arg(long)]
    pub inertials: Option<PathBuf>,
    /// Write the identified model here: the model file with every body's identified inertial
    /// (`[[inertials]]`) and the identified effects (`[[effects]]`); `dvrk sim --model ARM=FILE`
    /// and `--model FILE` load it. Terms no per-joint effect expresses are listed in its notes.
    #[arg(short = 'o', long)]
    pub output: Option<PathBuf>,
    /// A second recording the fit never sees: its relative errors go under `validation`.
    #[arg(long)]
    pub validate: Option<PathBuf>,
    /// Zero-phase low-pass cut-off (Hz) for velocities (then differentiated) and efforts, on
    /// every channel (default: the model's per-channel cut-offs, 10 Hz; PSM insertion and roll 20 Hz).
    #[arg(long)]
    pub cutoff: Option<f64>,
    /// Gravity in the model's base frame (m/s^2), `x,y,z`.
    #[arg(long, default_value = "0,0,-9.81", allow_hyphen_values = true)]
    pub gravity: String,
    /// Draw, per channel, the measured efforts against the identified model's prediction on the
    /// validation recording (the fitted one without --validate), as PNG or SVG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// A joint's cable torque measured on its own (the WPI MTM platform's joint test,
    /// `joint_test_cable.csv`: position, unused, effort; two slow sweeps): its cubic fit is the
    /// prior of that joint's `cable_spring` (--cable-joint).
    #[arg(long)]
    pub cable_test: Option<PathBuf>,
    /// The joint --cable-test sweeps.
    #[arg(long, default_value = "wrist_platform")]
    pub cable_joint: String,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Skip the ablation (the identification again for each cumulative step of the options:
    /// most of the time: 12 of 14 s on the WPI PSM); the summary then has no `ablation`.
    #[arg(long)]
    pub no_ablation: bool,
}

pub fn run(args: &IdentifyArgs) -> Result<()> {
    let mut inputs = vec![("--recording", args.recording.as_path()), ("--model", std::path::Path::new(&args.model))];
    inputs.extend(args.validate.as_deref().map(|v| ("--validate", v)));
    inputs.extend(args.inertials.as_deref().map(|v| ("--inertials", v)));
    inputs.extend(args.cable_test.as_deref().map(|v| ("--cable-test", v)));
    crate::io::check_outputs(&inputs, &[("-o", args.output.as_deref()), ("--plot", args.plot.as_deref())])?;
    crate::io::check_plot(args.plot.as_deref())?;
    let gravity = crate::io::parse_gravity(&args.gravity)?;
    // The recording's format (read from its first bytes when `auto`) before any model is loaded.
    let format = dvrk_sim::recording::resolve_format(&args.recording, &args.format).with_context(|| format!("--recording {}", args.recording.display()))?;
    let model = dvrk_kin::load(&args.model, None).with_context(|| format!("--model {}", args.model))?;
    let prior = match &args.inertials {
        Some(p) => {
            let text = dvrk_kin::load::read_text(p).with_context(|| format!("--inertials {}", p.display()))?;
            dvrk_sim::inertials::Inertials::parse(&text, &p.display().to_string(), &model)?
        }
        // An identified model file carries its own inertials: they are the prior.
        None => dvrk_sim::scene::builtin_inertials(&model.name, &model).with_context(|| format!("--model {}: no built-in inertials; give --inertials", args.model))?.with_model(&model),
    };
    let mut options = IdentifyOptions::for_recording(&model, format);
    if let Some(c) = args.cutoff {
        options.processing.cutoff = c;
        options.processing.channel_cutoff.clear();
    }
    options.processing.gravity = gravity;
    let (rec, mut notes) = read_log(&args.recording, &args.format, &model, &args.arm)?;
    if let Some(path) = &args.cable_test {
        let joint = model.joint_id(&args.cable_joint).with_context(|| format!("--cable-joint {}", args.cable_joint))?;
        let test = dvrk_calib::identify::cable_prior::from_joint_test(path, joint).with_context(|| format!("--cable-test {}", path.display()))?;
        let [k1, k2, k3] = test.prior.value;
        notes.push(format!(
            "--cable-test {}: {} cable torque {k1:.4} q + {k2:.4} q^2 + {k3:.4} q^3 (+ {:.4}) N·m over {:.2}..{:.2} rad (misfit {:.4} N·m RMS; friction {:.4} N·m): the prior of its cable_spring",
            path.display(),
            args.cable_joint,
            test.constant,
            test.range.0,
            test.range.1,
            test.misfit_rms,
            test.friction
        ));
        if !options.terms.joint_springs.iter().any(|(j, _)| *j == joint) {
            bail!("--cable-test {}: model {}'s identification fits no cable spring on {} (its options put them on: {})", path.display(), model.name, args.cable_joint, options.terms.joint_springs.iter().map(|(j, _)| model.joints[*j].name.as_str()).collect::<Vec<_>>().join(", "));
        }
        options.joint_spring_priors.push(test.prior);
    }
    let inertias = prior.body_inertias(&model)?;
    let held_out = match &args.validate {
        Some(v) => Some(read_log(v, format, &model, &args.arm).with_context(|| format!("--validate {}", v.display()))?.0),
        None => None,
    };
    let spinner = crate::progress::Progress::spinner("", crate::progress::Progress::wanted(args.json));
    use dvrk_calib::identify::summary::{run_with, Ablation};
    let ablation = if args.no_ablation { Ablation::Skipped } else { Ablation::Rows };
    let result = run_with(&model, &inertias, &rec, held_out.as_ref(), &options, &args.recording.display().to_string(), format, ablation, &mut |stage| spinner.set_message(stage))
        .with_context(|| format!("--recording {}", args.recording.display()))?;
    spinner.finish();
    let (id, rigid, mut summary) = (&result.identification, &result.rigid, result.summary.clone());
    summary["notes"] = serde_json::json!(notes);
    for n in &notes {
        eprintln!("note: {n}");
    }
    let ablation = &result.ablation;
    let mut staged = Vec::new();
    if let Some(o) = &args.output {
        let recording = args.recording.display().to_string();
        let identified = output::identified_model(&model, id, &options.processing, &rec.joint_map(), &inertias, &recording)?;
        let text = output::output_toml(&identified, &recording)?;
        summary["not_expressed_as_effects"] = serde_json::json!(identified.not_expressed);
        staged.push(crate::io::stage(o, text.as_bytes()).with_context(|| format!("-o {}", o.display()))?);
        summary["output"] = serde_json::json!(o.display().to_string());
    }
    if let Some(p) = &args.plot {
        let (shown, source) = match (&held_out, &args.validate) {
            (Some(r), Some(v)) => (r, v),
            _ => (&rec, &args.recording),
        };
        let image = dvrk_calib::identify::plot::figure(id, &model, shown, &options, &source.display().to_string())?.encode(p)?;
        staged.push(crate::io::stage(p, &image).with_context(|| format!("--plot {}", p.display()))?);
        summary["plot"] = serde_json::json!(p.display().to_string());
    }
    // Every output staged, then all committed together.
    dvrk_kin::atomic::commit_all(staged)?;
    for w in &id.warnings {
        eprintln!("warning: {}: {}", w.name, w.message);
    }
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
        return Ok(());
    }
    println!("identified {} from {} ({} samples): {} parameters, {} determined by the data", model.name, args.recording.display(), id.samples, id.layout.len(), id.base_parameters);
    println!("{:<28} {:>10} {:>12} {:>12} {:>14}", "channel", "rel. error", "rigid only", "validation", "as published");
    let held = |key: &str, c: usize| summary.get("validation").and_then(|v| v.pointer(&format!("{key}/{c}"))).and_then(|x| x.as_f64()).map(|x| format!("{x:.3}")).unwrap_or_default();
    for (c, name) in id.channels.iter().enumerate() {
        let (v, p) = (held("/relative_error", c), held("/as_published/relative_error", c));
        println!("{name:<28} {:>10.3} {:>12.3} {v:>12} {p:>14}", id.relative_error[c], rigid.relative_error[c]);
    }
    if let Some(p) = summary.get("validation").and_then(|v| v.get("as_published")).filter(|p| !p.is_null()) {
        let (start, stop) = (p["window_s"][0].as_f64().unwrap_or(f64::NAN), p["window_s"][1].as_f64().unwrap_or(f64::NAN));
        let span = match p["period_s"].as_f64() {
            _ if p["cable_removed"].as_bool() == Some(true) => format!("their MTM notebook's first 10 s, their platform-cable torque taken out of the efforts"),
            Some(period) => format!("the excitation's first period, {period} s"),
            None => "no period found: the whole trimmed recording".to_string(),
        };
        println!(
            "as published: against the efforts low-passed at {:.2} Hz (order {}), over {start:.2}..{stop:.2} s ({span}), as the WPI authors computed theirs",
            p["cutoff_hz"].as_f64().unwrap_or(f64::NAN),
            p["order"],
        );
    }
    println!("physically consistent: {} ({} cutting-plane rounds)", summary["physically_consistent"], id.fit.rounds);
    if !ablation.is_empty() {
        println!("ablation (cumulative; relative error per channel{}):", if held_out.is_some() { ", fitted / held-out" } else { "" });
    }
    for row in ablation {
        let fmt = |v: &[f64]| v.iter().map(|x| format!("{x:.3}")).collect::<Vec<_>>().join(" ");
        match &row.validation {
            Some(v) => println!("  {:<52} {}  /  {}", row.effects, fmt(&row.relative_error), fmt(v)),
            None => println!("  {:<52} {}", row.effects, fmt(&row.relative_error)),
        }
    }
    for e in report::effects(id).iter().filter(|e| e.name != "armature") {
        let ps: Vec<String> = e.parameters.iter().map(|(k, v)| format!("{k} {:.4}", v.as_f64().unwrap_or(f64::NAN))).collect();
        println!("  {} {}: {}", e.name, e.joint, ps.join(", "));
    }
    for o in args.output.iter().chain(&args.plot) {
        println!("wrote {}", o.display());
    }
    Ok(())
}
