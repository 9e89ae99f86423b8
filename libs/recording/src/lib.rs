//! # robotd-recording: robotd's recordings, read back
//!
//! `robotd record` and `robotd serve`'s `[record]` write the bus into MCAP files (the Foxglove
//! edge's bridge does the writing). Two things read them back: `robotd replay`, which publishes
//! a file onto a bus, and the replay robot driver (`robot.driver = "replay"`), which plays a
//! file as the robot. Both need the same few things, and they live here, below both (a driver
//! must not depend on an edge):
//!
//! - [`reader`]: the messages of a file in the order they were written, one at a time, from a
//!   buffered file: a recording of a gigabyte is never in memory at once;
//! - [`camera`]: a camera frame put back together from its two channels (`/camera`, the JPEG;
//!   `/camera/meta`, its header) and decoded with robotd's one JPEG decoder;
//! - [`contents`]: what a file holds (messages per channel, time span, the robot it was
//!   recorded on, the first arm state), from one pass over it, for the checks a replay makes
//!   before it starts and for `robotd doctor`.
//!
//! The channel names are constants here, and the bridge writes with them, so writer and
//! readers cannot drift apart:
//!
//! | channel | holds |
//! |---|---|
//! | [`CAMERA`] | `foxglove.CompressedImage`, JPEG |
//! | [`CAMERA_META`] | JSON [`camera::FrameMeta`]: frame id, capture time, size, camera pose, intrinsics |
//! | [`ROBOT_DESCRIPTION`] | JSON `{"data": <URDF>}`: which robot it was |
//! | [`bus_channel`]`(topic)` | JSON of each bus message, e.g. `/bus/arm/state` |
//!
//! ```no_run
//! # fn demo() -> Result<(), robotd_recording::reader::ReadError> {
//! use robotd_recording::{contents::Contents, reader::Messages};
//! let path = std::path::Path::new("session.mcap");
//! let contents = Contents::inspect(path)?;
//! println!("{}", contents.describe());
//! for message in Messages::open(path)? {
//!     let message = message?;
//!     println!("{} at {} ns: {} bytes", message.topic, message.log_time, message.data.len());
//! }
//! # Ok(()) }
//! ```

pub mod camera;
pub mod contents;
pub mod reader;

/// The camera images, JPEG (`foxglove.CompressedImage`).
pub const CAMERA: &str = "/camera";
/// The header of each camera image, logged right after it at the same time.
pub const CAMERA_META: &str = "/camera/meta";
/// The robot's URDF, once a second.
pub const ROBOT_DESCRIPTION: &str = "/robot_description";

/// The channel of a bus topic in a recording: `/bus/<topic>`.
pub fn bus_channel(topic: &str) -> String {
    format!("/bus/{topic}")
}

/// The channel of `arm/state`.
pub const ARM_STATE: &str = "/bus/arm/state";
/// The channel of `gripper/state`.
pub const GRIPPER_STATE: &str = "/bus/gripper/state";

#[cfg(any(test, feature = "fixture"))]
pub mod fixture;

#[cfg(test)]
mod fuzz;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_state_channels_are_bus_channels() {
        assert_eq!(ARM_STATE, bus_channel("arm/state"));
        assert_eq!(GRIPPER_STATE, bus_channel("gripper/state"));
    }
}
