//! The gripper's solid parts: two fingers and a palm, as boxes in the tool centre point frame.
//!
//! TCP frame: +x along the tool (from the palm towards the fingertips), the fingers close along
//! ±y, z completes the right-handed frame. The fingertips are at the TCP; each finger reaches
//! back `finger_length_m` along −x, its inner face at ±opening/2 along y; the palm sits behind
//! the fingers.

use nalgebra::{Isometry3, Translation3, Vector3};
use robotd_protocol::geometry::RobotModel;

/// Sizes of a two-finger parallel gripper, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperGeometry {
    /// Largest distance between the fingers' inner faces.
    pub max_opening_m: f64,
    /// Finger thickness along the closing axis (TCP y).
    pub finger_thickness_m: f64,
    /// Finger width across the closing axis (TCP z).
    pub finger_width_m: f64,
    /// Finger length along the tool axis (TCP x).
    pub finger_length_m: f64,
    /// Palm box: `[along the tool axis (x), along the closing axis (y), across (z)]`.
    pub palm_m: [f64; 3],
}

impl GripperGeometry {
    /// The gripper of `model`.
    ///
    /// - Ned2 ("Gripper 1"): 0.040 m maximum opening (docs/robot-models.md), fingers 8 × 18 × 35 mm, palm
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

    /// The three solid boxes of the gripper with the TCP at `tcp` and the fingers `opening_m`
    /// apart: left finger (+y), right finger (−y), palm.
    pub fn boxes(&self, tcp: &Isometry3<f64>, opening_m: f64) -> [GripperBox; 3] {
        let l = self.finger_length_m;
        let t = self.finger_thickness_m;
        let half_finger = Vector3::new(l / 2.0, t / 2.0, self.finger_width_m / 2.0);
        let y = opening_m / 2.0 + t / 2.0;
        let at = |x: f64, y: f64| {
            tcp * Isometry3::from_parts(Translation3::new(x, y, 0.0), Default::default())
        };
        [
            GripperBox {
                name: "left finger",
                pose: at(-l / 2.0, y),
                half_extents_m: half_finger,
            },
            GripperBox {
                name: "right finger",
                pose: at(-l / 2.0, -y),
                half_extents_m: half_finger,
            },
            GripperBox {
                name: "palm",
                pose: at(-l - self.palm_m[0] / 2.0, 0.0),
                half_extents_m: Vector3::new(
                    self.palm_m[0] / 2.0,
                    self.palm_m[1] / 2.0,
                    self.palm_m[2] / 2.0,
                ),
            },
        ]
    }
}

/// One solid box of the gripper, for collision checks and drawing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GripperBox {
    /// `"left finger"`, `"right finger"` or `"palm"`.
    pub name: &'static str,
    /// Pose of the box's centre in the world.
    pub pose: Isometry3<f64>,
    /// Half extents along the box's own axes (= the TCP axes), metres.
    pub half_extents_m: Vector3<f64>,
}
