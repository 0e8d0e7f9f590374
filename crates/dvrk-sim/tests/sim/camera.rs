//! The stereo camera of the full-camera scene against the analytic pinhole, its parameters, noise,
//! recording and frame files; the link geometry and its colliders.

use dvrk_sim::camera::{depth_mm, CameraParams, Eye, Marker, StereoCamera};
use dvrk_sim::geometry::{ArmGeometry, Part, JAW_SIZE_M, TOOL_RADIUS_M};
use dvrk_sim::run::TrajectoryKind;
use dvrk_sim::{Colliders, Outputs, RecordOptions, RunOptions, Scene, Sim, SimOptions};
use nalgebra::{Point3, Translation3, Vector3};

const MARKER: [f32; 3] = [1.0, 0.0, 1.0];

fn full_camera() -> (Scene, Sim) {
    let scene = Scene::load("full-camera").unwrap();
    let sim = Sim::new(&scene, &SimOptions::default()).unwrap();
    (scene, sim)
}

fn arm(sim: &Sim, name: &str) -> usize {
    sim.arms.iter().position(|a| a.name == name).unwrap()
}

/// World position of an arm's tool tip by forward kinematics at the arm's home (m).
fn fk_tip(sim: &Sim, a: usize) -> Vector3<f64> {
    let m = &sim.arms[a].model;
    (m.fk(&m.home()).unwrap()[m.tip] * Point3::origin()).coords
}

/// The analytic pinhole: `p` (world, m) in an eye placed by FK of the ECM at its home, projected
/// with K built here from the parameters (not the camera's).
fn pinhole(sim: &Sim, p: &CameraParams, eye: Eye, point: &Vector3<f64>) -> (f64, f64, f64) {
    let e = &sim.arms[arm(sim, "ECM")].model;
    let x = if eye == Eye::Left { -p.baseline_m } else { p.baseline_m };
    let pose = e.fk(&e.home()).unwrap()[e.tip] * Translation3::new(x, 0.0, 0.0);
    let c = pose.inverse() * Point3::from(*point);
    let f = p.width as f64 / 2.0 / (p.hfov_rad / 2.0).tan();
    (f * c.x / c.z + (p.width as f64 - 1.0) / 2.0, f * c.y / c.z + (p.height as f64 - 1.0) / 2.0, c.z)
}

/// Centroid (column, row) of the pixels of exactly `color`, and their count.
fn centroid(img: &dvrk_sim::camera::EyeImage, color: [u8; 3]) -> (f64, f64, usize) {
    let (mut su, mut sv, mut n) = (0.0, 0.0, 0usize);
    for r in 0..img.height {
        for c in 0..img.width {
            if img.pixel(c, r) == color {
                su += c as f64;
                sv += r as f64;
                n += 1;
            }
        }
    }
    (su / n as f64, sv / n as f64, n)
}

