//! A joint path followed in time, for drivers that stream a motion tick by tick.
//!
//! A motion is a list of joint waypoints (one goal, or the dense waypoints of a straight tool
//! path). Each segment between two waypoints takes the time its joints need at their velocity
//! limits, divided by the policy's speed scale, and starts when the one before it ended. At each
//! control tick a driver asks [`TimedPath::sample`] where the arm should be now.
//!
//! Time, not ticks, decides: a segment shorter than a tick is passed within the tick, so a path
//! of many short segments takes the time its speed gives it, not one tick per waypoint (a
//! 100-waypoint lowering at 100 Hz would otherwise last at least a second, whatever its length).
//! The waypoints passed since the last sample are returned too, for a simulator that moves the
//! tool through each of them.

/// Where the arm should be at one moment of a [`TimedPath`].
#[derive(Debug, Clone, PartialEq)]
pub struct PathSample {
    /// Waypoints reached since the previous sample, in order (the last one may equal `now`).
    pub passed: Vec<Vec<f64>>,
    /// The joints now: on the current segment, or the last waypoint once finished.
    pub now: Vec<f64>,
    /// Whether the last waypoint is reached.
    pub finished: bool,
}

/// The time of one segment, seconds (joints from, joints to).
type SegmentTime = Box<dyn Fn(&[f64], &[f64]) -> f64 + Send + Sync>;

/// A joint path from the arm's present joints through waypoints, timed segment by segment.
pub struct TimedPath {
    from: Vec<f64>,
    waypoints: std::vec::IntoIter<Vec<f64>>,
    to: Option<Vec<f64>>,
    /// Seconds since the start at which the current segment began.
    segment_start_s: f64,
    segment_s: f64,
    smooth: bool,
    duration_s: SegmentTime,
}

impl std::fmt::Debug for TimedPath {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TimedPath")
            .field("from", &self.from)
            .field("to", &self.to)
            .field("segment_start_s", &self.segment_start_s)
            .field("segment_s", &self.segment_s)
            .finish_non_exhaustive()
    }
}

impl TimedPath {
    /// The path from `start` through `waypoints`; `segment_s(a, b)` is the time of the segment
    /// from `a` to `b` in seconds (0 or less: reached at once). With `smooth`, each segment
    /// starts and stops gently (a cubic profile); otherwise it runs at constant speed.
    pub fn new(
        start: Vec<f64>,
        waypoints: Vec<Vec<f64>>,
        smooth: bool,
        segment_s: impl Fn(&[f64], &[f64]) -> f64 + Send + Sync + 'static,
    ) -> Self {
        let mut waypoints = waypoints.into_iter();
        let to = waypoints.next();
        let first_s = to.as_ref().map_or(0.0, |to| segment_s(&start, to));
        Self {
            from: start,
            waypoints,
            to,
            segment_start_s: 0.0,
            segment_s: first_s,
            smooth,
            duration_s: Box::new(segment_s),
        }
    }

    /// Where the arm should be `elapsed_s` seconds after the start (never earlier than the
    /// previous sample's time).
    pub fn sample(&mut self, elapsed_s: f64) -> PathSample {
        let mut passed = Vec::new();
        loop {
            let Some(to) = &self.to else {
                return PathSample {
                    now: passed.last().cloned().unwrap_or_else(|| self.from.clone()),
                    passed,
                    finished: true,
                };
            };
            let into_segment_s = elapsed_s - self.segment_start_s;
            if into_segment_s < self.segment_s {
                let tau = (into_segment_s / self.segment_s).max(0.0);
                let s = if self.smooth {
                    tau * tau * (3.0 - 2.0 * tau)
                } else {
                    tau
                };
                let now = self
                    .from
                    .iter()
                    .zip(to)
                    .map(|(a, b)| a + (b - a) * s)
                    .collect();
                return PathSample {
                    passed,
                    now,
                    finished: false,
                };
            }
            // This segment is over: the next one starts when it ended.
            self.segment_start_s += self.segment_s.max(0.0);
            let reached = self.to.take().unwrap_or_default();
            self.to = self.waypoints.next();
            if let Some(next) = &self.to {
                self.segment_s = (self.duration_s)(&reached, next);
            }
            passed.push(reached.clone());
            self.from = reached;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One second per radian of the largest joint change.
    fn one_s_per_rad(a: &[f64], b: &[f64]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (y - x).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn many_short_segments_are_passed_within_one_sample() {
        // 100 segments of 0.01 rad: one second in all, whatever the tick.
        let waypoints: Vec<Vec<f64>> = (1..=100).map(|i| vec![f64::from(i) * 0.01]).collect();
        let mut path = TimedPath::new(vec![0.0], waypoints, false, one_s_per_rad);
        let first = path.sample(0.255);
        assert_eq!(first.passed.len(), 25);
        assert!((first.now[0] - 0.255).abs() < 1e-9, "{first:?}");
        assert!(!first.finished);
        let last = path.sample(1.0);
        assert_eq!(last.passed.len(), 75);
        assert!((last.now[0] - 1.0).abs() < 1e-9);
        assert!(last.finished);
        let after = path.sample(2.0);
        assert!(after.finished && after.passed.is_empty());
        assert!((after.now[0] - 1.0).abs() < 1e-9);
    }

    #[test]
    fn a_smooth_segment_starts_and_ends_gently() {
        let mut path = TimedPath::new(vec![0.0, 0.0], vec![vec![2.0, 1.0]], true, one_s_per_rad);
        let early = path.sample(0.2);
        // The cubic profile at a tenth of the way: 0.028 of the distance, not 0.1.
        assert!((early.now[0] - 2.0 * 0.028).abs() < 1e-9, "{early:?}");
        assert!((early.now[1] - 0.028).abs() < 1e-9);
        let middle = path.sample(1.0);
        assert!((middle.now[0] - 1.0).abs() < 1e-9);
        assert!(path.sample(2.0).finished);
    }

    #[test]
    fn a_segment_of_no_time_and_an_empty_path_are_reached_at_once() {
        let mut path = TimedPath::new(vec![0.5], vec![vec![0.5], vec![0.7]], false, one_s_per_rad);
        let start = path.sample(0.0);
        assert_eq!(start.passed, vec![vec![0.5]]);
        assert!(!start.finished);
        let mut empty = TimedPath::new(vec![0.3], vec![], true, one_s_per_rad);
        let sample = empty.sample(0.0);
        assert!(sample.finished);
        assert_eq!(sample.now, vec![0.3]);
    }
}
