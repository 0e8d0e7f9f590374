//! `dvrk sim --plot`: the Figure-10-like tracking PNG of a run.

use dvrk_sim::plot::{BLUE, GREEN, ORANGE};
use dvrk_sim::run::{run_traced, TrajectoryKind};
use dvrk_sim::{RunOptions, Scene, SimOptions};

#[test]
fn a_psm_run_plots_commanded_measured_and_error_per_joint() {
    let scene = Scene::load("psm").unwrap();
    let options = RunOptions { duration: 2.0, trajectory: TrajectoryKind::Sine, sim: SimOptions::default() };
    let (summary, trace) = run_traced(&scene, &options, None, Some(50.0), |_| {}).unwrap();
    let trace = trace.unwrap();
    assert!(summary.finite);
    // One row per PSM joint, sampled at 50 Hz over 2 s (plus the last step).
    let n = summary.joints.len();
    assert_eq!(trace.joints.len(), n);
    assert!((100..=102).contains(&trace.t.len()), "{} samples", trace.t.len());
    for j in &trace.joints {
        assert_eq!(j.commanded.len(), trace.t.len());
        assert_eq!(j.measured.len(), trace.t.len());
        assert!(j.unit == "rad" || j.unit == "m");
    }

    let fig = trace.figure("psm sine");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tracking.png");
    let bytes = fig.encode(&path).unwrap();
    std::fs::write(&path, &bytes).unwrap();
    let png = std::fs::read(&path).unwrap();
    assert_eq!(&png[..8], &[0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a]);
    assert_eq!(&png[12..16], b"IHDR");
    let (w, h) = (u32::from_be_bytes(png[16..20].try_into().unwrap()), u32::from_be_bytes(png[20..24].try_into().unwrap()));
    // Two 480 x 200 panels per joint row under a 20 px title band.
    assert_eq!((w, h), (960, 20 + 200 * n as u32));
    assert_eq!(&png[png.len() - 8..png.len() - 4], b"IEND");

    let (pw, ph, px) = fig.pixels();
    assert_eq!((pw, ph), (w as usize, h as usize));
    let count = |c: [u8; 3]| px.chunks(3).filter(|p| *p == c).count();
    assert!(count(BLUE) > 100, "commanded colour drawn");
    assert!(count(ORANGE) > 100, "measured colour drawn");
    assert!(count(GREEN) > 100, "error colour drawn");
    assert!(count([0, 0, 0]) > 1000, "axes and labels drawn");

    // The SVG: each series a polyline in its colour per joint (and its legend entry's), axis
    // labels with units, the legend's names.
    let svg = fig.svg();
    let stroked = |c: [u8; 3]| svg.matches(&format!("<polyline fill=\"none\" opacity=\"1\" stroke=\"#{:02X}{:02X}{:02X}\"", c[0], c[1], c[2])).count();
    for c in [BLUE, ORANGE, GREEN] {
        assert_eq!(stroked(c), 2 * n, "{c:?}");
    }
    for text in ["time (s)", "position (rad)", "error (m)", "commanded", "measured - commanded"] {
        assert!(svg.contains(text), "{text}");
    }
}

#[test]
fn an_unknown_plot_format_is_refused() {
    let scene = Scene::load("psm").unwrap();
    let options = RunOptions { duration: 0.1, trajectory: TrajectoryKind::Hold, sim: SimOptions::default() };
    let (_, trace) = run_traced(&scene, &options, None, Some(50.0), |_| {}).unwrap();
    let fig = trace.unwrap().figure("hold");
    assert!(fig.encode(std::path::Path::new("x.jpg")).is_err());
    assert!(run_traced(&scene, &options, None, Some(0.0), |_| {}).is_err());
}
