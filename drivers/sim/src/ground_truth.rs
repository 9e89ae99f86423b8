//! `sim/world`: the simulator's ground truth on the bus, for tests, benchmarks and dashboards.
//!
//! Perception never reads it (it sees pixels only); it answers "where is every object really,
//! and is it held?", so a test can check what the robot did against what really happened.

use crate::SimRobot;
use robotd_protocol::diagnostics::{SimObjectState, SimWorldReply};
use robotd_runtime::bus::{Bus, BusError};

/// Serves `sim/world` for `robot` until the task is aborted.
pub fn serve_ground_truth(
    bus: &Bus,
    robot: SimRobot,
) -> Result<tokio::task::JoinHandle<()>, BusError> {
    let mut server = bus.server(&robotd_topics::SIM_WORLD)?;
    Ok(tokio::spawn(async move {
        let served = server
            .serve(move |_request| {
                let reply = robot.with_world(|world| SimWorldReply {
                    scene: world.scene_name().to_owned(),
                    objects: world
                        .objects()
                        .iter()
                        .map(|o| SimObjectState {
                            label: o.spec.label.clone(),
                            x_m: o.pose.translation.x,
                            y_m: o.pose.translation.y,
                            z_m: o.pose.translation.z,
                            yaw_rad: o.yaw_rad(),
                            bottom_z_m: o.bottom_z(),
                            top_z_m: o.top_z(),
                            held: o.held,
                        })
                        .collect(),
                });
                async move { Ok(reply) }
            })
            .await;
        if let Err(error) = served {
            tracing::warn!(%error, "the sim/world service stopped");
        }
    }))
}
