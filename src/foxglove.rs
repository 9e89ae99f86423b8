//! `robotd serve`'s Foxglove side: the live view (`[foxglove] bind`) and the always-on
//! recording (`[record]`), both fed by the same kind of bridge from the bus.

use crate::serve::Runtime;
use anyhow::Result;
use robotd_config::Config;
use robotd_foxglove::always_on::AlwaysOn;
use robotd_foxglove::bridge::BridgeSettings;
use robotd_foxglove::live::LiveView;

/// What runs while `robotd serve` runs; dropping it stops both.
pub struct Viewers {
    _live: Option<LiveView>,
    _recording: Option<AlwaysOn>,
}

/// The motion policy's fence and keep-out zones as boxes to draw.
pub fn geofence_boxes(
    fence: &robotd_safety::fence::Fence,
) -> (
    robotd_foxglove::scene::Box3,
    Vec<robotd_foxglove::scene::Box3>,
) {
    let boxed = |name: &str, min: [f64; 3], max: [f64; 3]| robotd_foxglove::scene::Box3 {
        name: name.to_owned(),
        min,
        max,
    };
    (
        boxed("geofence", fence.min.into(), fence.max.into()),
        fence
            .keep_out
            .iter()
            .map(|k| boxed(&k.name, k.min, k.max))
            .collect(),
    )
}

/// Starts the live view and the recording that `config` asks for.
pub async fn start(config: &Config, runtime: &Runtime) -> Result<Viewers> {
    let settings = BridgeSettings {
        camera_fps: config.foxglove.camera_fps,
        jpeg_quality: config.foxglove.jpeg_quality,
        model: config.robot.model(),
        workspaces: runtime.workspaces.clone(),
        geofence: Some(geofence_boxes(runtime.safety_api()?.safety.fence())),
        topics: None,
        camera: true,
        camera_intrinsics: Some(runtime.camera_intrinsics()),
    };
    let recording =
        robotd_foxglove::always_on::start(runtime.bus.clone(), &config.record, settings.clone())
            .map_err(|e| anyhow::anyhow!("[record]: {e}"))?;
    let live = match config.foxglove.bind {
        Some(bind) => {
            let live = robotd_foxglove::live::start(runtime.bus.clone(), bind, settings).await?;
            eprintln!(
                "robotd: Foxglove live view on ws://{}:{}",
                bind.ip(),
                live.port()
            );
            Some(live)
        }
        None => None,
    };
    Ok(Viewers {
        _live: live,
        _recording: recording,
    })
}
