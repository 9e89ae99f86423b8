//! `system/hardware`: the running robot answers what it is — driver, camera intrinsics,
//! versions, e-stop — on the bus, to tools that must not connect to the robot themselves
//! while robotd holds it (a Ned2 serves one client, a servo bus has one master).
//! `robotd commission` attached to a running robotd asks here.
//!
//! Any bus client may ask, as often as it likes, so an answer costs the robot nothing it
//! needs: the e-stop is the policy's latch, the intrinsics are the camera driver's (as it
//! knows them now: a Ned2 sends its own when it connects), and the versions — on a WidowX
//! eighteen servo reads queued between the control loop's — are read once and reused for
//! [`VERSIONS_FRESH`].

use robotd_driver::{ArmDriver, CameraDriver, HardwareInfo};
use robotd_protocol::hardware::HardwareReport;
use robotd_runtime::bus::{Bus, BusError};
use robotd_safety::Safety;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long versions read from the robot are answered without reading them again.
pub const VERSIONS_FRESH: Duration = Duration::from_secs(30);

/// What the service answers about the robot.
pub struct RobotFacts {
    /// The configured driver's name.
    pub driver_name: String,
    /// Whether this process is a `robotd commission` run.
    pub commissioning: bool,
    /// The arm's driver (versions).
    pub arm: Arc<dyn ArmDriver>,
    /// The camera's driver (intrinsics).
    pub camera: Arc<dyn CameraDriver>,
    /// The motion policy (e-stop).
    pub safety: Safety,
}

/// The `system/hardware` server, bound but not yet answering.
pub struct InfoService {
    server: robotd_runtime::bus::Server<robotd_protocol::hardware::HardwareQuery, HardwareReport>,
    facts: RobotFacts,
}

/// Binds `system/hardware` for the robot of `facts` (fails when the bus cannot serve it);
/// [`InfoService::spawn`] starts answering.
pub fn bind(bus: &Bus, facts: RobotFacts) -> Result<InfoService, BusError> {
    Ok(InfoService {
        server: bus.server(&robotd_topics::SYSTEM_HARDWARE)?,
        facts,
    })
}

impl InfoService {
    /// Answers until the task is aborted.
    pub fn spawn(self) -> tokio::task::JoinHandle<()> {
        let InfoService { mut server, facts } = self;
        let facts = Arc::new(facts);
        let versions: Arc<Mutex<Option<(Instant, HardwareInfo)>>> = Arc::default();
        tokio::spawn(async move {
            let served = server
                .serve(move |_query| {
                    let (facts, versions) = (facts.clone(), versions.clone());
                    async move {
                        Ok(HardwareReport {
                            driver: facts.driver_name.clone(),
                            commissioning: facts.commissioning,
                            intrinsics: facts.camera.intrinsics(),
                            versions: read_versions(&facts.arm, &versions).await,
                            estop: facts.safety.estop(),
                        })
                    }
                })
                .await;
            if let Err(error) = served {
                tracing::error!(%error, "the system/hardware service stopped");
            }
        })
    }
}

/// The versions read within [`VERSIONS_FRESH`], or read now (a failed read is not kept).
async fn read_versions(
    arm: &Arc<dyn ArmDriver>,
    cache: &Mutex<Option<(Instant, HardwareInfo)>>,
) -> Result<HardwareInfo, String> {
    let fresh = |c: &Option<(Instant, HardwareInfo)>| {
        c.as_ref()
            .filter(|(read, _)| read.elapsed() < VERSIONS_FRESH)
            .map(|(_, info)| info.clone())
    };
    if let Some(info) = cache.lock().ok().and_then(|c| fresh(&c)) {
        return Ok(info);
    }
    let info = arm.hardware_info().await.map_err(|e| e.to_string())?;
    if let Ok(mut c) = cache.lock() {
        *c = Some((Instant::now(), info.clone()));
    }
    Ok(info)
}
