//! The geofence: where the tool centre point may be.
//!
//! The allowed space is one box: the rectangle spanning every configured workspace, their
//! observation poses and the arm's rest pose, grown by `fence_margin_m`, from the table floor
//! up to the ceiling — minus the keep-out boxes, and within the reach of the base axis. A
//! point outside gets a refusal that names the limit and the value, e.g. "the tool centre
//! would go to z -0.030 m, below the table floor 0.000 m".

use crate::config::{KeepOutBox, SafetyConfig};
use nalgebra::Vector3;
use robotd_kinematics::BodyBox;
use std::fmt;

/// Which limit a point or motion broke, for refusals and the audit log.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// The limit's short name (`floor`, `fence`, `keep_out`, `reach`, `joint_limit`, …).
    pub limit: &'static str,
    /// What a user can act on.
    pub reason: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.reason)
    }
}

/// The space the tool centre point may occupy.
#[derive(Debug, Clone, PartialEq)]
pub struct Fence {
    /// Lowest corner of the allowed box.
    pub min: Vector3<f64>,
    /// Highest corner of the allowed box.
    pub max: Vector3<f64>,
    /// Farthest distance from the base's vertical axis, metres.
    pub max_reach_m: f64,
    /// Boxes never to enter.
    pub keep_out: Vec<KeepOutBox>,
}

impl Fence {
    /// The fence around `points` (workspace corners, observation and rest poses, `[x, y]`
    /// metres) grown by the configured margin, between the floor and the ceiling.
    /// `model_reach_m` is used when the configuration leaves `max_reach_m` at 0.
    pub fn around(points: &[[f64; 2]], config: &SafetyConfig, model_reach_m: f64) -> Self {
        let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points.iter().filter(|p| p.iter().all(|v| v.is_finite())) {
            for axis in 0..2 {
                min[axis] = min[axis].min(p[axis]);
                max[axis] = max[axis].max(p[axis]);
            }
        }
        if !min[0].is_finite() {
            // Nothing configured: an empty fence refuses every motion.
            (min, max) = ([0.0; 2], [0.0; 2]);
        }
        let m = config.fence_margin_m;
        Fence {
            min: Vector3::new(min[0] - m, min[1] - m, config.floor_z_m),
            max: Vector3::new(max[0] + m, max[1] + m, config.ceiling_z_m),
            max_reach_m: if config.max_reach_m > 0.0 {
                config.max_reach_m
            } else {
                model_reach_m
            },
            keep_out: config.keep_out.clone(),
        }
    }

    /// `Ok` when the tool centre may be at `p` (metres, base frame).
    pub fn check(&self, p: &Vector3<f64>) -> Result<(), Violation> {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(Violation {
                limit: "finite",
                reason: format!(
                    "the tool centre position ({}, {}, {}) is not finite",
                    p.x, p.y, p.z
                ),
            });
        }
        if p.z < self.min.z {
            return Err(Violation {
                limit: "floor",
                reason: format!(
                    "the tool centre would go to z {:.3} m, below the table floor {:.3} m",
                    p.z, self.min.z
                ),
            });
        }
        if p.z > self.max.z {
            return Err(Violation {
                limit: "ceiling",
                reason: format!(
                    "the tool centre would go to z {:.3} m, above the ceiling {:.3} m",
                    p.z, self.max.z
                ),
            });
        }
        for (axis, name) in [(0, "x"), (1, "y")] {
            if p[axis] < self.min[axis] || p[axis] > self.max[axis] {
                return Err(Violation {
                    limit: "fence",
                    reason: format!(
                        "the tool centre would go to {name} {:.3} m, outside the geofence {name} {:.3} … {:.3} m (the workspaces plus the margin)",
                        p[axis], self.min[axis], self.max[axis]
                    ),
                });
            }
        }
        let reach = p.xy().norm();
        if reach > self.max_reach_m {
            return Err(Violation {
                limit: "reach",
                reason: format!(
                    "the tool centre would be {reach:.3} m from the base axis, beyond the reach limit {:.3} m",
                    self.max_reach_m
                ),
            });
        }
        for keep_out in &self.keep_out {
            if (0..3).all(|a| p[a] >= keep_out.min[a] && p[a] <= keep_out.max[a]) {
                return Err(Violation {
                    limit: "keep_out",
                    reason: format!(
                        "the tool centre would enter the keep-out box '{}' at ({:.3}, {:.3}, {:.3}) m",
                        keep_out.name, p.x, p.y, p.z
                    ),
                });
            }
        }
        Ok(())
    }
}

