//! Compiling a model file ([`ModelSpec`]) into a [`Model`]: the DH table's frames in
//! depth-first order, the effects checked and applied, the bodies, closures and remote centre
//! located, the file's inertials, drive and covariance checked. It sits above the model and the
//! analyses that fill it, so the model stays plain data.

use crate::error::{KinError, Result};
use crate::expr::{parse_affine, Affine, Scope};
use crate::model::{pose_from_rows, rx, rz, tx, tz, Eval, Frame, Joint, Model, Motion, Pose, Rcm};
use crate::spec::{Convention, EffectSpec, FrameJoint, FrameRef, ModelSpec, Value};
use std::collections::BTreeMap;

impl Model {
    /// Compile a model file. `load_serial` is not needed here: serial equivalence is checked by
    /// [`crate::check`].
    pub fn compile(mut spec: ModelSpec) -> Result<Model> {
        let n = spec.joints.len();
        // A link_length effect edits the DH table itself; the spec keeps the file's numbers.
        let file_spec = spec.clone();
        crate::effects::apply_link_lengths(&mut spec)?;
        crate::effects::apply_counterweight(&mut spec)?;
        let mut parameters = BTreeMap::new();
        for (k, p) in &spec.parameters {
            if !p.value.is_finite() {
                return Err(KinError::field(format!("parameters.{k}.value"), format!("{} is not finite", p.value)));
            }
            parameters.insert(k.clone(), p.value);
        }
        let joint_names: Vec<String> = spec.joints.iter().map(|j| j.name.clone()).collect();
        let mut joints = Vec::with_capacity(n);
        for (i, j) in spec.joints.iter().enumerate() {
            let field = |f: &str| format!("joints[{i}] ({}).{f}", j.name);
            for (f, v) in [("lower", j.lower), ("upper", j.upper), ("effort_limit", j.effort_limit)] {
                if !v.is_finite() {
                    return Err(KinError::field(field(f), format!("{v} is not finite")));
                }
            }
            if j.lower > j.upper {
                return Err(KinError::field(field("lower"), format!("{} is above upper = {}", j.lower, j.upper)));
            }
            if joint_names[..i].contains(&j.name) {
                return Err(KinError::field(field("name"), format!("`{}` appears twice", j.name)));
            }
            let home = j.home.unwrap_or(0.0_f64.clamp(j.lower, j.upper));
            if !home.is_finite() || home < j.lower || home > j.upper {
                return Err(KinError::field(field("home"), format!("{home} is not within [{}, {}]", j.lower, j.upper)));
            }
            joints.push(Joint {
                name: j.name.clone(),
                kind: j.kind,
                lower: j.lower,
                upper: j.upper,
                effort_limit: j.effort_limit,
                home,
            });
        }
        let scope = Scope { parameters: &parameters, joints: &joint_names };
        let order = frame_order(&spec)?;
        let mut frames: Vec<Frame> = Vec::with_capacity(order.len());
        let mut position = vec![usize::MAX; spec.frames.len()];
        for (pos, &(fi, parent)) in order.iter().enumerate() {
            position[fi] = pos;
            let fs = &spec.frames[fi];
            let field = |f: &str| format!("frames[{fi}] ({}).{f}", fs.name);
            let value = |v: &Value, f: &str| -> Result<Affine> {
                match v {
                    Value::Number(x) if x.is_finite() => Ok(Affine::constant(n, *x)),
                    Value::Number(x) => Err(KinError::field(field(f), format!("{x} is not finite"))),
                    Value::Expr(e) => parse_affine(e, &field(f), &scope),
                }
            };
            let a = value(&fs.a, "a")?;
            let alpha = value(&fs.alpha, "alpha")?;
            let d = value(&fs.d, "d")?;
            let theta = value(&fs.theta, "theta")?;
            for (aff, f) in [(&a, "a"), (&alpha, "alpha")] {
                if !aff.is_constant() {
                    return Err(KinError::field(field(f), "must not depend on a joint"));
                }
            }
            let (pre, post, motion) = if let Some(t) = &fs.transform {
                if fs.joint != FrameJoint::Fixed {
                    return Err(KinError::field(field("transform"), "only a fixed frame may be given as a transform"));
                }
                if [&fs.a, &fs.alpha, &fs.d, &fs.theta].iter().any(|v| **v != Value::Number(0.0)) {
                    return Err(KinError::field(field("transform"), "give either a transform or DH entries, not both"));
                }
                let p = pose_from_rows(t, &field("transform"))?;
                (Pose::identity(), None, Motion::Fixed(p))
            } else {
                let (pre, post) = match spec.convention {
                    Convention::Modified => (rx(alpha.offset) * tx(a.offset), None),
                    Convention::Standard => (Pose::identity(), Some(tx(a.offset) * rx(alpha.offset))),
                };
                let motion = match fs.joint {
                    FrameJoint::Fixed => {
                        if !theta.is_constant() || !d.is_constant() {
                            return Err(KinError::field(field("joint"), "a fixed frame's theta and d must not depend on a joint"));
                        }
                        let mut p = pre * rz(theta.offset) * tz(d.offset);
                        if let Some(post) = &post {
                            p *= post;
                        }
                        Motion::Fixed(p)
                    }
                    FrameJoint::Revolute => {
                        if !d.is_constant() {
                            return Err(KinError::field(field("d"), "a revolute frame's d must not depend on a joint"));
                        }
                        if theta.is_constant() {
                            // Locked revolute (the paper lists some as R with a constant angle).
                            let mut p = pre * rz(theta.offset) * tz(d.offset);
                            if let Some(post) = &post {
                                p *= post;
                            }
                            Motion::Fixed(p)
                        } else {
                            Motion::Revolute { d0: d.offset }
                        }
                    }
                    FrameJoint::Prismatic => {
                        if !theta.is_constant() {
                            return Err(KinError::field(field("theta"), "a prismatic frame's theta must not depend on a joint"));
                        }
                        if d.is_constant() {
                            // Locked prismatic: as for revolute frames with a constant angle.
                            let mut p = pre * rz(theta.offset) * tz(d.offset);
                            if let Some(post) = &post {
                                p *= post;
                            }
                            Motion::Fixed(p)
                        } else {
                            Motion::Prismatic
                        }
                    }
                };
                let pre = match motion {
                    Motion::Prismatic => pre * rz(theta.offset),
                    _ => pre,
                };
                (pre, post, motion)
            };
            let (a_num, alpha_num) =
                if fs.transform.is_some() { (f64::NAN, f64::NAN) } else { (a.offset, alpha.offset) };
            frames.push(Frame {
                index: fs.index.unwrap_or(pos as i64 + 1),
                name: fs.name.clone(),
                parent: parent.map(|p| position[p]),
                body: 0,
                joint: fs.joint,
                a: a_num,
                alpha: alpha_num,
                theta,
                d,
                pre,
                post,
                motion,
            });
        }
        for (i, f) in frames.iter().enumerate() {
            if frames[..i].iter().any(|g| g.name == f.name) {
                return Err(KinError::field(format!("frames ({}).name", f.name), "frame name appears twice"));
            }
            if frames[..i].iter().any(|g| g.index == f.index) {
                return Err(KinError::field(format!("frames ({}).index", f.name), format!("frame number {} appears twice", f.index)));
            }
        }
        let coupling = match &spec.coupling {
            None => None,
            Some(rows) => Some(matrix_from_rows(rows, "coupling")?),
        };
        let mut model = Model {
            name: spec.name.clone(),
            title: spec.title.clone(),
            joints,
            frames,
            bodies: Vec::new(),
            closures: Vec::new(),
            rcm: None,
            tip: 0,
            base: Pose::identity(),
            coupling,
            spec: file_spec,
            origin: None,
            tool_file: None,
            parts: Vec::new(),
            effects: Vec::new(),
            eval: Eval::default(),
        };
        model.tip = match &spec.tip {
            Some(r) => model.frame_id(r).map_err(|e| KinError::field("tip", e.to_string()))?,
            None => model.frames.len().saturating_sub(1),
        };
        if model.frames.is_empty() {
            return Err(KinError::field("frames", "a model needs at least one frame"));
        }
        let effects = crate::effects::check_effects(&model)?;
        crate::effects::apply_kinematic(&mut model, &effects)?;
        model.effects = effects;
        let declared: Vec<Option<String>> =
            (0..model.frames.len()).map(|i| model.spec_frame(i).and_then(|f| f.body.clone())).collect();
        model.finalize(&declared)?;
        model.check_inertials()?;
        model.check_drive()?;
        model.check_inertial_covariance()?;
        crate::closure::compile_closures(&mut model)?;
        if let Some(r) = &spec.rcm {
            let frame = model.frame_id(&r.frame).map_err(|e| KinError::field("rcm.frame", e.to_string()))?;
            let point = crate::rcm::locate_rcm(&model, frame);
            model.rcm = Some(Rcm { frame, point });
        }
        Ok(model)
    }

