//! # robotd-foxglove: robotd in the Foxglove app, live and recorded
//!
//! Roboticists look at robots in Foxglove; its file format, MCAP, is what ROS 2 bags default to.
//! This crate puts robotd there on the Foxglove SDK (no hand-written protocol):
//!
//! - [`bridge`]: one thread reading the bus and logging camera images, the arm's transforms,
//!   joint states, model (URDF) and a drawing of it, the objects and workspaces as 3D scenes,
//!   logs, and every bus topic as JSON, into a Foxglove context;
//! - [`live`]: the WebSocket server the Foxglove app connects to (`[foxglove] bind`), fed by
//!   the bridge;
//! - [`record`]: the same channels into an MCAP file (`robotd record`);
//! - [`replay`]: an MCAP file published back on the bus (`robotd replay`);
//! - [`urdf`]: the links and joints of the robot model, as the bridge needs them.
//!
//! `config/foxglove-layout.json` is a layout that opens the useful panels (import it in the
//! app: Layouts → Import).

pub mod always_on;
pub mod bridge;
pub mod config;
pub mod live;
pub mod record;
pub mod replay;
pub mod scene;
pub mod topics;
pub mod urdf;

pub use config::{FoxgloveConfig, RecordConfig};
