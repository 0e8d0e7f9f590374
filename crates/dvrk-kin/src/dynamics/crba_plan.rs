//! The composite-rigid-body pass's work list, built once per model ([`super::DynamicsModel`]).

use crate::model::Model;

/// The composite-rigid-body pass flattened once per model: for each frame with a variable, the
/// frames with a variable it hangs from (itself included), and for each such pair where
/// `s_j . (I^c_i s_i)` lands in `M`'s lower triangle with what coefficient. The pass then runs
/// down three flat lists instead of walking ancestors and multiplying joint terms every step.
#[derive(Debug, Clone, Default)]
pub(crate) struct Plan {
    /// Per frame with a variable: the frame and the end of its run in `pairs`.
    pub(crate) frames: Vec<(usize, usize)>,
    /// Per pair: the ancestor frame `j` and the end of its run in `scatter`.
    pub(crate) pairs: Vec<(usize, usize)>,
    /// Column-major index into `M` (lower triangle) and coefficient (`c_ik c_jl`, doubled on the
    /// diagonal for `j != i`, where both orders land on it).
    pub(crate) scatter: Vec<(usize, f64)>,
    pub(crate) nq: usize,
}

impl Plan {
    /// The plan of `model`, whose frames' variables have the non-zero `terms` `(joint, c)`.
    pub(crate) fn new(model: &Model, terms: &[Vec<(usize, f64)>]) -> Plan {
        let n = model.nq();
        let mut plan = Plan { nq: n, ..Plan::default() };
        for i in 0..model.frames.len() {
            if terms[i].is_empty() {
                continue;
            }
            let mut cur = Some(i);
            while let Some(j) = cur {
                cur = model.frames[j].parent;
                if terms[j].is_empty() {
                    continue;
                }
                let from = plan.scatter.len();
                for &(k, ck) in &terms[i] {
                    for &(l, cl) in &terms[j] {
                        // M[k][l] and (for j != i) M[l][k] gain ck cl m_ij: keep the lower one.
                        let (r, c) = (k.max(l), k.min(l));
                        let coef = if j == i {
                            if k < l {
                                continue;
                            }
                            ck * cl
                        } else if k == l {
                            2.0 * ck * cl
                        } else {
                            ck * cl
                        };
                        let at = r + c * n;
                        match plan.scatter[from..].iter_mut().find(|(x, _)| *x == at) {
                            Some(e) => e.1 += coef,
                            None => plan.scatter.push((at, coef)),
                        }
                    }
                }
                plan.pairs.push((j, plan.scatter.len()));
            }
            plan.frames.push((i, plan.pairs.len()));
        }
        plan
    }
}
