//! `robotd serve`'s dashboard: the live view on the bus and the page's routes, wired to the
//! running service (health, workspaces, the agent).

use crate::serve::Runtime;
use anyhow::{Context, Result};
use robotd_config::Config;
use robotd_dashboard::live::Live;
use robotd_dashboard::{AgentLink, DashboardApi};
use robotd_topics::{AGENT_CANCEL, AGENT_REQUEST};
use std::sync::{Arc, Mutex};

/// The dashboard's routes and its live state (stop it at shutdown). `agent` is the agent
/// actor, or why none runs.
pub fn routes<A>(
    config: &Config,
    runtime: &Runtime,
    agent: &Result<A, String>,
) -> Result<(axum::Router, Arc<Live>)> {
    let settings = &config.dashboard;
    let live = robotd_dashboard::live::start(
        runtime.bus.clone(),
        settings.camera_fps,
        settings.jpeg_quality,
    )
    .context("starting the dashboard's live view")?;
    let agent = match agent {
        Ok(_) => AgentLink::Available {
            requests: Box::new(Mutex::new(runtime.bus.publisher(&AGENT_REQUEST)?)),
            cancels: Box::new(Mutex::new(runtime.bus.publisher(&AGENT_CANCEL)?)),
        },
        Err(reason) => AgentLink::Off(reason.clone()),
    };
    let agent = Arc::new(agent);
    let health = runtime.health_source.clone();
    let fence = runtime.safety_api()?.safety.fence().clone();
    let geofence = serde_json::json!({
        "min": [fence.min.x, fence.min.y, fence.min.z],
        "max": [fence.max.x, fence.max.y, fence.max.z],
        "keep_out": fence.keep_out.iter().map(|k| serde_json::json!({
            "name": k.name, "min": k.min, "max": k.max,
        })).collect::<Vec<_>>(),
    });
    let api = DashboardApi {
        live: live.clone(),
        health: Arc::new(move || health()),
        workspaces: serde_json::to_value(&runtime.workspaces)?,
        geofence,
        agent: agent.clone(),
        tool_calls: Arc::new(|| {
            let calls = robotd_tools::timings::recent(std::time::Duration::from_secs(300));
            serde_json::to_value(calls).unwrap_or_default()
        }),
    };
    let voice = robotd_dashboard::voice::VoiceApi {
        stt: Arc::new(runtime.bus.client(&robotd_topics::STT_TRANSCRIBE)?),
        estop: Arc::new(Mutex::new(
            runtime.bus.publisher(&robotd_topics::SAFETY_ESTOP)?,
        )),
        agent,
        live: live.clone(),
        config: config.voice.clone(),
    };
    let routes = robotd_dashboard::router(api).merge(robotd_dashboard::voice::routes(voice));
    Ok((routes, live))
}
