//! Property: every message type survives `encode` → `decode` of its envelope unchanged, for
//! arbitrary (finite) contents, and `encode_body` writes the same message as `encode`.

mod strategies;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use robotd_protocol::envelope::{
    decode, encode_body, encode_to_vec, Envelope, Message, TraceContext,
};
use robotd_protocol::location::{Direction, Location, WorkspacePoint};
use robotd_protocol::objects::DetectedObject;
use std::fmt::Debug;
use strategies::*;

// ---------------------------------------------------------------- the property

fn round_trip<T>(body: T, trace: TraceContext) -> Result<(), TestCaseError>
where
    T: Message + Clone + PartialEq + Debug,
{
    let envelope = Envelope::new(body).with_trace(trace);
    let bytes = encode_to_vec(&envelope).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let back: Envelope<T> = decode(&bytes).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(&back, &envelope);

    let mut borrowed = Vec::new();
    encode_body(&envelope.body, &envelope.trace, &mut borrowed)
        .map_err(|e| TestCaseError::fail(e.to_string()))?;
    let back: Envelope<T> = decode(&borrowed).map_err(|e| TestCaseError::fail(e.to_string()))?;
    prop_assert_eq!(&back.body, &envelope.body);
    prop_assert_eq!(&back.trace, &envelope.trace);
    prop_assert_eq!(back.msg_type.as_str(), T::TYPE);
    Ok(())
}

macro_rules! round_trip_tests {
    ($($name:ident: $strategy:expr;)+) => {
        proptest! {
            #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]
            $(
                #[test]
                fn $name(body in $strategy, trace in trace()) {
                    round_trip(body, trace)?;
                }
            )+
        }
    };
}

round_trip_tests! {
    arm_command_round_trips: arm_command();
    arm_reply_round_trips: arm_reply();
    arm_state_round_trips: arm_state();
    gripper_command_round_trips: gripper_command();
    gripper_reply_round_trips: gripper_reply();
    gripper_state_round_trips: gripper_state();
    camera_frame_header_round_trips: frame_header();
    camera_image_round_trips: camera_image();
    camera_intrinsics_round_trips: intrinsics();
    detections_round_trip: detections();
    workspace_request_round_trips: workspace_request();
    workspace_reply_round_trips: workspace_reply();
    detectable_labels_round_trip: detectable_labels();
    workspace_query_round_trips: workspace_query();
    tracked_objects_round_trip: tracked_objects();
    speak_request_round_trips: speak_request();
    speech_event_round_trips: speech_event();
    text_overlay_round_trips: text_overlay();
    agent_request_round_trips: agent_request();
    agent_cancel_round_trips: agent_cancel();
    agent_event_round_trips: agent_event();
    actor_health_round_trips: actor_health();
    restart_event_round_trips: restart_event();
    emergency_stop_round_trips: emergency_stop();
    estop_release_round_trips: estop_release();
    hardware_query_round_trips: hardware_query();
    hardware_report_round_trips: hardware_report();
    estop_state_round_trips: estop_state();
    system_status_round_trips: system_status();
    ping_round_trips: ping();
    pong_round_trips: pong();
    test_pattern_request_round_trips: test_pattern_request();
    test_pattern_reply_round_trips: test_pattern_reply();
}

proptest! {
    /// Word enums parse back from their string whatever the case and surrounding whitespace.
    #[test]
    fn word_enums_parse_any_case(
        loc in location(),
        dir in prop::sample::select(Direction::ALL),
        point in workspace_point(),
        upper in any::<bool>(),
        pad in "[ \t]{0,3}",
    ) {
        let dress = |s: &str| {
            let s = if upper { s.to_uppercase() } else { s.to_owned() };
            format!("{pad}{s}{pad}")
        };
        prop_assert_eq!(dress(loc.as_str()).parse::<Location>().unwrap(), loc);
        prop_assert_eq!(dress(dir.as_str()).parse::<Direction>().unwrap(), dir);
        prop_assert_eq!(dress(point.as_str()).parse::<WorkspacePoint>().unwrap(), point);
    }

    /// Every DetectedObject also survives JSON, the MCP edge's format.
    #[test]
    fn detected_object_json_round_trips(obj in detected_object_with(decimal().boxed())) {
        let json = serde_json::to_string(&obj).unwrap();
        let back: DetectedObject = serde_json::from_str(&json).unwrap();
        prop_assert_eq!(back, obj);
    }
}
