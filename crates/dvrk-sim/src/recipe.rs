//! How `models/inertials/{psm,ecm}.toml` were made from the paper's SDF figures: the base
//! transform of each model, the bodies the SDF lacks, and the notes written into the file.
//! `tests/sim/inertials.rs` regenerates the files from `../shared/data/external/dvrk-env-inertials`
//! and checks they match (set `DVRK_REGEN_INERTIALS=1` to rewrite them).

use crate::error::{Result, SimError};
use crate::inertials::{from_sdf, BodyInertial, ExtraBody, Inertials, SdfExtract};
use dvrk_kin::{Model, Pose};
use nalgebra::{Rotation3, Translation3, Vector3};

/// The dvrk-kin base frame in the SDF model frame. PSM: the SDF puts the RCM at +y where dvrk-kin
/// puts it at -y, a half turn about z. ECM: a quarter turn about z (dvrk-kin +y is the SDF's +x)
/// and the SDF origin sits 0.5444 m (twice the 0.2722 m yaw-to-pitch offset) along x and
/// 0.10146 m (the yaw link's height) up. Both were read off the link origins at zero
/// configuration; `tests/sim/inertials.rs` checks every SDF joint axis against the model's.
pub fn base_transform(model: &str) -> Option<Pose> {
    match model {
        "psm" => Some(Pose::from_parts(Translation3::identity(), Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::PI))),
        "ecm" => Some(Pose::from_parts(
            Translation3::new(0.5444, 0.0, 0.10146),
            Rotation3::from_axis_angle(&Vector3::z_axis(), -std::f64::consts::FRAC_PI_2),
        )),
        _ => None,
    }
}

/// PSM counterweight (no link in the SDF): its mass balances the insertion stage's moving mass
/// about the pitch axis (`m_cw mu = m_moving`, mu = 0.6025); inertia of a 30 x 30 x 100 mm
/// uniform block along the counterweight's travel (frame 11 z).
fn psm_counterweight(moving_mass: f64) -> ExtraBody {
    let m = moving_mass / 0.6025;
    let (a, b, c) = (0.03_f64, 0.03_f64, 0.1_f64);
    let r = |x: f64| (x * 1e12).round() / 1e12;
    let ixx = r(m / 12.0 * (b * b + c * c));
    let iyy = r(m / 12.0 * (a * a + c * c));
    let izz = r(m / 12.0 * (a * a + b * b));
    ExtraBody {
        name: "counterweight_link".into(),
        inertial: BodyInertial {
            name: "counterweight_link".into(),
            frame: 11,
            mass: r(m),
            com: [0.0, 0.0, 0.0],
            inertia: [[ixx, 0.0, 0.0], [0.0, iyy, 0.0], [0.0, 0.0, izz]],
            provenance: format!(
                "not in the SDF: mass = moving insertion mass {moving_mass:.6} kg / mu 0.6025 (static balance about the pitch axis); inertia of a uniform 30 x 30 x 100 mm block"
            ),
        },
    }
}

const PSM_NOTES: &str = "Masses and inertias are the paper's SolidWorks figures as the dvrk_env SDF holds them (some \
hand-edited there). The tool links' 0.001 kg m^2 inertias are SDF placeholders, kept as given; the \
wrist and jaw joints get a reflected drive inertia (scene armature) on top.";

const ECM_NOTES: &str = "Masses and inertias are the paper's SolidWorks figures as the dvrk_env SDF holds them. \
The SDF's zero configuration is the dvrk-kin q = 0.";

/// Rebuild the inertials of built-in model `name` from the SDF extract's text.
pub fn regenerate(model: &Model, sdf_json: &str) -> Result<Inertials> {
    let sdf: SdfExtract = serde_json::from_str(sdf_json).map_err(|e| SimError::field(format!("{} SDF extract", model.name), "(json)", e.to_string()))?;
    let base = base_transform(&model.name).ok_or_else(|| SimError::field(&model.name, "model", "no SDF recipe for this model (psm, ecm)"))?;
    match model.name.as_str() {
        "psm" => {
            let moving = ["main_insertion_link", "tool_roll_link", "tool_pitch_link", "tool_yaw_link", "tool_gripper1_link", "tool_gripper2_link"];
            let m: f64 = sdf.links.iter().filter(|l| moving.contains(&l.link.as_str())).map(|l| l.mass_kg).sum();
            from_sdf(model, &sdf, &base, &[psm_counterweight(m)], PSM_NOTES)
        }
        _ => from_sdf(model, &sdf, &base, &[], ECM_NOTES),
    }
}

/// Edge lengths of the block every SUJ body is given (m): 80 x 80 mm across, 400 mm along the body
/// frame's x axis (the direction of the SUJ's long links, `a` = 0.4318 m).
const SUJ_BLOCK: [f64; 3] = [0.4, 0.08, 0.08];

/// Mass given to a SUJ body the SDF has no link for (kg).
const SUJ_MISSING_MASS: f64 = 1.0;

const SUJ_NOTES: &str = "Simple block inertias, not CAD figures: the setup joints are held in position mode (the paper \
holds them too), so their inertia matters little. The SDF's SUJ links do not map cleanly onto the dvrk-kin \
bodies (its SUJ-PSM arms have 5 links, L0-L4, for the model's 6 moving bodies, in other frame conventions), \
so only the masses are taken from it, link by link in chain order (L0 on the first body); a body past the \
SDF's last link gets 1 kg. Each body is a uniform 400 x 80 x 80 mm block (long along the body frame's x) \
centred on the body frame's origin.";

/// Block inertials of SUJ model `model` (`suj-psm1` .. `suj-psm3`, `suj-ecm`): masses from the SDF
/// extract `suj.json` (the `suj_<arm>_L<i>` links, in chain order), inertias of a uniform block.
pub fn suj_blocks(model: &Model, sdf_json: &str) -> Result<Inertials> {
    let sdf: SdfExtract = serde_json::from_str(sdf_json).map_err(|e| SimError::field("suj SDF extract", "(json)", e.to_string()))?;
    let Some(arm) = model.name.strip_prefix("suj-") else {
        return Err(SimError::field(&model.name, "model", "not a SUJ model (suj-psm1, suj-psm2, suj-psm3, suj-ecm)"));
    };
    let [a, b, c] = SUJ_BLOCK;
    let r = |x: f64| (x * 1e12).round() / 1e12;
    let bodies = model
        .bodies
        .iter()
        .enumerate()
        .map(|(i, body)| {
            let link = format!("suj_{arm}_L{i}");
            let (mass, from) = match sdf.links.iter().find(|l| l.link == link) {
                Some(l) => (l.mass_kg, format!("mass of SDF link {link}")),
                None => (SUJ_MISSING_MASS, format!("no SDF link {link}: {SUJ_MISSING_MASS} kg assumed")),
            };
            let (ixx, iyy, izz) = (r(mass / 12.0 * (b * b + c * c)), r(mass / 12.0 * (a * a + c * c)), r(mass / 12.0 * (a * a + b * b)));
            BodyInertial {
                name: body.name.clone(),
                frame: model.frames[body.frames[0]].index,
                mass,
                com: [0.0, 0.0, 0.0],
                inertia: [[ixx, 0.0, 0.0], [0.0, iyy, 0.0], [0.0, 0.0, izz]],
                provenance: format!("{from}; inertia of a uniform 400 x 80 x 80 mm block centred on the frame origin"),
            }
        })
        .collect();
    let identity = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
    Ok(Inertials { model: model.name.clone(), source: sdf.source.clone(), base_transform: identity, notes: SUJ_NOTES.into(), bodies })
}
