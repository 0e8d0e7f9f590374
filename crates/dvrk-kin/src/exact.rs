//! Fixed-size numbers read exactly from model, inertials and scene files: serde reads a
//! `[f64; 3]` from the first three entries of a longer list without a word (an inertia of four
//! rows was read as its first three, issue 45). Each function is a `deserialize_with` for one
//! shape, and says the shape it found.

use serde::de::Error;
use serde::{Deserialize, Deserializer};

fn exact<E: Error, const N: usize>(v: Vec<f64>, what: &str) -> Result<[f64; N], E> {
    let n = v.len();
    v.try_into().map_err(|_| E::custom(format!("{n} numbers where {what} has {N}")))
}

fn rows<'de, D: Deserializer<'de>, const R: usize, const C: usize>(d: D, what: &str) -> Result<[[f64; C]; R], D::Error> {
    let v: Vec<Vec<f64>> = Vec::deserialize(d)?;
    if v.len() != R || v.iter().any(|r| r.len() != C) {
        let shape: Vec<String> = v.iter().map(|r| r.len().to_string()).collect();
        return Err(D::Error::custom(format!("{} rows of [{}] numbers where {what} has {R} rows of {C}", v.len(), shape.join(", "))));
    }
    let mut out = [[0.0; C]; R];
    for (o, r) in out.iter_mut().zip(v) {
        *o = exact(r, what)?;
    }
    Ok(out)
}

/// Three numbers (a point or vector, m).
pub fn vec3<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
    exact(Vec::deserialize(d)?, "a 3-vector")
}

/// A 3x3 matrix, row-major (an inertia, kg m^2).
pub fn mat3<'de, D: Deserializer<'de>>(d: D) -> Result<[[f64; 3]; 3], D::Error> {
    rows::<D, 3, 3>(d, "a 3x3 matrix")
}

/// A 4x4 matrix, row-major (a homogeneous transform, m).
pub fn mat4<'de, D: Deserializer<'de>>(d: D) -> Result<[[f64; 4]; 4], D::Error> {
    rows::<D, 4, 4>(d, "a 4x4 transform")
}

/// [`vec3`] of an optional field (with `#[serde(default)]`).
pub fn opt_vec3<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[f64; 3]>, D::Error> {
    vec3(d).map(Some)
}

/// [`mat4`] of an optional field (with `#[serde(default)]`).
pub fn opt_mat4<'de, D: Deserializer<'de>>(d: D) -> Result<Option<[[f64; 4]; 4]>, D::Error> {
    mat4(d).map(Some)
}
