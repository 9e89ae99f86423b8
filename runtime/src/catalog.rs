//! The catalogue of robotd's bus topics and services: name, message types, overflow policy.
//!
//! Every process that joins a robotd bus (robotd itself, an actor in its own process, a test)
//! declares topics from here, so both ends always agree on names and policies — a mismatch is
//! refused by iceoryx2 when the port is created.

use crate::bus::{FrameTopic, Overflow, Service};
use robotd_protocol::diagnostics::{Ping, Pong, TestPatternReply, TestPatternRequest};

/// robotd's own liveness probe: any process can ping the running service.
pub const SYSTEM_PING: Service<Ping, Pong> = Service::new("system/ping");

/// The example external actor's command: publish one test-pattern frame.
pub const TEST_PATTERN: Service<TestPatternRequest, TestPatternReply> =
    Service::new("example/test_pattern/command");

/// The example external actor's frames (latest wins, like every camera).
pub const TEST_PATTERN_FRAMES: FrameTopic =
    FrameTopic::new("example/test_pattern/frames", Overflow::latest_wins(2));

/// Supervision events (restarts, safe states, exhausted budgets) of every supervised actor.
/// Latest wins: a stuck dashboard must never slow down a restart; every event is also a
/// metric and a log line.
pub const HEALTH_RESTARTS: crate::bus::Topic<robotd_protocol::health::RestartEvent> =
    crate::bus::Topic::new("health/restarts", Overflow::latest_wins(64));
