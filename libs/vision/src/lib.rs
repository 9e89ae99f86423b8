//! robotd's vision library: objects from a camera's pixels, in robot coordinates.
//!
//! The Python stack sends each frame to a GPU detector and then asks the robot, over TCP,
//! where each pixel lies on the table. robotd does both itself on the CPU:
//!
//! - [`markers`] finds the workspace sheet's ring markers in the frame (each checked for its
//!   concentric rings by [`rings`]) and the fours of them that can make a sheet; when they
//!   give no sheet, [`blurred_markers`] looks again for markers too blurred or too small for
//!   their rings to show ([`disc_scan`] proposes, [`ring_fit`] fits the designs' blurred
//!   profiles of [`ring_model`]);
//! - [`sheet`] proves a sheet through the homography four markers give: a pinhole camera can
//!   see the configured rectangle so, the markers are one size on the table, the white
//!   centre is between them (and, with a marker only like its design, the border shows). A
//!   workspace is found only when all of that holds;
//! - [`plane`] fits the table plane's homography to them, recovers where the camera is, and
//!   maps a pixel to the table — or to the height of an object's top face (parallax);
//! - [`background`] measures the sheet itself in each frame (its paper's colour, where its
//!   printed border ends), so that only what is not the sheet becomes an object;
//! - a [`detector::Detector`] finds the objects; the built-in [`detector::ColourDetector`]
//!   segments coloured objects on the white sheet and names them with the [`labels`] table;
//! - [`footprint`] measures every object the same way whoever found it: centre of mass,
//!   minimum-area rectangle (width along y, height along x), gripper rotation;
//! - [`pipeline::Pipeline`] is that chain for one frame. The perception actor
//!   (`actors/perception`) runs it on the bus; the Redis edge uses it to place an external
//!   detector's pixels on the table. Nothing here touches the bus.
//!
//! Nothing here looks at the simulator's ground truth: the simulated camera's pixels are all
//! it gets, as on the real robot.
//!
//! ```
//! use robotd_vision::detector::{ColourDetector, ColourDetectorSettings};
//! use robotd_vision::labels::LabelTable;
//! use robotd_vision::pipeline::Pipeline;
//! use robotd_protocol::geometry::{Point2, Pose, RobotModel};
//! use robotd_protocol::workspace::WorkspaceInfo;
//! use robotd_render::Intrinsics;
//!
//! let workspace = WorkspaceInfo {
//!     id: "niryo_ws".into(),
//!     robot: RobotModel::Ned2,
//!     upper_left: Point2::new(0.337, 0.087),
//!     lower_right: Point2::new(0.163, -0.087),
//!     observation_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
//! };
//! let detector = ColourDetector::new(LabelTable::builtin(), ColourDetectorSettings::default());
//! let pipeline = Pipeline::new(&Intrinsics::ned2().into(), vec![workspace], Box::new(detector))
//!     .unwrap();
//! assert!(pipeline.detector_labels().contains(&"pencil".to_string()));
//! ```

pub mod background;
pub mod blurred_markers;
pub mod camera;
pub mod components;
pub mod detector;
pub mod disc_scan;
pub mod external;
pub mod footprint;
pub mod groups;
pub mod labels;
pub mod markers;
pub mod pipeline;
pub mod plane;
pub mod rect;
pub mod ring_fit;
pub mod ring_model;
pub mod rings;
pub mod shade;
pub mod sheet;
pub mod spans;
pub mod still;
pub mod warped;

pub use pipeline::{Pipeline, PipelineError, SheetStatus};