#[test]
fn each_psm_tool_tip_is_at_its_pinhole_pixel_in_both_eyes_and_disparity_gives_its_depth() {
    let (scene, sim) = full_camera();
    let mut params = scene.camera.clone().unwrap();
    params.noise_sigma = 0.0;
    let mut cam = StereoCamera::new(&params, &sim, "full-camera").unwrap();
    // Plain render first: the depth image at each tip's pixel shows the tool at the tip.
    cam.capture(&sim);
    let mut worst_px: f64 = 0.0;
    let mut worst_depth: f64 = 0.0;
    let mut worst_gap: f64 = 0.0;
    for name in ["PSM1", "PSM2", "PSM3"] {
        let tip = fk_tip(&sim, arm(&sim, name));
        for eye in [Eye::Left, Eye::Right] {
            let (u, v, z) = pinhole(&sim, &params, eye, &tip);
            assert!((0.0..800.0).contains(&u) && (0.0..800.0).contains(&v), "{name} tip at ({u}, {v}) px is out of the {eye:?} image");
            let (pu, pv) = (u.round(), v.round());
            let d = cam.image(eye).depth_at(pu as u32, pv as u32) as f64;
            // Back-projected, the pixel's depth lands on the wrist (a ball of the tool radius at
            // the tip) or on a jaw blade in front of it: within a blade's length of the tip.
            let k = cam.intrinsics;
            let seen = Vector3::new((pu - k.cx) / k.fx * d, (pv - k.cy) / k.fy * d, d);
            let tip_eye = Vector3::new((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
            let gap = (seen - tip_eye).norm();
            println!("{name} {eye:?}: depth {d:.4} m at the tip pixel, tip at {z:.4} m: the seen point is {:.1} mm from the tip", gap * 1e3);
            assert!(gap <= JAW_SIZE_M[0] + TOOL_RADIUS_M, "{name} {eye:?}: depth {d} m at the tip pixel, tip at {z} m");
            worst_gap = worst_gap.max(gap);
        }
    }
    // Then a 1.5 mm marker sphere on each tip (drawn over the image): its pixels' centroid.
    for name in ["PSM1", "PSM2", "PSM3"] {
        let tip = fk_tip(&sim, arm(&sim, name));
        cam.markers = vec![Marker { position: tip, radius: 0.0015, color: MARKER }];
        cam.capture(&sim);
        let mut u_eye = [0.0; 2];
        let mut z_tip = 0.0;
        for (k, eye) in [Eye::Left, Eye::Right].into_iter().enumerate() {
            let (u, v, z) = pinhole(&sim, &params, eye, &tip);
            let (cu, cv, n) = centroid(cam.image(eye), [255, 0, 255]);
            assert!(n > 20, "{name} {eye:?}: only {n} marker pixels");
            let err = ((cu - u).powi(2) + (cv - v).powi(2)).sqrt();
            println!("{name} {eye:?}: rendered ({cu:.2}, {cv:.2}) px, pinhole ({u:.2}, {v:.2}) px, error {err:.3} px, z {z:.4} m");
            assert!(err < 1.0, "{name} {eye:?}: tip rendered at ({cu}, {cv}), pinhole ({u}, {v})");
            worst_px = worst_px.max(err);
            u_eye[k] = cu;
            z_tip = z;
        }
        // Parallel stereo: disparity = fx * 2 baseline / z.
        let disparity = u_eye[0] - u_eye[1];
        let z = cam.intrinsics.fx * 2.0 * params.baseline_m / disparity;
        let rel = (z - z_tip).abs() / z_tip;
        println!("{name}: disparity {disparity:.2} px -> depth {z:.4} m (FK {z_tip:.4} m, {:.3}%)", 100.0 * rel);
        assert!(rel < 0.01, "{name}: depth from disparity {z} m, FK {z_tip} m");
        worst_depth = worst_depth.max(rel);
    }
    println!("worst tip pixel error {worst_px:.3} px, worst depth-from-disparity error {:.3}%, depth image at the tip pixel within {:.1} mm of the tip", 100.0 * worst_depth, worst_gap * 1e3);
}

#[test]
fn the_camera_projection_equals_the_analytic_pinhole() {
    let (scene, sim) = full_camera();
    let p = scene.camera.clone().unwrap();
    let cam = StereoCamera::new(&p, &sim, "full-camera").unwrap();
    let k = cam.intrinsics;
    assert!((k.fx - 400.0 / (0.698f64).tan()).abs() < 1e-9, "fx = {}", k.fx);
    assert_eq!((k.cx, k.cy), (399.5, 399.5));
    for name in ["PSM1", "PSM2", "PSM3"] {
        let tip = fk_tip(&sim, arm(&sim, name));
        for eye in [Eye::Left, Eye::Right] {
            let (u, v) = cam.project(&sim, eye, &tip).unwrap();
            let (pu, pv, _) = pinhole(&sim, &p, eye, &tip);
            // The sim's bodies start exactly at the FK poses.
            assert!((u - pu).abs() < 1e-6 && (v - pv).abs() < 1e-6, "{name} {eye:?}: ({u}, {v}) vs ({pu}, {pv})");
        }
    }
}

fn camera_error(field: &str, value: &str) -> String {
    let text = Scene::load("full-camera").map(|_| include_str!("../../../../models/scenes/full-camera.toml")).unwrap();
    let line = text.lines().find(|l| l.starts_with(&format!("{field} ="))).unwrap();
    let bad = text.replacen(line, &format!("{field} = {value}"), 1);
    Scene::parse(&bad, "bad.toml", None).expect_err("rejected").to_string()
}

#[test]
fn bad_camera_parameters_are_rejected_with_the_field_and_value() {
    assert_eq!(camera_error("width", "0"), "bad.toml: camera.width: 0 px is not in 1..=8192");
    assert_eq!(camera_error("height", "0"), "bad.toml: camera.height: 0 px is not in 1..=8192");
    assert_eq!(camera_error("hfov_rad", "3.2"), "bad.toml: camera.hfov_rad: 3.2 rad is not in (0, pi): a pinhole camera sees less than a half space");
    assert_eq!(camera_error("hfov_rad", "0.0"), "bad.toml: camera.hfov_rad: 0 rad is not in (0, pi): a pinhole camera sees less than a half space");
    assert_eq!(camera_error("rate_hz", "-30.0"), "bad.toml: camera.rate_hz: -30 Hz is not a positive frame rate");
    assert_eq!(camera_error("clip_far_m", "0.01"), "bad.toml: camera.clip_far_m: 0.01 m is not beyond clip_near_m = 0.02 m");
    assert_eq!(camera_error("noise_sigma", "-0.1"), "bad.toml: camera.noise_sigma: -0.1 is not in [0, 1] (a fraction of full scale)");
    assert_eq!(camera_error("arm", "\"ECM2\""), "bad.toml: camera.arm: `ECM2` is not an arm of the scene (valid: SUJ-ECM, ECM, SUJ-PSM1, PSM1, SUJ-PSM2, PSM2, SUJ-PSM3, PSM3)");
    let e = camera_error("width", "-5");
    assert!(e.starts_with("bad.toml: (syntax): "), "{e}");
}

#[test]
fn images_are_deterministic_for_a_seed_and_the_noise_has_the_paper_sigma() {
    let (scene, sim) = full_camera();
    let p = scene.camera.clone().unwrap();
    let render = |seed: u64, sigma: f64| {
        let mut c = StereoCamera::new(&CameraParams { seed, noise_sigma: sigma, ..p.clone() }, &sim, "full-camera").unwrap();
        c.capture(&sim);
        c.capture(&sim);
        (c.left.rgb.clone(), c.right.rgb.clone())
    };
    let a = render(7, 0.007);
    assert!(a == render(7, 0.007), "same seed, same images");
    assert!(a != render(8, 0.007), "another seed, other noise");
    let clean = render(7, 0.0);
    let diffs: Vec<f64> = a.0.iter().zip(&clean.0).map(|(n, c)| *n as f64 - *c as f64).collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let sd = (diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / diffs.len() as f64).sqrt();
    println!("noise: mean {mean:.4}, sd {sd:.4} levels (expected 0.007 x 255 = 1.785)");
    assert!(mean.abs() < 0.01, "mean {mean}");
    assert!((sd - 0.007 * 255.0).abs() < 0.03 * 0.007 * 255.0, "sd {sd}");
    // The eyes see the scene from 20 mm apart.
    assert!(clean.0 != clean.1);
}

#[test]
fn a_recorded_camera_image_decodes_to_the_frame_file_and_the_calibration_matches() {
    let dir = tempfile::tempdir().unwrap();
    let scene = Scene::load("full-camera").unwrap();
    let record = RecordOptions { path: dir.path().join("run.mcap"), rate: 100.0 };
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    let options = RunOptions { duration: 0.05, trajectory: TrajectoryKind::Sine, sim: SimOptions::default() };
    let (summary, _) = dvrk_sim::run_with(&scene, &options, &Outputs { record: Some(&record), trace_rate: None, frames_dir: Some(&frames), ..Default::default() }, |_| {}).unwrap();
    let cam = summary.camera.unwrap();
    // Frames at t = 0.001 s (the first step), 1/30 s: 2 in 0.05 s.
    assert_eq!(cam.frames, 2);
    let bytes = std::fs::read(&record.path).unwrap();
    let mut images = Vec::new();
    let mut depth = Vec::new();
    let mut calibration = None;
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        match m.channel.topic.as_str() {
            "/camera/left/image" => {
                assert_eq!(m.channel.schema.as_ref().unwrap().name, "foxglove.CompressedImage");
                images.push((m.log_time, dvrk_sim::recording::camera_msgs::decode_compressed_image(&m.data).unwrap()));
            }
            "/camera/left/depth" => depth.push(dvrk_sim::recording::camera_msgs::decode_compressed_image(&m.data).unwrap()),
            "/camera/right/calibration" => {
                assert_eq!(m.channel.schema.as_ref().unwrap().encoding, "protobuf");
                calibration = Some(<foxglove::messages::CameraCalibration as foxglove::Decode>::decode(&m.data[..]).unwrap());
            }
            _ => {}
        }
    }
    assert_eq!(images.len(), 2);
    assert_eq!(images[0].0, 1_000_000, "first frame at the first step (ns)");
    let (png_bytes, format, frame) = &images[0].1;
    assert_eq!((format.as_str(), frame.as_str()), ("png", "camera_left"));
    // The recorded image is the frame file, byte for byte, and decodes to 800 x 800 RGB.
    assert_eq!(png_bytes, &std::fs::read(frames.join("left_000001.png")).unwrap());
    let mut dec = png::Decoder::new(std::io::Cursor::new(png_bytes.clone())).read_info().unwrap();
    let mut buf = vec![0; dec.output_buffer_size().unwrap()];
    let info = dec.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height, info.color_type, info.bit_depth), (800, 800, png::ColorType::Rgb, png::BitDepth::Eight));
    // Blue PSM2 pixels (b > r + 60) are there.
    assert!(buf.chunks_exact(3).filter(|p| p[2] as i32 > p[0] as i32 + 60).count() > 1000);
    let mut dec = png::Decoder::new(std::io::Cursor::new(depth[0].0.clone())).read_info().unwrap();
    let mut dbuf = vec![0; dec.output_buffer_size().unwrap()];
    let info = dec.next_frame(&mut dbuf).unwrap();
    assert_eq!((info.color_type, info.bit_depth), (png::ColorType::Grayscale, png::BitDepth::Sixteen));
    let mm: Vec<u16> = dbuf.chunks_exact(2).map(|b| u16::from_be_bytes([b[0], b[1]])).filter(|d| *d > 0).collect();
    assert!(mm.len() > 1000 && mm.iter().all(|d| (20..2000).contains(d)), "depths in mm within the scene");
    assert_eq!(depth_mm(0.1234), 123);
    let c = calibration.unwrap();
    let fx = 400.0 / (1.396f64 / 2.0).tan();
    assert!((c.k[0] - fx).abs() < 1e-9);
    assert!((c.p[3] + fx * 0.02).abs() < 1e-9, "right eye P[3] = -fx B");
    assert_eq!((c.width, c.height, c.frame_id.as_str()), (800, 800, "camera_right"));
    for name in ["left_000002.png", "right_000002.png", "left_depth_000002.png", "right_depth_000002.png"] {
        assert!(frames.join(name).is_file(), "{name}");
    }
    assert!(!frames.join("left_000003.png").exists());
}

