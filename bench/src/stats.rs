//! Latency statistics of the benchmarks: percentiles of sorted samples.

use std::time::Duration;

/// p-th percentile (0..=100) of sorted durations, in microseconds.
pub fn percentile_us(sorted: &[Duration], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = ((p / 100.0) * (sorted.len() - 1) as f64).round() as usize;
    sorted[rank.min(sorted.len() - 1)].as_secs_f64() * 1e6
}

/// Summary of a latency sample.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Latency {
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
}

impl Latency {
    /// Summarises `samples` (sorted in place).
    pub fn of(samples: &mut [Duration]) -> Self {
        samples.sort_unstable();
        Self {
            p50_us: percentile_us(samples, 50.0),
            p99_us: percentile_us(samples, 99.0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_pick_the_right_rank() {
        let mut samples: Vec<Duration> = (1..=100).map(Duration::from_micros).collect();
        let latency = Latency::of(&mut samples);
        assert!((latency.p50_us - 50.0).abs() <= 1.0, "{}", latency.p50_us);
        assert!((latency.p99_us - 99.0).abs() <= 1.0, "{}", latency.p99_us);
        assert!(percentile_us(&[], 50.0).is_nan());
    }
}