/// How far a body is past the floor and the ceiling, metres (0 when inside).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BodyDepth {
    /// Depth of the lowest lifted box below the floor.
    pub below_floor_m: f64,
    /// Height of the highest lifted box above the ceiling.
    pub above_ceiling_m: f64,
}

impl Fence {
    /// How far `body`'s lifted links (those moved by more than the base's vertical axis) are
    /// past the floor and the ceiling.
    pub fn body_depth(&self, body: &[BodyBox]) -> BodyDepth {
        let mut depth = BodyDepth::default();
        for part in body.iter().filter(|b| b.joints_from_base >= 2) {
            let (low, high) = part.z_range();
            depth.below_floor_m = depth.below_floor_m.max(self.min.z - low);
            depth.above_ceiling_m = depth.above_ceiling_m.max(high - self.max.z);
        }
        depth
    }

    /// `Ok` when every link of `body` is inside the fence: lifted links above the floor and
    /// below the ceiling by more than `allowed` (an arm already past a limit may move as
    /// long as it goes no deeper), no moving link in a keep-out box.
    pub fn check_body(&self, body: &[BodyBox], allowed: BodyDepth) -> Result<(), Violation> {
        const EPSILON_M: f64 = 1e-6;
        for part in body.iter().filter(|b| b.joints_from_base >= 2) {
            let (low, high) = part.z_range();
            if self.min.z - low > allowed.below_floor_m.max(0.0) + EPSILON_M {
                return Err(Violation {
                    limit: "floor",
                    reason: format!(
                        "the arm's {} would go down to z {low:.3} m, below the table floor {:.3} m",
                        part.link, self.min.z
                    ),
                });
            }
            if high - self.max.z > allowed.above_ceiling_m.max(0.0) + EPSILON_M {
                return Err(Violation {
                    limit: "ceiling",
                    reason: format!(
                        "the arm's {} would go up to z {high:.3} m, above the ceiling {:.3} m",
                        part.link, self.max.z
                    ),
                });
            }
        }
        for part in body.iter().filter(|b| b.joints_from_base >= 1) {
            for keep_out in &self.keep_out {
                let (min, max) = (Vector3::from(keep_out.min), Vector3::from(keep_out.max));
                if part.overlaps_aligned_box(&min, &max) {
                    let c = part.pose.translation.vector;
                    return Err(Violation {
                        limit: "keep_out",
                        reason: format!(
                            "the arm's {} would enter the keep-out box '{}' (the link's centre at ({:.3}, {:.3}, {:.3}) m)",
                            part.link, keep_out.name, c.x, c.y, c.z
                        ),
                    });
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fence() -> Fence {
        let config = SafetyConfig {
            keep_out: vec![KeepOutBox {
                name: "camera mast".into(),
                min: [0.30, 0.05, 0.0],
                max: [0.40, 0.10, 0.5],
            }],
            ..SafetyConfig::default()
        };
        Fence::around(&[[0.337, 0.087], [0.163, -0.087]], &config, 0.44)
    }

    #[test]
    fn the_box_is_the_workspaces_plus_the_margin() {
        let f = fence();
        assert!(f.check(&Vector3::new(0.25, 0.0, 0.1)).is_ok());
        assert!(f.check(&Vector3::new(0.366, 0.0, 0.1)).is_ok());
        let e = f.check(&Vector3::new(0.25, 0.0, -0.03)).unwrap_err();
        assert_eq!(
            e.reason,
            "the tool centre would go to z -0.030 m, below the table floor 0.000 m"
        );
        assert_eq!(
            f.check(&Vector3::new(0.37, 0.0, 0.1)).unwrap_err().limit,
            "fence"
        );
        assert_eq!(
            f.check(&Vector3::new(0.25, 0.0, 0.6)).unwrap_err().limit,
            "ceiling"
        );
        assert_eq!(
            f.check(&Vector3::new(0.35, 0.07, 0.1)).unwrap_err().limit,
            "keep_out"
        );
        assert_eq!(
            f.check(&Vector3::new(f64::NAN, 0.0, 0.1))
                .unwrap_err()
                .limit,
            "finite"
        );
    }

    #[test]
    fn reach_is_measured_from_the_base_axis() {
        let mut f = fence();
        f.max_reach_m = 0.3;
        assert_eq!(
            f.check(&Vector3::new(0.29, 0.1, 0.1)).unwrap_err().limit,
            "reach"
        );
    }

    #[test]
    fn no_workspace_means_no_motion() {
        let f = Fence::around(&[], &SafetyConfig::default(), 0.44);
        assert!(f.check(&Vector3::new(0.25, 0.0, 0.1)).is_err());
    }
}