#[test]
fn frames_dir_needs_a_scene_with_a_camera() {
    let dir = tempfile::tempdir().unwrap();
    let options = RunOptions { duration: 0.01, trajectory: TrajectoryKind::Hold, sim: SimOptions::default() };
    let e = dvrk_sim::run_with(&Scene::load("psm").unwrap(), &options, &Outputs { frames_dir: Some(dir.path()), ..Default::default() }, |_| {}).err().unwrap();
    assert_eq!(e.to_string(), format!("built-in scene psm: camera: --frames-dir {}: the scene has no camera", dir.path().display()));
}

#[test]
fn psm_solids_follow_the_kinematics() {
    let m = dvrk_sim::dvrk_kin::load("psm", None).unwrap();
    let g = ArmGeometry::new(&m).unwrap();
    let length = |s: &dvrk_sim::geometry::Solid| s.shape.as_capsule().map(|c| c.segment.length()).unwrap_or(0.0);
    // The instrument shaft: a tool capsule as long as the tool file's roll D, on the insertion body.
    let body = m.bodies.iter().position(|b| b.name == "main_insertion_link").unwrap();
    let shaft = g.bodies[body].iter().filter(|s| s.part == Part::Tool).map(length).fold(0.0, f64::max);
    assert!((shaft - m.spec.parameters["tool_length"].value).abs() < 1e-12, "shaft {shaft} m");
    // Two jaw blades, every body has a solid.
    assert_eq!(g.bodies.iter().flatten().filter(|s| s.part == Part::Jaw).count(), 2);
    assert!(g.bodies.iter().all(|b| !b.is_empty()));
}

