//! # robotd-placement: where the fingers and the objects will go, checked before anything moves
//!
//! The table geometry and the planner the skills actor checks every pick, place and push
//! with ([`plan`], [`geometry`]), and the settings they read ([`SkillsSettings`]). They live
//! in a library below the actors because two actors judge the table by the same rules: the
//! skills before they move, and the workspace model when it answers where an object can go
//! (free space) and which object stands on which (stacks). One copy of the rules means the
//! answer a client gets is a place the skills accept.
//!
//! ```
//! use robotd_placement::{geometry, SkillsSettings};
//! use robotd_protocol::RobotModel;
//!
//! let settings = SkillsSettings::new(RobotModel::Ned2, Vec::new());
//! assert!(settings.gripper_max_width_m > 0.0);
//! assert!(geometry::STACK_SUPPORT_TOLERANCE_M > 0.0);
//! ```

pub mod geometry;
pub mod plan;
#[cfg(test)]
#[path = "plan/heights.rs"]
mod plan_heights;
mod settings;

pub use settings::SkillsSettings;
