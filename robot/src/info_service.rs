//! `system/hardware`: the running robot answers what it is — driver, camera intrinsics,
//! versions, e-stop — on the bus, to tools that must not connect to the robot themselves
//! while robotd holds it (a Ned2 serves one client, a servo bus has one master).
//! `robotd commission` attached to a running robotd asks here.

use robotd_driver::ArmDriver;
use robotd_protocol::camera::CameraIntrinsics;
use robotd_protocol::hardware::HardwareReport;
use robotd_runtime::bus::{Bus, BusError};
use robotd_safety::Safety;
use std::sync::Arc;

/// Serves `system/hardware` for the robot behind `driver` until the task is aborted.
pub fn serve(
    bus: &Bus,
    driver_name: String,
    driver: Arc<dyn ArmDriver>,
    intrinsics: CameraIntrinsics,
    safety: Safety,
) -> Result<tokio::task::JoinHandle<()>, BusError> {
    let mut server = bus.server(&robotd_topics::SYSTEM_HARDWARE)?;
    Ok(tokio::spawn(async move {
        let served = server
            .serve(move |_query| {
                let (driver, driver_name) = (driver.clone(), driver_name.clone());
                let (intrinsics, estop) = (intrinsics.clone(), safety.estop());
                async move {
                    Ok(HardwareReport {
                        driver: driver_name,
                        intrinsics,
                        versions: driver.hardware_info().await.map_err(|e| e.to_string()),
                        estop,
                    })
                }
            })
            .await;
        if let Err(error) = served {
            tracing::error!(%error, "the system/hardware service stopped");
        }
    }))
}