    /// This model with `effect` added to its file's effects, compiled again (a kinematic effect
    /// moves the frames, a physical one joins [`Model::effects`]); the base (a scene's mount
    /// included: a simulator that mounts the model again wants the file's own base), file and
    /// tool file are kept. What a hypothesis test or a generator does to a model.
    pub fn with_effect(&self, effect: &EffectSpec) -> Result<Model> {
        let mut spec = self.spec.clone();
        spec.effects.push(effect.clone());
        let mut m = Model::compile(spec)?;
        m.base = self.base;
        m.origin = self.origin.clone();
        m.tool_file = self.tool_file.clone();
        Ok(m)
    }

    /// Last step of building a model from frames: the evaluation data, then the bodies (named
    /// from `declared`, one optional name per frame).
    pub(crate) fn finalize(&mut self, declared: &[Option<String>]) -> Result<()> {
        self.eval = Eval::build(&self.frames);
        crate::bodies::assign_bodies(self, declared)
    }
}

impl Model {
    /// The `[[inertials]]` of the model file: each names a body once and is physical
    /// ([`crate::BodyInertia::check`]).
    fn check_inertials(&self) -> Result<()> {
        for (i, e) in self.spec.inertials.iter().enumerate() {
            let what = format!("inertials[{i}] ({})", e.body);
            if !self.bodies.iter().any(|b| b.name == e.body) {
                let valid: Vec<&str> = self.bodies.iter().map(|b| b.name.as_str()).collect();
                return Err(KinError::field(format!("{what}.body"), format!("model {} has no body `{}` (valid: {})", self.name, e.body, valid.join(", "))));
            }
            if self.spec.inertials[..i].iter().any(|o| o.body == e.body) {
                return Err(KinError::field(format!("{what}.body"), "body appears twice"));
            }
            crate::BodyInertia::new(e.mass, e.com, e.inertia).check(&what)?;
        }
        Ok(())
    }