#[test]
fn a_model_file_mesh_replaces_a_body_s_solids_and_bad_meshes_are_named() {
    let dir = tempfile::tempdir().unwrap();
    // A 20 mm cube as binary STL, in mm.
    let v = |x: f32, y: f32, z: f32| stl_io::Vector::new([x, y, z]);
    let c = [v(0., 0., 0.), v(20., 0., 0.), v(20., 20., 0.), v(0., 20., 0.), v(0., 0., 20.), v(20., 0., 20.), v(20., 20., 20.), v(0., 20., 20.)];
    let faces = [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]];
    let tris: Vec<stl_io::Triangle> = faces.iter().map(|f| stl_io::Triangle { normal: v(0., 0., 0.), vertices: [c[f[0]], c[f[1]], c[f[2]]] }).collect();
    let mut f = std::fs::File::create(dir.path().join("cube.stl")).unwrap();
    stl_io::write_stl(&mut f, tris.iter()).unwrap();
    drop(f);
    let psm = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../models/psm.toml")).unwrap();
    let write = |extra: &str| {
        let p = dir.path().join("psm-mesh.toml");
        std::fs::write(&p, format!("{psm}\n{extra}")).unwrap();
        dvrk_sim::dvrk_kin::load(p.to_str().unwrap(), None).unwrap()
    };
    let m = write("[[meshes]]\nbody = \"yaw_link\"\nfile = \"cube.stl\"\nscale = 0.001\n");
    let g = ArmGeometry::new(&m).unwrap();
    let yaw = &g.bodies[m.bodies.iter().position(|b| b.name == "yaw_link").unwrap()];
    assert_eq!(yaw.len(), 1);
    assert_eq!(yaw[0].part, Part::Mesh);
    let mesh = yaw[0].shape.as_trimesh().unwrap();
    assert_eq!(mesh.indices().len(), 12);
    let aabb = mesh.local_aabb();
    assert!(((aabb.maxs - aabb.mins).x - 0.02).abs() < 1e-9, "scaled to m");
    let m = write("[[meshes]]\nbody = \"yaw_link\"\nfile = \"missing.stl\"\n");
    let e = ArmGeometry::new(&m).unwrap_err().to_string();
    assert!(e.contains("meshes[0].file: ") && e.contains("missing.stl"), "{e}");
    let m = write("[[meshes]]\nbody = \"no_link\"\nfile = \"cube.stl\"\n");
    let e = ArmGeometry::new(&m).unwrap_err().to_string();
    assert!(e.contains("meshes[0].body: `no_link` is not a body of psm (valid: "), "{e}");
    // Issue 63: a mesh that never ends or never starts is refused at once, naming the file.
    #[cfg(unix)]
    {
        assert!(std::process::Command::new("mkfifo").arg(dir.path().join("fifo.stl")).status().unwrap().success());
        for file in ["fifo.stl", "/dev/zero"] {
            let m = write(&format!("[[meshes]]\nbody = \"yaw_link\"\nfile = \"{file}\"\n"));
            let e = ArmGeometry::new(&m).unwrap_err().to_string();
            assert!(e.contains("meshes[0].file: ") && e.contains(file.trim_start_matches('/')) && e.contains("not a regular file"), "{e}");
        }
    }
}

