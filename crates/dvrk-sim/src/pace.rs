//! Pacing simulated time to the wall clock: the one loop timing of a live run, `dvrk sim
//! --realtime` (the Foxglove view) and `dvrk serve` (ROS 2) alike.

use std::time::{Duration, Instant};

/// Keeps simulated time at `factor` times the wall clock since its start.
#[derive(Debug, Clone)]
pub struct Pacer {
    start: Instant,
    factor: f64,
    worst_lag: f64,
}

impl Pacer {
    /// Simulated time behind the wall clock is not counted as lag during the first simulated
    /// second (start-up: discovery, the first messages).
    const SETTLE: f64 = 1.0;

    /// Start the clock now; `factor` 1 is real time.
    pub fn new(factor: f64) -> Pacer {
        Pacer { start: Instant::now(), factor, worst_lag: 0.0 }
    }

    /// Sleep until the wall clock reaches simulated time `t` (s) over the factor; when the
    /// simulation is behind instead, remember by how much (after its first second).
    pub fn wait(&mut self, t: f64) {
        let ahead = t / self.factor - self.start.elapsed().as_secs_f64();
        if ahead > 1e-4 {
            std::thread::sleep(Duration::from_secs_f64(ahead));
        } else if t > Self::SETTLE {
            self.worst_lag = self.worst_lag.max(-ahead);
        }
    }

    /// The furthest the simulation fell behind the wall clock (s, wall time).
    pub fn worst_lag(&self) -> f64 {
        self.worst_lag
    }

    /// Wall-clock time since the start (s).
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_paced_run_takes_its_simulated_time_and_a_late_one_counts_its_lag() {
        let mut p = super::Pacer::new(2.0);
        p.wait(0.2); // 0.2 s simulated at twice real time: 0.1 s of wall time
        let e = p.elapsed();
        assert!((0.0999..0.3).contains(&e), "{e}");
        assert_eq!(p.worst_lag(), 0.0);
        // At 100 times real time, 1.2 s simulated is due at 12 ms; 40 ms have passed: lag.
        let mut late = super::Pacer::new(100.0);
        std::thread::sleep(std::time::Duration::from_millis(40));
        late.wait(0.5); // within the first simulated second: not counted
        assert_eq!(late.worst_lag(), 0.0);
        late.wait(1.2);
        assert!((0.027..0.2).contains(&late.worst_lag()), "{}", late.worst_lag());
    }
}
