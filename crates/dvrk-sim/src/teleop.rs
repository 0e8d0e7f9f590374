//! MTM -> PSM follow mode with the dVRK console's semantics (sawIntuitiveResearchKit
//! `mtsTeleOperationPSM`): relative, scaled translation; absolute orientation; an alignment check
//! before following starts; the clutch; the gripper driving the jaw. All in the camera frame.
//!
//! Frames (written down once, `docs/mtm.md` draws them):
//! - `mtm`: the MTM's tip pose in its base frame (`/MTMR/measured_cp`);
//! - `display`: the surgeon's view; [`TeleopConfig::display_from_mtm`] is the fixed rotation the
//!   console applies to MTM poses (identity when the MTM base is the display frame);
//! - `camera`: the ECM's camera frame, which the display shows: the PSM's tip is commanded in it.
//!   A motion of the hand along the display's x moves the tool along the camera's x.
//!
//! Translation is relative: when following starts (and again after each clutch release) the MTM's
//! and the PSM's positions are the anchors, and the PSM moves `scale` times the MTM's displacement
//! from its anchor. Orientation is absolute: the PSM's tip takes the MTM's orientation (times the
//! alignment offset in [`Align::Offset`] mode). Following starts only when the two orientations
//! differ by less than [`TeleopConfig::start_tolerance_rad`] ([`Align::Refuse`], the console's
//! default); while the clutch is pressed nothing is commanded. The settings' defaults are the
//! console's (dVRK `dvrk_teleoperation`: scale 0.2, 5 deg, the gripper-to-jaw map).

use dvrk_kin::Pose;
use nalgebra::{Rotation3, Vector3};

/// What to do when the MTM's orientation does not match the PSM's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    /// Wait until they match within the start tolerance (the console's default).
    Refuse,
    /// Keep the difference at follow start as an offset (the console's alignment offset).
    Offset,
}

/// The follow mode's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct TeleopConfig {
    /// PSM translation per MTM translation (the console's default 0.2).
    pub scale: f64,
    /// Largest orientation difference at which following starts (rad; the console's 5 deg).
    pub start_tolerance_rad: f64,
    pub align: Align,
    /// The rotation from the MTM's base frame to the display (= camera) frame.
    pub display_from_mtm: Rotation3<f64>,
    /// Gripper opening (rad) to jaw angle (rad): `jaw = jaw_per_gripper * gripper + jaw_offset`,
    /// at least `jaw_min` (and within the jaw joint's limits, which the caller applies). The
    /// console's: a 60 deg gripper opens the jaw to 80 deg, so 4/3, offset 0, jaw at least -20 deg.
    pub jaw_per_gripper: f64,
    pub jaw_offset: f64,
    /// Lowest jaw command (rad).
    pub jaw_min: f64,
    /// Fastest jaw command change (rad/s; the console's 2 pi): a replay applies it between samples.
    pub jaw_rate: f64,
}

impl Default for TeleopConfig {
    fn default() -> Self {
        TeleopConfig {
            scale: 0.2,
            start_tolerance_rad: 5f64.to_radians(),
            align: Align::Refuse,
            display_from_mtm: Rotation3::identity(),
            jaw_per_gripper: 80.0 / 60.0,
            jaw_offset: 0.0,
            jaw_min: -20f64.to_radians(),
            jaw_rate: 2.0 * std::f64::consts::PI,
        }
    }
}

/// One sample of the master: its tip pose in its base frame, the gripper's opening (rad), the
/// clutch pedal.
#[derive(Debug, Clone, PartialEq)]
pub struct MtmSample {
    pub pose: Pose,
    pub gripper: f64,
    pub clutch: bool,
}

/// The follow mode's state.
#[derive(Debug, Clone, PartialEq)]
pub enum TeleopState {
    /// Not following: the orientations differ by this much (rad), above the start tolerance.
    Misaligned(f64),
    /// The clutch is pressed.
    Clutched,
    /// Following from these anchors (camera frame, m) with this orientation offset.
    Following { mtm_anchor: Vector3<f64>, psm_anchor: Vector3<f64>, offset: Rotation3<f64> },
}

/// What the PSM is asked for: its tip pose in the camera frame and its jaw angle (rad).
#[derive(Debug, Clone, PartialEq)]
pub struct PsmCommand {
    pub tip_in_camera: Pose,
    pub jaw: f64,
}

/// The MTM -> PSM follow mode (see the module's doc).
#[derive(Debug, Clone)]
pub struct Teleop {
    pub config: TeleopConfig,
    pub state: TeleopState,
    /// The alignment offset kept by [`Align::Offset`] once following first started.
    offset: Option<Rotation3<f64>>,
}

/// The angle (rad) of the rotation between `a` and `b`.
pub fn angle_between(a: &Rotation3<f64>, b: &Rotation3<f64>) -> f64 {
    (a.transpose() * b).angle()
}

