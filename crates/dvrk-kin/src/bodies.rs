//! Rigid bodies: frames whose relative placement never changes move as one part (the simulation
//! makes one rigid body of them).

use crate::error::{KinError, Result};
use crate::fk::{compute_frame_placements, Data};
use crate::model::{sample_configurations, Body, Model};

/// Relative placements that change by less than this (m, rad) count as constant.
const RIGID_TOL: f64 = 1e-9;

/// Group the frames into bodies by testing relative placements over spread configurations, then
/// name them from the file's `body` entries (a declared body that is not rigid is an error).
pub(crate) fn assign_bodies(model: &mut Model, declared_names: &[Option<String>]) -> Result<()> {
    let nf = model.frames.len();
    let samples = sample_configurations(&model.joints, 6);
    let mut data = Data::new(model);
    let mut poses = Vec::with_capacity(samples.len());
    for q in &samples {
        compute_frame_placements(model, &mut data, q);
        poses.push(data.frames.clone());
    }
    let rigid = |i: usize, j: usize| -> bool {
        let rel0 = poses[0][i].inverse() * poses[0][j];
        poses[1..].iter().all(|p| {
            let rel = p[i].inverse() * p[j];
            (rel.translation.vector - rel0.translation.vector).norm() < RIGID_TOL
                && (rel.rotation.matrix() - rel0.rotation.matrix()).abs().max() < RIGID_TOL
        })
    };
    // Frames that are rigid to the base (no motion from the base) form the base body.
    let mut group = vec![usize::MAX; nf];
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in 0..nf {
        if group[i] != usize::MAX {
            continue;
        }
        let g = groups.len();
        let members: Vec<usize> = (i..nf).filter(|&j| group[j] == usize::MAX && (j == i || rigid(i, j))).collect();
        for &j in &members {
            group[j] = g;
        }
        groups.push(members);
    }
    let mut bodies: Vec<Body> = Vec::with_capacity(groups.len());
    for members in groups {
        let declared: Vec<&str> = members.iter().filter_map(|&j| declared_names[j].as_deref()).collect();
        let name = declared.first().map(|s| s.to_string()).unwrap_or_else(|| model.frames[members[0]].name.clone());
        bodies.push(Body { name, frames: members });
    }
    // A declared body name shared by frames of different rigid groups is a modelling error.
    for (bi, b) in bodies.iter().enumerate() {
        for (bj, c) in bodies.iter().enumerate().skip(bi + 1) {
            let _ = bj;
            for name in b.frames.iter().filter_map(|&j| declared_names[j].as_deref()) {
                if c.frames.iter().any(|&j| declared_names[j].as_deref() == Some(name)) {
                    return Err(KinError::field(
                        format!("frames ({}).body", model.frames[c.frames[0]].name),
                        format!(
                            "`{name}` is declared one body, but frames {} and {} move relative to each other",
                            model.frames[b.frames[0]].name,
                            model.frames[c.frames[0]].name
                        ),
                    ));
                }
            }
        }
    }
    for (bi, b) in bodies.iter().enumerate() {
        for &j in &b.frames {
            model.frames[j].body = bi;
        }
    }
    model.bodies = bodies;
    Ok(())
}

impl Model {
    /// The file entry of frame `i` (matched by name).
    pub(crate) fn spec_frame(&self, i: usize) -> Option<&crate::spec::FrameSpec> {
        let name = &self.frames[i].name;
        self.spec.frames.iter().find(|f| &f.name == name)
    }
}
