//! Loop closures: residuals and the conditioning of the closure constraints.

use crate::error::{KinError, Result};
use crate::fk::{compute_frame_placements, Data};
use crate::model::{Closure, Model};
use nalgebra::{DMatrix, Vector3};

pub(crate) fn compile_closures(model: &mut Model) -> Result<()> {
    let specs = model.spec.closures.clone();
    let mut closures = Vec::with_capacity(specs.len());
    let mut data = Data::new(model);
    compute_frame_placements(model, &mut data, &model.home());
    for (i, c) in specs.iter().enumerate() {
        let field = |f: &str| format!("closures[{i}] ({}).{f}", c.name);
        let frame = model.frame_id(&c.frame).map_err(|e| KinError::field(field("frame"), e.to_string()))?;
        let partner = model.frame_id(&c.partner).map_err(|e| KinError::field(field("partner"), e.to_string()))?;
        if frame == partner {
            return Err(KinError::field(field("partner"), "a closure needs two different frames"));
        }
        let finite = |p: &[f64; 3], f: &str| -> Result<Vector3<f64>> {
            if p.iter().any(|x| !x.is_finite()) {
                return Err(KinError::field(field(f), format!("{p:?} has a non-finite entry")));
            }
            Ok(Vector3::from(*p))
        };
        let point = finite(&c.point, "point")?;
        let partner_point = match &c.partner_point {
            Some(p) => finite(p, "partner_point")?,
            None => data.frames[partner].inverse_transform_point(&(data.frames[frame] * nalgebra::Point3::from(point))).coords,
        };
        closures.push(Closure { name: c.name.clone(), frame, point, partner, partner_point });
    }
    model.closures = closures;
    Ok(())
}

/// World-frame gap of closure `c` (m) for the placements in `data`.
pub fn closure_gap(c: &Closure, data: &Data) -> Vector3<f64> {
    let a = data.frames[c.frame] * nalgebra::Point3::from(c.point);
    let b = data.frames[c.partner] * nalgebra::Point3::from(c.partner_point);
    a - b
}

/// Largest closure gap (m) for the placements in `data` (0 for a model without closures).
pub fn max_closure_residual(model: &Model, data: &Data) -> f64 {
    model.closures.iter().map(|c| closure_gap(c, data).norm()).fold(0.0, f64::max)
}

/// The physical pivots of the mechanism: moving frames grouped by the pair of bodies they join
/// (frames of one body turning about one pivot are one joint).
fn pivots(model: &Model) -> Vec<Vec<usize>> {
    // (child body, parent body) -> frames
    type Key = (usize, Option<usize>);
    let mut groups: Vec<(Key, Vec<usize>)> = Vec::new();
    for (i, f) in model.frames.iter().enumerate() {
        if !f.is_moving() {
            continue;
        }
        let key = (f.body, f.parent.map(|p| model.frames[p].body));
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, v)) => v.push(i),
            None => groups.push((key, vec![i])),
        }
    }
    groups.into_iter().map(|(_, v)| v).collect()
}

/// Closure Jacobian (3 x nclosures rows, one column per pivot of the tree, m/rad or m/m) for the
/// placements in `data`: how the closure gaps change when each tree pivot moves on its own.
pub fn closure_jacobian(model: &Model, data: &Data) -> DMatrix<f64> {
    let piv = pivots(model);
    let mut g = DMatrix::zeros(3 * model.closures.len(), piv.len());
    for (k, c) in model.closures.iter().enumerate() {
        let pa = data.frames[c.frame] * nalgebra::Point3::from(c.point);
        for (col, frames) in piv.iter().enumerate() {
            for &j in frames {
                let (sens, _) = crate::jacobian::joint_motion_at(model, data, j, &pa.coords);
                let mut v = Vector3::zeros();
                if model.is_ancestor_or_self(j, c.frame) {
                    v += sens;
                }
                if model.is_ancestor_or_self(j, c.partner) {
                    v -= sens;
                }
                for r in 0..3 {
                    g[(3 * k + r, col)] += v[r];
                }
            }
        }
    }
    g
}

/// Conditioning of the closure constraints: the smallest of the singular values that are
/// non-zero at the home configuration (m/rad). Zero means a loop has flattened (a singularity).
#[derive(Debug, Clone, PartialEq)]
pub struct ClosureConditioning {
    /// Number of independent closure constraints (rank at home).
    pub rank: usize,
    /// `sigma_rank` at the home configuration.
    pub at_home: f64,
    /// Smallest `sigma_rank` over the sampled joint range, and where.
    pub worst: f64,
    pub worst_q: Vec<f64>,
}

/// Evaluate [`ClosureConditioning`] over `samples` configurations spread over the joint range
/// plus a grid over every joint that moves a closure.
pub fn closure_conditioning(model: &Model, samples: usize) -> Option<ClosureConditioning> {
    if model.closures.is_empty() {
        return None;
    }
    let mut data = Data::new(model);
    let sigma = |data: &mut Data, q: &[f64]| -> Vec<f64> {
        compute_frame_placements(model, data, q);
        let mut s = closure_jacobian(model, data).singular_values().as_slice().to_vec();
        s.sort_by(|a, b| b.total_cmp(a));
        s
    };
    let home = model.home();
    let s0 = sigma(&mut data, &home);
    let rank = s0.iter().filter(|x| **x > 1e-9 * s0[0].max(1e-300)).count();
    if rank == 0 {
        return None;
    }
    let mut configs = crate::model::sample_configurations(&model.joints, samples);
    // A fine sweep of each joint alone from home: loop singularities are often one-joint events.
    for k in 0..model.nq() {
        let j = &model.joints[k];
        for s in 0..=200 {
            let mut q = home.clone();
            q[k] = j.lower + (j.upper - j.lower) * s as f64 / 200.0;
            configs.push(q);
        }
    }
    let mut worst = f64::INFINITY;
    let mut worst_q = home.clone();
    for q in configs {
        let s = sigma(&mut data, &q);
        let v = s.get(rank - 1).copied().unwrap_or(0.0);
        if v < worst {
            worst = v;
            worst_q = q;
        }
    }
    Some(ClosureConditioning { rank, at_home: s0[rank - 1], worst, worst_q })
}

impl Model {
    /// True when frame `a` is `b` or one of its predecessors.
    pub fn is_ancestor_or_self(&self, a: usize, b: usize) -> bool {
        let mut cur = Some(b);
        while let Some(c) = cur {
            if c == a {
                return true;
            }
            if c < a {
                return false; // depth-first order: ancestors come first
            }
            cur = self.frames[c].parent;
        }
        false
    }
}
