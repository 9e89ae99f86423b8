//! The gripper's solid parts: two fingers and a palm, as boxes in the tool centre point frame.
//!
//! TCP frame: +x along the tool (from the palm towards the fingertips), the fingers close along
//! ±y, z completes the right-handed frame. The fingertips are at the TCP; each finger reaches
//! back `finger_length_m` along −x, its inner face at ±opening/2 along y; the palm sits behind
//! the fingers.

use nalgebra::{Isometry3, Translation3, Vector3};

pub use robotd_protocol::gripper_geometry::GripperGeometry;

/// The gripper's solid boxes for a [`GripperGeometry`] (whose numbers live in
/// `robotd_protocol`, shared with the skills' planner).
pub trait GripperBoxes {
    /// The three solid boxes of the gripper with the TCP at `tcp` and the fingers `opening_m`
    /// apart: left finger (+y), right finger (−y), palm.
    fn boxes(&self, tcp: &Isometry3<f64>, opening_m: f64) -> [GripperBox; 3];
}

impl GripperBoxes for GripperGeometry {
    fn boxes(&self, tcp: &Isometry3<f64>, opening_m: f64) -> [GripperBox; 3] {
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
