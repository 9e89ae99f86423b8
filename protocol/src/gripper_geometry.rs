//! The gripper's solid sizes: one set of numbers for the simulator that collides with them and
//! the skills that plan around them.
//!
//! Both robots carry a two-finger parallel gripper. Seen from the tool centre point (between
//! the fingertips, the tool pointing down): the fingers close along one horizontal axis, each
//! finger is `finger_thickness_m` thick along it and `finger_width_m` wide across it, and
//! reaches `finger_length_m` up from the fingertips; the palm sits on top of the fingers. A
//! planner that checks the space the open fingers and the palm sweep with these numbers checks
//! what the simulator (and, as far as the numbers are right, the robot) will touch.
//!
//! ```
//! use robotd_protocol::gripper_geometry::GripperGeometry;
//! use robotd_protocol::RobotModel;
//!
//! let ned2 = GripperGeometry::for_model(RobotModel::Ned2);
//! assert_eq!(ned2.max_opening_m, 0.040);
//! // The open fingers sweep 28 mm each side of the tool centre along the closing axis.
//! assert!((ned2.open_reach_m() - 0.028).abs() < 1e-12);
//! ```

use crate::geometry::RobotModel;

/// Sizes of a two-finger parallel gripper, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperGeometry {
    /// Largest distance between the fingers' inner faces.
    pub max_opening_m: f64,
    /// Finger thickness along the closing axis.
    pub finger_thickness_m: f64,
    /// Finger width across the closing axis.
    pub finger_width_m: f64,
    /// Finger length along the tool axis, from the fingertips (the tool centre) up.
    pub finger_length_m: f64,
    /// Palm box: `[along the tool axis, along the closing axis, across]`.
    pub palm_m: [f64; 3],
}

impl GripperGeometry {
    /// The gripper of `model`.
    ///
    /// - Ned2 ("Gripper 1"): 0.040 m maximum opening, fingers 8 × 18 × 35 mm, palm
    ///   30 × 60 × 30 mm.
    /// - WidowX 250: each finger's prismatic joint runs 0.015 … 0.037 m from the centre and the
    ///   fingers touch at 0.015, so the opening between the pads is 2 × (joint − 0.015) =
    ///   0 … 0.044 m; fingers 8 × 20 × 40 mm, palm 30 × 70 × 35 mm (approximate).
    pub fn for_model(model: RobotModel) -> Self {
        match model {
            RobotModel::Ned2 => Self {
                max_opening_m: 0.040,
                finger_thickness_m: 0.008,
                finger_width_m: 0.018,
                finger_length_m: 0.035,
                palm_m: [0.030, 0.060, 0.030],
            },
            RobotModel::WidowX250 => Self {
                max_opening_m: 0.044,
                finger_thickness_m: 0.008,
                finger_width_m: 0.020,
                finger_length_m: 0.040,
                palm_m: [0.030, 0.070, 0.035],
            },
        }
    }

    /// How far the fully open fingers reach from the tool centre along the closing axis.
    pub fn open_reach_m(&self) -> f64 {
        self.max_opening_m / 2.0 + self.finger_thickness_m
    }
}