    /// The model file's `[drive]`: an armature per joint, every figure finite and non-negative.
    fn check_drive(&self) -> Result<()> {
        let Some(d) = &self.spec.drive else { return Ok(()) };
        if d.armature.len() != self.nq() {
            return Err(KinError::field("drive.armature", format!("has {} entries, model {} has {} joints", d.armature.len(), self.name, self.nq())));
        }
        let bad = |v: f64| !v.is_finite() || v < 0.0;
        if bad(d.damping) {
            return Err(KinError::field("drive.damping", format!("{} is not a finite non-negative number", d.damping)));
        }
        if let Some((k, v)) = d.armature.iter().enumerate().find(|(_, v)| bad(**v)) {
            return Err(KinError::field(format!("drive.armature[{k}] ({})", self.joints[k].name), format!("{v} is not a finite non-negative number")));
        }
        Ok(())
    }

    /// The model file's `[inertial_covariance]`: known bodies, each once, and a lower triangular
    /// factor of the right size with finite entries and a positive diagonal.
    fn check_inertial_covariance(&self) -> Result<()> {
        let Some(c) = &self.spec.inertial_covariance else { return Ok(()) };
        for (i, name) in c.bodies.iter().enumerate() {
            if !self.bodies.iter().any(|b| &b.name == name) {
                return Err(KinError::field(format!("inertial_covariance.bodies[{i}]"), format!("model {} has no body `{name}`", self.name)));
            }
            if c.bodies[..i].contains(name) {
                return Err(KinError::field(format!("inertial_covariance.bodies[{i}]"), format!("body `{name}` appears twice")));
            }
        }
        let n = c.bodies.len() * crate::dynamics::PARAMETERS_PER_BODY;
        if c.cholesky.len() != n {
            return Err(KinError::field("inertial_covariance.cholesky", format!("has {} rows; {} bodies need {n}", c.cholesky.len(), c.bodies.len())));
        }
        for (i, row) in c.cholesky.iter().enumerate() {
            let what = format!("inertial_covariance.cholesky[{i}]");
            if row.len() != i + 1 {
                return Err(KinError::field(what, format!("has {} entries; row {i} of a lower triangular factor has {}", row.len(), i + 1)));
            }
            if let Some((k, v)) = row.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(KinError::field(format!("{what}[{k}]"), format!("{v} is not a finite number")));
            }
            if !(row[i] > 0.0) {
                return Err(KinError::field(format!("{what}[{i}]"), format!("{:.6e}: the diagonal of a Cholesky factor is positive", row[i])));
            }
        }
        Ok(())
    }
}