#[test]
fn massless_colliders_leave_the_dynamics_unchanged() {
    let scene = Scene::load("psm").unwrap();
    let run = |colliders: Colliders| {
        let mut sim = Sim::new(&scene, &SimOptions { colliders, ..Default::default() }).unwrap();
        for i in 0..sim.nq() {
            let q = sim.q()[i];
            sim.set_target(i, q + 0.05, 0.0).unwrap();
        }
        for _ in 0..200 {
            sim.step();
        }
        sim.q().to_vec()
    };
    // rapier re-sums the (zero) collider mass into each body: the same dynamics up to rounding.
    let off = run(Colliders::Off);
    for c in [Colliders::NoContacts, Colliders::Contacts] {
        let q = run(c);
        let worst = off.iter().zip(&q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-10, "{c:?}: joints differ by {worst}");
    }
}

/// 1 s of the tracking test with the camera: 31 frames (t = 0.001 s, then every 1/30 s), loops
/// closed, and the ECM near the aimed home the scene gives it. The ECM is PID-held as in full.toml
/// (ecm.toml's gains, no gravity feed-forward): it sags while the integrators build up, 1.3e-2 rad
/// of yaw and 2.6 cm of insertion at most over a 10 s run (its error in the full scene at home:
/// 3.4e-2 rad of pitch, 2.0 cm of insertion).
#[test]
fn full_camera_runs_one_second_with_the_ecm_holding_its_aim() {
    let scene = Scene::load("full-camera").unwrap();
    let ecm = scene.arms.iter().find(|a| a.name == "ECM").unwrap();
    assert_eq!(ecm.model.home(), vec![0.3672, -0.5025, 0.0073, 0.9]);
    let options = RunOptions { duration: 1.0, trajectory: TrajectoryKind::Sine, sim: SimOptions::default() };
    let (s, _) = dvrk_sim::run_with(&scene, &options, &Outputs::default(), |_| {}).unwrap();
    assert!(s.finite);
    assert!(s.max_closure_error < 1e-5, "gap {} m", s.max_closure_error);
    let cam = s.camera.unwrap();
    assert_eq!(cam.frames, 31);
    println!("1 s: RTF {:.2}, camera {:.1} ms per stereo frame", s.real_time_factor, cam.time_per_frame * 1e3);
    for j in s.joints.iter().filter(|j| j.arm == "ECM") {
        println!("ECM {}: max error {:.2e} {}", j.joint, j.max_error, j.unit);
        let bound = if j.unit == "m" { 0.03 } else { 0.015 };
        assert!(j.max_error < bound, "ECM {} drifts {} {} from its aim", j.joint, j.max_error, j.unit);
    }
}

/// Every built-in model (the MTMs' standard DH, the composed cart) gets a solid on every body,
/// each a finite shape placed in its body.
#[test]
fn every_builtin_model_has_link_geometry() {
    for name in dvrk_sim::dvrk_kin::builtin_names() {
        let m = dvrk_sim::dvrk_kin::load(name, None).unwrap();
        let g = ArmGeometry::new(&m).unwrap();
        assert_eq!(g.bodies.len(), m.bodies.len(), "{name}");
        for (b, solids) in g.bodies.iter().enumerate() {
            assert!(!solids.is_empty(), "{name}: body {} has no solid", m.bodies[b].name);
            for s in solids {
                let (v, t) = dvrk_sim::geometry::tessellate(s);
                assert!(!t.is_empty() && v.iter().all(|p| p.iter().all(|x| x.is_finite()) && p.norm() < 2.0), "{name}: {s:?}");
            }
        }
    }
}
