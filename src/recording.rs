//! `robotd record FILE.mcap` and `robotd replay FILE.mcap`: the running robotd's bus into an
//! MCAP file, and a file back onto a bus without a robot (the work is in `robotd-foxglove`).
//!
//! `robotd replay` refuses to publish a robot's topics (camera frames, arm and gripper state)
//! onto a bus where a robotd runs: that robotd's own camera and arm publish them too, and the
//! two would mix. Running robotd on a recording is the replay driver's job
//! (`robot.driver = "replay"`, `drivers/replay`). It never publishes a safety topic
//! (`safety/estop`), even when `--topics` names it: a recorded e-stop or release must not act
//! on a live robot.

use anyhow::{bail, Context, Result};
use robotd_config::Config;
use robotd_foxglove::bridge::BridgeSettings;
use robotd_foxglove::replay::ReplayOptions;
use robotd_runtime::bus::{Bus, BusOptions};
use std::path::Path;
use std::time::Duration;

/// Parses a duration such as `10`, `10s`, `2.5m`, `1h`.
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let text = text.trim();
    let (number, unit) = match text.find(|c: char| c.is_ascii_alphabetic()) {
        Some(i) => text.split_at(i),
        None => (text, "s"),
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{text}' is not a duration; write e.g. 30s, 2m or 1h"))?;
    let seconds = match unit {
        "s" => value,
        "m" => value * 60.0,
        "h" => value * 3600.0,
        _ => return Err(format!("'{text}': the unit must be s, m or h")),
    };
    if !(seconds.is_finite() && seconds > 0.0 && seconds <= 7.0 * 86_400.0) {
        return Err(format!(
            "'{text}': a duration must be above 0 and at most 7 days"
        ));
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// Comma-separated topics, each one of robotd's (`camera/frames` for `with_camera`).
fn topic_list(text: &str, with_camera: bool) -> Result<Vec<String>> {
    let known: Vec<String> = robotd_foxglove::topics::all()
        .iter()
        .map(|t| t.name().to_owned())
        .collect();
    let mut topics = Vec::new();
    for topic in text.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        let ok = known.iter().any(|k| k == topic) || (with_camera && topic == "camera/frames");
        if !ok {
            bail!(
                "unknown topic '{topic}'; robotd's topics are: {}{}",
                if with_camera { "camera/frames, " } else { "" },
                known.join(", ")
            );
        }
        topics.push(topic.to_owned());
    }
    Ok(topics)
}

fn runtime() -> Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the tokio runtime")
}

