//! An actor in its own process that joins a running robotd's bus: a test-pattern camera.
//!
//! It shows what a lab needs to plug a new actor into robotd without touching robotd: open the
//! bus in the same namespace, declare ports from the shared catalogue, serve and publish.
//! Here the actor first pings robotd (calling into robotd), then serves "publish a frame"
//! commands, writing each frame straight into shared memory.
//!
//! ```text
//! cargo run --release                                   # terminal 1: robotd
//! cargo run --release --example external_actor         # terminal 2: this actor
//! ```
//!
//! Options: `--namespace NAME` (default: `$ROBOTD_BUS__NAMESPACE`, else `robotd`, robotd's
//! default bus namespace).

use robotd_protocol::diagnostics::{Ping, TestPatternReply, TestPatternRequest};
use robotd_runtime::bus::{Bus, BusOptions, Fault, FaultKind};
use robotd_topics::{SYSTEM_PING, TEST_PATTERN, TEST_PATTERN_FRAMES};
use std::time::Duration;

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    iceoryx2::prelude::set_log_level(iceoryx2::prelude::LogLevel::Error);
    let namespace = parse_namespace()?;
    let bus = Bus::open(BusOptions::new(&namespace, "example-test-pattern-camera"))?;

    // Call robotd: proves this process reached the running service's bus.
    let robotd = bus.client(&SYSTEM_PING)?;
    if !robotd.wait_for_server(Duration::from_secs(10)).await {
        return Err(
            format!("no robotd found on bus namespace '{namespace}' (is it running?)").into(),
        );
    }
    let pong = robotd
        .request(
            &Ping {
                seq: 1,
                payload: b"hello robotd".to_vec(),
            },
            Duration::from_secs(5),
        )
        .await?;
    let robotd_said = format!("pong {} from robotd pid {}", pong.seq, pong.served_by_pid);
    drop(robotd); // a client holds a slot of robotd's service; give it back
    eprintln!("external actor: {robotd_said}");

    let frames = bus.frame_publisher(&TEST_PATTERN_FRAMES)?;
    let mut server = bus.server(&TEST_PATTERN)?;
    println!("ready");

    let pid = std::process::id();
    loop {
        tokio::select! {
            incoming = server.next() => {
                let (envelope, pending) = incoming?.split();
                let request: TestPatternRequest = envelope.body;
                let reply = publish_pattern(&frames, &request).map(|delivered_to| TestPatternReply {
                    frame_id: request.frame_id,
                    delivered_to,
                    served_by_pid: pid,
                    robotd_said: robotd_said.clone(),
                });
                server.respond(pending, reply)?;
            }
            _ = tokio::signal::ctrl_c() => return Ok(()),
        }
    }
}

fn publish_pattern(
    frames: &robotd_runtime::bus::FramePublisher,
    request: &TestPatternRequest,
) -> Result<u64, Fault> {
    let unavailable =
        |e: robotd_runtime::bus::BusError| Fault::new(FaultKind::Unavailable, e.to_string());
    let mut frame = frames.loan().map_err(unavailable)?;
    frame.header_mut().frame_id = request.frame_id;
    for (i, pixel) in frame.pixels_mut().iter_mut().enumerate() {
        *pixel = ((i + request.seed as usize) % 251) as u8;
    }
    frame.send().map(|n| n as u64).map_err(unavailable)
}

fn parse_namespace() -> Result<String, String> {
    let mut args = std::env::args().skip(1);
    // Same default and variable as robotd's own `bus.namespace` (robotd sets it for the actor
    // processes it supervises).
    let mut namespace =
        std::env::var("ROBOTD_BUS__NAMESPACE").unwrap_or_else(|_| "robotd".to_owned());
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--namespace" => namespace = args.next().ok_or("--namespace needs a value")?,
            "-h" | "--help" => {
                println!("usage: external_actor [--namespace NAME]");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument '{other}' (try --help)")),
        }
    }
    Ok(namespace)
}
