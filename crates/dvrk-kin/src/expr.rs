//! Affine expressions of the actuated joints, as written in model files.
//!
//! A passive frame's DH variable is `theta = sum_k c_k q_k + b` (rad, or m for `d`). Model files
//! write it the way the paper's tables do: `"-q2 + beta1 + pi/2"`, `"mu*q3"`, `"0.5*jaw - pi/2"`.
//! Terms are numbers, `pi`, named parameters of the model and joints (`q1`..`qN`, 1-based, or the
//! joint's name), joined by `+`/`-`, with `*` and `/` inside a term. At most one joint per term.

use crate::error::{KinError, Result};
use std::collections::BTreeMap;

/// `value = coef . q + offset`, dense over the model's actuated joints.
#[derive(Debug, Clone, PartialEq)]
pub struct Affine {
    /// One coefficient per actuated joint (unitless, or m/rad for mixed maps).
    pub coef: Vec<f64>,
    /// Constant part (rad or m).
    pub offset: f64,
}

impl Affine {
    /// A constant.
    pub fn constant(n: usize, offset: f64) -> Self {
        Affine { coef: vec![0.0; n], offset }
    }
    /// True when no joint moves it.
    pub fn is_constant(&self) -> bool {
        self.coef.iter().all(|c| *c == 0.0)
    }
    /// Evaluate at `q` (len = number of joints).
    #[inline]
    pub fn eval(&self, q: &[f64]) -> f64 {
        self.coef.iter().zip(q).fold(self.offset, |acc, (c, x)| acc + c * x)
    }
    /// Joints with a non-zero coefficient.
    pub fn joints(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.coef.iter().copied().enumerate().filter(|(_, c)| *c != 0.0)
    }
}

/// Names an expression may use.
pub struct Scope<'a> {
    /// Named constants of the model (rad or m).
    pub parameters: &'a BTreeMap<String, f64>,
    /// Actuated joint names, in order.
    pub joints: &'a [String],
}

impl Scope<'_> {
    fn joint(&self, name: &str) -> Option<usize> {
        if let Some(i) = self.joints.iter().position(|j| j == name) {
            return Some(i);
        }
        let k: usize = name.strip_prefix('q')?.parse().ok()?;
        (1..=self.joints.len()).contains(&k).then(|| k - 1)
    }
}

/// Parse `expr` (the text of `field`) into an affine map of the joints.
pub fn parse_affine(expr: &str, field: &str, scope: &Scope) -> Result<Affine> {
    let err = |m: String| KinError::Expr { field: field.into(), expr: expr.into(), message: m };
    let n = scope.joints.len();
    let mut out = Affine::constant(n, 0.0);
    let tokens = tokenize(expr).map_err(&err)?;
    if tokens.is_empty() {
        return Err(err("empty expression".into()));
    }
    let mut i = 0;
    while i < tokens.len() {
        // Sign of the term.
        let mut sign = 1.0;
        while let Some(Tok::Op(c @ ('+' | '-'))) = tokens.get(i) {
            if *c == '-' {
                sign = -sign;
            }
            i += 1;
        }
        // Factors joined by * and /.
        let mut value = sign;
        let mut joint: Option<usize> = None;
        let mut expect_factor = true;
        let mut divide = false;
        while i < tokens.len() {
            match &tokens[i] {
                Tok::Op('+' | '-') if !expect_factor => break,
                Tok::Op(c @ ('*' | '/')) if !expect_factor => {
                    divide = *c == '/';
                    expect_factor = true;
                }
                Tok::Num(x) if expect_factor => {
                    value = if divide { value / x } else { value * x };
                    expect_factor = false;
                }
                Tok::Ident(name) if expect_factor => {
                    if let Some(k) = scope.joint(name) {
                        if divide {
                            return Err(err(format!("cannot divide by joint `{name}`")));
                        }
                        if joint.replace(k).is_some() {
                            return Err(err("a product of two joints is not affine".into()));
                        }
                    } else {
                        let x = if name == "pi" {
                            std::f64::consts::PI
                        } else if let Some(v) = scope.parameters.get(name) {
                            *v
                        } else {
                            let mut valid: Vec<String> = vec!["pi".into()];
                            valid.extend(scope.parameters.keys().cloned());
                            valid.extend(scope.joints.iter().cloned());
                            valid.push(format!("q1..q{n}"));
                            return Err(err(format!("unknown name `{name}` (valid: {})", valid.join(", "))));
                        };
                        value = if divide { value / x } else { value * x };
                    }
                    expect_factor = false;
                }
                t => return Err(err(format!("unexpected {t:?}"))),
            }
            i += 1;
        }
        if expect_factor {
            return Err(err("expression ends where a number or name belongs".into()));
        }
        if !value.is_finite() {
            return Err(err(format!("term evaluates to {value}")));
        }
        match joint {
            Some(k) => out.coef[k] += value,
            None => out.offset += value,
        }
    }
    Ok(out)
}

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    Ident(String),
    Op(char),
}

fn tokenize(s: &str) -> std::result::Result<Vec<Tok>, String> {
    let mut out = Vec::new();
    let chars: Vec<char> = s.chars().collect();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        if c.is_whitespace() {
            i += 1;
        } else if "+-*/".contains(c) {
            out.push(Tok::Op(c));
            i += 1;
        } else if c.is_ascii_digit() || c == '.' {
            let start = i;
            while i < chars.len()
                && (chars[i].is_ascii_digit()
                    || chars[i] == '.'
                    || chars[i] == 'e'
                    || chars[i] == 'E'
                    || ((chars[i] == '-' || chars[i] == '+') && matches!(chars[i - 1], 'e' | 'E')))
            {
                i += 1;
            }
            let text: String = chars[start..i].iter().collect();
            out.push(Tok::Num(text.parse().map_err(|_| format!("`{text}` is not a number"))?));
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push(Tok::Ident(chars[start..i].iter().collect()));
        } else {
            return Err(format!("unexpected character `{c}`"));
        }
    }
    Ok(out)
}
