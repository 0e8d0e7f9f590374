//! Step 1 of the workflow, "locate it": where along the motion a joint's residual is large. The
//! residual's RMS inside each regime of the motion (near reversals, at high speed, under high
//! load, at deep insertion) against its RMS over the whole analysed span; a ratio well above 1
//! points at the effects that live there (friction and play at reversals, viscous friction and
//! latency at speed, compliance under load, the tool's cable and insertion effects deep in).

use super::candidates::Table;
use super::signals::Prepared;
use serde::Serialize;

/// One joint's residual by regime, each as RMS over the joint's RMS on the whole span.
#[derive(Debug, Clone, Serialize)]
pub struct Location {
    pub joint: String,
    /// RMS over the whole analysed span, over the joint's noise floor in the band.
    pub rms: f64,
    /// Slowest 10% of the joint's samples (|velocity|): around reversals.
    pub reversals: f64,
    /// Fastest 20%.
    pub high_speed: f64,
    /// Largest 20% of the predicted effort's magnitude.
    pub high_load: f64,
    /// Deepest 20% of the insertion (arms with a prismatic joint).
    pub deep_insertion: Option<f64>,
    /// The regime whose ratio is largest, when it is at least 1.5.
    pub worst: Option<String>,
}

/// RMS of `r[i][k]` over the samples `keep` selects.
fn rms_where(r: &Table, k: usize, keep: &[bool]) -> f64 {
    let (s, n) = r.iter().zip(keep).filter(|(_, k)| **k).fold((0.0, 0usize), |(s, n), (row, _)| (s + row[k] * row[k], n + 1));
    (s / n.max(1) as f64).sqrt()
}

/// Samples whose `value` is at or above its `q` quantile (`above`), or at or below it.
fn quantile_mask(value: &[f64], q: f64, above: bool) -> Vec<bool> {
    let mut sorted = value.to_vec();
    sorted.sort_by(f64::total_cmp);
    let cut = sorted[((sorted.len() - 1) as f64 * q).round() as usize];
    value.iter().map(|v| if above { *v >= cut } else { *v <= cut }).collect()
}

/// Each active joint's residual `r` (`[sample][joint]`) by regime, with the prediction `load`;
/// `insertion`: the prismatic joint, if the arm has one; `names`: the joints' names.
pub fn locate(prep: &Prepared, r: &Table, load: &Table, insertion: Option<usize>, names: &[String]) -> Vec<Location> {
    let magnitude = |t: &Table, k: usize| -> Vec<f64> { super::signals::column(t, k).iter().map(|v| v.abs()).collect() };
    let deep = insertion.map(|j| quantile_mask(&super::signals::column(&prep.q, j), 0.8, true));
    prep.active
        .iter()
        .map(|&k| {
            let all = vec![true; r.len()];
            let total = rms_where(r, k, &all).max(1e-300);
            let ratio = |mask: &[bool]| rms_where(r, k, mask) / total;
            let speed = magnitude(&prep.qd, k);
            let (reversals, high_speed) = (ratio(&quantile_mask(&speed, 0.1, false)), ratio(&quantile_mask(&speed, 0.8, true)));
            let high_load = ratio(&quantile_mask(&magnitude(load, k), 0.8, true));
            let deep_insertion = deep.as_ref().map(|m| ratio(m));
            let mut regimes = vec![("reversals", reversals), ("high_speed", high_speed), ("high_load", high_load)];
            regimes.extend(deep_insertion.map(|d| ("deep_insertion", d)));
            let worst = regimes.iter().filter(|(_, v)| *v >= 1.5).max_by(|a, b| a.1.total_cmp(&b.1)).map(|(n, _)| n.to_string());
            Location { joint: names[k].clone(), rms: total / prep.floor[k], reversals, high_speed, high_load, deep_insertion, worst }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_masks_pick_the_tails() {
        let v: Vec<f64> = (0..100).map(|i| i as f64).collect();
        assert_eq!(quantile_mask(&v, 0.8, true).iter().filter(|x| **x).count(), 21);
        assert_eq!(quantile_mask(&v, 0.1, false).iter().filter(|x| **x).count(), 11);
        // A residual that lives only where the mask is: the ratio is sqrt(n / n_mask).
        let r: Table = (0..100).map(|i| vec![if i >= 80 { 1.0 } else { 0.0 }]).collect();
        let m = quantile_mask(&v, 0.8, true);
        let ratio = rms_where(&r, 0, &m) / rms_where(&r, 0, &vec![true; 100]);
        assert!((ratio - (20.0f64 / 21.0 * 100.0 / 20.0).sqrt()).abs() < 1e-12, "{ratio}");
    }
}
