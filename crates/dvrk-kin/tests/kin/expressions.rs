//! Frame-variable expressions of model files (`-q2 + beta1 + pi/2`): affine in the joints.

use dvrk_kin::expr::{parse_affine, Affine, Scope};
use dvrk_kin::Result;
use std::collections::BTreeMap;
use std::f64::consts::PI;

fn scope_eval(e: &str) -> Result<Affine> {
    let mut p = BTreeMap::new();
    p.insert("beta1".to_string(), 0.3);
    p.insert("mu".to_string(), 0.6);
    let joints = vec!["yaw".to_string(), "pitch".to_string(), "insertion".to_string()];
    parse_affine(e, "theta", &Scope { parameters: &p, joints: &joints })
}

#[test]
fn paper_style_expressions() {
    let a = scope_eval("-q2 + beta1 + pi/2").unwrap();
    assert_eq!(a.coef, vec![0.0, -1.0, 0.0]);
    assert!((a.offset - (0.3 + PI / 2.0)).abs() < 1e-15);
    let b = scope_eval("mu*q3").unwrap();
    assert_eq!(b.coef, vec![0.0, 0.0, 0.6]);
    let c = scope_eval("0.5 * pitch - 1e-3").unwrap();
    assert_eq!(c.coef, vec![0.0, 0.5, 0.0]);
    assert!((c.offset + 1e-3).abs() < 1e-18);
    assert_eq!(scope_eval("- -yaw").unwrap().coef[0], 1.0);
}

#[test]
fn rejects_bad_expressions() {
    for bad in ["", "q2*q3", "1/q2", "beta3", "q9", "2 +", "3 $ 4", "1/0"] {
        let e = scope_eval(bad).unwrap_err().to_string();
        assert!(e.contains("theta"), "{bad}: {e}");
    }
    assert!(scope_eval("beta3").unwrap_err().to_string().contains("beta1"));
}