/// A dense matrix from rows, checking it is rectangular and finite.
pub(crate) fn matrix_from_rows(rows: &[Vec<f64>], field: &str) -> Result<nalgebra::DMatrix<f64>> {
    let nr = rows.len();
    let nc = rows.first().map_or(0, |r| r.len());
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != nc) {
        return Err(KinError::field(format!("{field}[{i}]"), format!("row has {} entries, expected {nc}", r.len())));
    }
    if rows.iter().flatten().any(|x| !x.is_finite()) {
        return Err(KinError::field(field, "has a non-finite entry"));
    }
    Ok(nalgebra::DMatrix::from_fn(nr, nc, |i, j| rows[i][j]))
}

/// Depth-first order of the spec's frames with each one's parent (spec positions), or an error
/// naming an unknown parent or a cycle.
fn frame_order(spec: &ModelSpec) -> Result<Vec<(usize, Option<usize>)>> {
    let nf = spec.frames.len();
    let mut parent: Vec<Option<usize>> = Vec::with_capacity(nf);
    for (i, f) in spec.frames.iter().enumerate() {
        let field = format!("frames[{i}] ({}).parent", f.name);
        let p = match &f.parent {
            FrameRef::Index(0) => None,
            FrameRef::Name(s) if s == "base" => None,
            r => {
                let found = spec.frames.iter().enumerate().position(|(k, g)| match r {
                    FrameRef::Index(x) => g.index.unwrap_or(k as i64 + 1) == *x,
                    FrameRef::Name(s) => g.name == *s,
                });
                match found {
                    Some(k) if k == i => return Err(KinError::field(field, format!("`{r}` is the frame itself"))),
                    Some(k) => Some(k),
                    None => {
                        let valid = std::iter::once("0 (base)".to_string())
                            .chain(spec.frames.iter().enumerate().map(|(k, g)| format!("{} ({})", g.index.unwrap_or(k as i64 + 1), g.name)));
                        return Err(KinError::field(field, KinError::unknown("frame", &r.to_string(), valid).to_string()));
                    }
                }
            }
        };
        parent.push(p);
    }
    // Depth-first from the base, children in file order.
    let mut order = Vec::with_capacity(nf);
    let mut stack: Vec<usize> = (0..nf).rev().filter(|&i| parent[i].is_none()).collect();
    while let Some(i) = stack.pop() {
        order.push((i, parent[i]));
        stack.extend((0..nf).rev().filter(|&k| parent[k] == Some(i)));
    }
    if order.len() < nf {
        let missing: Vec<&str> =
            (0..nf).filter(|i| !order.iter().any(|(k, _)| k == i)).map(|i| spec.frames[i].name.as_str()).collect();
        return Err(KinError::field("frames", format!("frames {} form a cycle (none reaches the base)", missing.join(", "))));
    }
    Ok(order)
}
