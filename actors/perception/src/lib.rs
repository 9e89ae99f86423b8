//! robotd's eyes on the bus: the perception actor reads the wrist camera's frames in shared
//! memory (`camera/frames`), runs the vision pipeline of `libs/vision` ([`robotd_vision`]:
//! markers, table plane, detector, footprints) on each, and publishes the objects in robot
//! coordinates on `perception/detections`, at frame rate.
//!
//! The vision modules are re-exported here under their usual names (`robotd_perception::
//! detector`, …). Nothing here looks at the simulator's ground truth: the simulated camera's
//! pixels are all it gets, as on the real robot (the `eval` feature scores it against ground
//! truth for tests and `robotd bench perception`).

pub mod config;
pub use config::PerceptionConfig;

pub mod actor;
#[cfg(feature = "eval")]
pub mod eval;
pub mod external_detections;
pub mod held_object;

pub use robotd_vision::{
    camera, components, detector, external, footprint, labels, markers, pipeline, plane, rect,
};

pub use actor::{Perception, PerceptionStartError, PerceptionStats, WorkspaceView};
pub use pipeline::{Pipeline, PipelineError, SheetStatus};