impl Teleop {
    pub fn new(config: TeleopConfig) -> Teleop {
        Teleop { config, state: TeleopState::Misaligned(f64::INFINITY), offset: None }
    }

    /// One step: the MTM's sample and the PSM tip's current pose in the camera frame; the PSM's
    /// command while following, `None` otherwise (the PSM holds).
    pub fn step(&mut self, mtm: &MtmSample, psm_in_camera: &Pose) -> Option<PsmCommand> {
        let m_rot = self.config.display_from_mtm * mtm.pose.rotation;
        let m_pos = self.config.display_from_mtm * mtm.pose.translation.vector;
        if mtm.clutch {
            self.state = TeleopState::Clutched;
            return None;
        }
        if !matches!(self.state, TeleopState::Following { .. }) {
            // Start (or resume after the clutch): the orientations must match, or the offset mode
            // keeps their difference (the first one it saw).
            let offset = match self.config.align {
                Align::Offset => *self.offset.get_or_insert(m_rot.transpose() * psm_in_camera.rotation),
                Align::Refuse => Rotation3::identity(),
            };
            let misalignment = angle_between(&(m_rot * offset), &psm_in_camera.rotation);
            if misalignment > self.config.start_tolerance_rad {
                self.state = TeleopState::Misaligned(misalignment);
                return None;
            }
            self.state = TeleopState::Following { mtm_anchor: m_pos, psm_anchor: psm_in_camera.translation.vector, offset };
        }
        let TeleopState::Following { mtm_anchor, psm_anchor, offset } = &self.state else { return None };
        let position = psm_anchor + self.config.scale * (m_pos - mtm_anchor);
        Some(PsmCommand {
            tip_in_camera: Pose::from_parts(nalgebra::Translation3::from(position), m_rot * offset),
            jaw: (self.config.jaw_per_gripper * mtm.gripper + self.config.jaw_offset).max(self.config.jaw_min),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose(p: [f64; 3], r: Rotation3<f64>) -> Pose {
        Pose::from_parts(nalgebra::Translation3::new(p[0], p[1], p[2]), r)
    }

    /// Relative scaled translation, absolute orientation, the clutch re-anchoring, the refusal
    /// of a misaligned start and the offset mode.
    #[test]
    fn follows_relative_translation_and_absolute_orientation() {
        let r0 = Rotation3::from_euler_angles(0.1, -0.2, 0.3);
        let psm = pose([0.01, 0.02, 0.1], r0);
        let mut t = Teleop::new(TeleopConfig::default());
        let at = |p: [f64; 3], r: Rotation3<f64>, clutch: bool| MtmSample { pose: pose(p, r), gripper: 0.5, clutch };
        // 10 deg off: refused.
        let off = r0 * Rotation3::from_axis_angle(&Vector3::x_axis(), 10f64.to_radians());
        assert!(t.step(&at([0.3, 0.0, 0.0], off, false), &psm).is_none());
        assert!(matches!(t.state, TeleopState::Misaligned(a) if (a - 10f64.to_radians()).abs() < 1e-9));
        // Aligned: starts, the PSM stays where it is, then moves 0.2 of the hand.
        let c = t.step(&at([0.3, 0.0, 0.0], r0, false), &psm).unwrap();
        assert!((c.tip_in_camera.translation.vector - psm.translation.vector).norm() < 1e-15);
        let c = t.step(&at([0.35, 0.0, -0.05], r0, false), &psm).unwrap();
        assert!((c.tip_in_camera.translation.vector - (psm.translation.vector + Vector3::new(0.01, 0.0, -0.01))).norm() < 1e-15);
        // Orientation absolute.
        let turned = r0 * Rotation3::from_axis_angle(&Vector3::z_axis(), 0.5);
        assert!(angle_between(&t.step(&at([0.35, 0.0, -0.05], turned, false), &psm).unwrap().tip_in_camera.rotation, &turned) < 1e-12);
        // Clutch: nothing; on release the anchors are the new positions.
        assert!(t.step(&at([0.5, 0.1, 0.0], r0, true), &psm).is_none());
        let moved = pose([0.02, 0.02, 0.09], r0);
        let c = t.step(&at([0.5, 0.1, 0.0], r0, false), &moved).unwrap();
        assert!((c.tip_in_camera.translation.vector - moved.translation.vector).norm() < 1e-15);
        // Offset mode: a 10 deg difference is kept.
        let mut t = Teleop::new(TeleopConfig { align: Align::Offset, ..TeleopConfig::default() });
        let c = t.step(&at([0.3, 0.0, 0.0], off, false), &psm).unwrap();
        assert!(angle_between(&c.tip_in_camera.rotation, &r0) < 1e-12);
    }
}