/// Records the bus of `config`'s namespace into `path` for `duration` (or until Ctrl-C).
pub fn record(
    config: &Config,
    path: &Path,
    topics: Option<&str>,
    duration: Option<Duration>,
) -> Result<String> {
    let chosen = topics.map(|t| topic_list(t, true)).transpose()?;
    let camera = chosen
        .as_ref()
        .is_none_or(|list| list.iter().any(|t| t == "camera/frames"));
    let bus = Bus::open(BusOptions::new(&config.bus.namespace, "robotd-record"))
        .with_context(|| format!("joining the bus '{}'", config.bus.namespace))?;
    let settings = BridgeSettings {
        camera_fps: config.foxglove.camera_fps,
        jpeg_quality: config.foxglove.jpeg_quality,
        model: config.robot.model(),
        workspaces: config.robot.workspace_infos(),
        geofence: None,
        topics: chosen.map(|list| list.into_iter().filter(|t| t != "camera/frames").collect()),
        camera,
        // Another process: the camera's intrinsics are the running robotd's, unknown here.
        camera_intrinsics: None,
    };
    let runtime = runtime()?;
    {
        let _in_runtime = runtime.enter();
        warn_without_a_robotd(&bus)?;
    }
    let recording = robotd_foxglove::record::start(bus, path, settings)?;
    eprintln!(
        "robotd: recording bus '{}' into {}{}",
        config.bus.namespace,
        path.display(),
        duration.map_or(" until Ctrl-C".to_owned(), |d| format!(" for {d:?}"))
    );
    runtime.block_on(async {
        match duration {
            Some(duration) => tokio::select! {
                () = tokio::time::sleep(duration) => {}
                _ = tokio::signal::ctrl_c() => {}
            },
            None => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    });
    let summary = recording.finish()?;
    let counts: Vec<String> = summary
        .messages
        .iter()
        .map(|(topic, n)| format!("{topic} {n}"))
        .collect();
    Ok(format!(
        "wrote {} ({} messages, {} bytes): {}",
        summary.path.display(),
        summary.total(),
        summary.bytes,
        counts.join(", ")
    ))
}

/// Says so when no robotd serves on `bus`: a wrong `--namespace` would otherwise record only
/// the robot model and workspaces and report success.
fn warn_without_a_robotd(bus: &Bus) -> Result<()> {
    let ping = bus
        .client(&robotd_topics::SYSTEM_PING)
        .context("looking for a robotd on the bus")?;
    if !ping.has_server() {
        eprintln!(
            "robotd: warning: no robotd is running on bus '{}' (nothing answers system/ping): \
             only other processes' messages will be recorded. Is this the namespace robotd \
             serve printed? Pass it with --namespace",
            bus.namespace()
        );
    }
    Ok(())
}

/// The topics a robot publishes: replaying them where a robotd runs mixes two robots.
const ROBOT_TOPICS: [&str; 3] = ["camera/frames", "arm/state", "gripper/state"];

/// Refuses to publish `topics` of a robot onto `bus` when a robotd runs there (it serves
/// `system/ping`), whose own camera and arm publish the same topics.
fn refuse_a_second_robot(bus: &Bus, topics: &[String], path: &Path) -> Result<()> {
    let robot_topics: Vec<&str> = topics
        .iter()
        .map(String::as_str)
        .filter(|t| ROBOT_TOPICS.contains(t))
        .collect();
    if robot_topics.is_empty() {
        return Ok(());
    }
    let ping = bus
        .client(&robotd_topics::SYSTEM_PING)
        .context("looking for a robotd on the bus")?;
    if ping.has_server() {
        bail!(
            "a robotd is running on bus '{}', and its own camera and arm publish {}: replayed \
             and live data would mix. To run robotd's perception, workspace model, dashboard \
             and tools on the recording, start robotd with the recording as its robot: robotd \
             serve --set robot.driver=replay --set robot.replay.file={} (another --namespace \
             if this robotd keeps running); to publish it for your own subscribers, choose a \
             namespace without a robotd",
            bus.namespace(),
            robot_topics.join(", "),
            path.display()
        );
    }
    Ok(())
}

/// Replays `path` onto the bus of `config`'s namespace.
pub fn replay(config: &Config, path: &Path, topics: Option<&str>, speed: f64) -> Result<String> {
    if !(speed.is_finite() && speed >= 0.0) {
        bail!("--speed must be 0 (as fast as possible) or a positive factor, got {speed}");
    }
    let options = ReplayOptions {
        speed,
        topics: topics.map(|t| topic_list(t, true)).transpose()?,
    };
    // Before touching the bus: a safety topic is never replayed (the library refuses it too).
    if let Some(topic) = options
        .topics
        .iter()
        .flatten()
        .find(|t| robotd_foxglove::replay::is_safety_topic(t))
    {
        return Err(robotd_foxglove::replay::ReplayError::SafetyTopic(topic.clone()).into());
    }
    let chosen: Vec<String> = match &options.topics {
        Some(list) => list.clone(),
        None => robotd_foxglove::replay::DEFAULT_TOPICS
            .iter()
            .map(|t| (*t).to_owned())
            .collect(),
    };
    let bus = Bus::open(BusOptions::new(&config.bus.namespace, "robotd-replay"))
        .with_context(|| format!("joining the bus '{}'", config.bus.namespace))?;
    let summary = runtime()?.block_on(async {
        refuse_a_second_robot(&bus, &chosen, path)?;
        Ok::<_, anyhow::Error>(robotd_foxglove::replay::replay(&bus, path, &options).await?)
    })?;
    let published: Vec<String> = summary
        .published
        .iter()
        .map(|(topic, n)| format!("{topic} {n}"))
        .collect();
    let skipped: Vec<String> = summary
        .skipped
        .iter()
        .map(|(reason, n)| format!("{reason} ({n})"))
        .collect();
    if summary.published.is_empty() {
        bail!(
            "nothing in {} was replayed (skipped: {})",
            path.display(),
            if skipped.is_empty() {
                "none".to_owned()
            } else {
                skipped.join(", ")
            }
        );
    }
    Ok(format!(
        "replayed {:.1} s of recording in {:.1} s: {}{}",
        summary.recorded_seconds,
        summary.seconds,
        published.join(", "),
        if skipped.is_empty() {
            String::new()
        } else {
            format!("; skipped: {}", skipped.join(", "))
        }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_have_units() {
        assert_eq!(parse_duration("10").unwrap(), Duration::from_secs(10));
        assert_eq!(parse_duration("2.5m").unwrap(), Duration::from_secs(150));
        assert_eq!(parse_duration("1h").unwrap(), Duration::from_secs(3600));
        for bad in ["", "0", "-3s", "10x", "abc", "nan", "8d"] {
            assert!(parse_duration(bad).is_err(), "{bad}");
        }
    }
}
