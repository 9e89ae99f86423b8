//! The generators of the round-trip property: arbitrary (finite) contents of every message
//! type.

use proptest::prelude::*;
use robotd_protocol::agent::{AgentCancel, AgentEvent, AgentEventKind, AgentRequest};
use robotd_protocol::arm::{ArmCommand, ArmError, ArmReply, ArmState, PathKind};
use robotd_protocol::camera::{CameraFrameHeader, CameraImage, CameraIntrinsics, ImageEncoding};
use robotd_protocol::diagnostics::{Ping, Pong, TestPatternReply, TestPatternRequest};
use robotd_protocol::envelope::TraceContext;
use robotd_protocol::geometry::{JointState, Point2, Point3, Pose, PoseDelta, RobotModel};
use robotd_protocol::gripper::{GripperCommand, GripperError, GripperReply, GripperState};
use robotd_protocol::hardware::{HardwareInfo, HardwareQuery, HardwareReport, MotorInfo};
use robotd_protocol::health::{
    ActorHealth, ActorState, EStopRelease, EStopState, EmergencyStop, RestartEvent, SystemStatus,
};
use robotd_protocol::location::{Location, WorkspacePoint};
use robotd_protocol::objects::{
    DetectedObject, Detections, Dimensions, ImageCoordinates, ObjectPosition, RelBox, RelPoint,
};
use robotd_protocol::speech::{OverlayKind, SpeakRequest, SpeechEvent, TextOverlay};
use robotd_protocol::workspace::{
    DetectableLabels, TrackedObjects, WorkspaceError, WorkspaceInfo, WorkspaceQuery,
    WorkspaceReply, WorkspaceRequest,
};

// ---------------------------------------------------------------- strategies: basics

/// Any finite f64, including zero, subnormals and huge magnitudes.
pub fn float() -> impl Strategy<Value = f64> {
    prop::num::f64::NORMAL | prop::num::f64::ZERO | prop::num::f64::SUBNORMAL
}

pub fn text() -> impl Strategy<Value = String> {
    ".{0,16}"
}

pub fn texts() -> impl Strategy<Value = Vec<String>> {
    prop::collection::vec(text(), 0..4)
}

pub fn floats() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(float(), 0..8)
}

pub fn trace() -> impl Strategy<Value = TraceContext> {
    (prop::option::of(text()), prop::option::of(text())).prop_map(|(traceparent, tracestate)| {
        TraceContext {
            traceparent,
            tracestate,
        }
    })
}

// ---------------------------------------------------------------- strategies: geometry

pub fn pose() -> impl Strategy<Value = Pose> {
    prop::array::uniform6(float()).prop_map(Pose::from_array)
}

pub fn pose_delta() -> impl Strategy<Value = PoseDelta> {
    prop::array::uniform6(float()).prop_map(|a| PoseDelta {
        dx_m: a[0],
        dy_m: a[1],
        dz_m: a[2],
        droll_rad: a[3],
        dpitch_rad: a[4],
        dyaw_rad: a[5],
    })
}

pub fn point2() -> impl Strategy<Value = Point2> {
    (float(), float()).prop_map(|(x, y)| Point2::new(x, y))
}

pub fn joint_state() -> impl Strategy<Value = JointState> {
    (floats(), floats(), any::<u64>()).prop_map(|(positions_rad, velocities_rad_s, ts)| {
        JointState {
            positions_rad,
            velocities_rad_s,
            timestamp_unix_ns: ts,
        }
    })
}

pub fn robot_model() -> impl Strategy<Value = RobotModel> {
    prop::sample::select(RobotModel::ALL.to_vec())
}

pub fn location() -> impl Strategy<Value = Location> {
    prop::sample::select(Location::ALL)
}

pub fn workspace_point() -> impl Strategy<Value = WorkspacePoint> {
    prop::sample::select(WorkspacePoint::ALL)
}

// ---------------------------------------------------------------- strategies: arm, gripper

pub fn arm_command() -> impl Strategy<Value = ArmCommand> {
    prop_oneof![
        (
            pose(),
            prop::sample::select(vec![PathKind::Joint, PathKind::Linear])
        )
            .prop_map(|(target, path)| ArmCommand::MoveToPose { target, path }),
        floats().prop_map(|positions_rad| ArmCommand::MoveJoints { positions_rad }),
        pose_delta().prop_map(|delta| ArmCommand::ShiftPose { delta }),
        Just(ArmCommand::Stop),
        text().prop_map(|workspace_id| ArmCommand::GoToObservationPose { workspace_id }),
        Just(ArmCommand::Calibrate),
        Just(ArmCommand::ClearCollision),
        Just(ArmCommand::GetPose),
        Just(ArmCommand::GetJoints),
        Just(ArmCommand::GetCollisionState),
    ]
}

pub fn arm_error() -> impl Strategy<Value = ArmError> {
    prop_oneof![
        (pose(), text()).prop_map(|(target, reason)| ArmError::Unreachable { target, reason }),
        (any::<u32>(), float(), float(), float()).prop_map(
            |(joint, value_rad, min_rad, max_rad)| {
                ArmError::JointLimit {
                    joint,
                    value_rad,
                    min_rad,
                    max_rad,
                }
            }
        ),
        Just(ArmError::Collision),
        Just(ArmError::NotCalibrated),
        Just(ArmError::Stopped),
        text().prop_map(|reason| ArmError::EStopped { reason }),
        (text(), texts()).prop_map(|(workspace_id, known)| ArmError::UnknownWorkspace {
            workspace_id,
            known
        }),
        text().prop_map(|reason| ArmError::InvalidCommand { reason }),
        any::<u64>().prop_map(|after_ms| ArmError::Timeout { after_ms }),
        text().prop_map(|reason| ArmError::Unavailable { reason }),
        text().prop_map(|message| ArmError::Driver { message }),
    ]
}

pub fn arm_reply() -> impl Strategy<Value = ArmReply> {
    prop_oneof![
        pose().prop_map(|pose| ArmReply::Ok { pose }),
        joint_state().prop_map(|joints| ArmReply::Joints { joints }),
        any::<bool>()
            .prop_map(|collision_detected| ArmReply::CollisionState { collision_detected }),
        arm_error().prop_map(ArmReply::from),
    ]
}

pub fn arm_state() -> impl Strategy<Value = ArmState> {
    (
        joint_state(),
        pose(),
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        any::<bool>(),
        any::<u64>(),
    )
        .prop_map(
            |(joints, tool_pose, moving, collision_detected, calibrated, estop_engaged, still)| {
                ArmState {
                    joints,
                    tool_pose,
                    moving,
                    collision_detected,
                    calibrated,
                    estop_engaged,
                    still_since_unix_ns: still,
                }
            },
        )
}

pub fn gripper_command() -> impl Strategy<Value = GripperCommand> {
    prop_oneof![
        Just(GripperCommand::Open),
        Just(GripperCommand::Close),
        float().prop_map(|width_m| GripperCommand::SetWidth { width_m }),
        Just(GripperCommand::GetState),
    ]
}

pub fn gripper_reply() -> impl Strategy<Value = GripperReply> {
    let error = prop_oneof![
        (float(), float())
            .prop_map(|(width_m, max_m)| GripperError::InvalidWidth { width_m, max_m }),
        text().prop_map(|reason| GripperError::EStopped { reason }),
        text().prop_map(|reason| GripperError::Unavailable { reason }),
        text().prop_map(|reason| GripperError::InvalidCommand { reason }),
        text().prop_map(|message| GripperError::Driver { message }),
    ];
    prop_oneof![
        (any::<bool>(), float())
            .prop_map(|(holding, width_m)| GripperReply::State { holding, width_m }),
        error.prop_map(GripperReply::from),
    ]
}

pub fn gripper_state() -> impl Strategy<Value = GripperState> {
    (any::<bool>(), float(), any::<bool>()).prop_map(|(holding, width_m, moving)| GripperState {
        holding,
        width_m,
        moving,
    })
}

// ---------------------------------------------------------------- strategies: camera, objects

pub fn frame_header() -> impl Strategy<Value = CameraFrameHeader> {
    (
        any::<u64>(),
        any::<u64>(),
        any::<u32>(),
        any::<u32>(),
        any::<u32>(),
        prop::sample::select(vec![
            ImageEncoding::Rgb8,
            ImageEncoding::Bgr8,
            ImageEncoding::Jpeg,
        ]),
        pose(),
        prop::option::of(text()),
    )
        .prop_map(
            |(frame_id, timestamp_unix_ns, width, height, channels, encoding, camera_pose, ws)| {
                CameraFrameHeader {
                    frame_id,
                    timestamp_unix_ns,
                    width,
                    height,
                    channels,
                    encoding,
                    camera_pose,
                    workspace_id: ws,
                }
            },
        )
}

pub fn camera_image() -> impl Strategy<Value = CameraImage> {
    (frame_header(), prop::collection::vec(any::<u8>(), 0..2048))
        .prop_map(|(header, data)| CameraImage { header, data })
}

pub fn intrinsics() -> impl Strategy<Value = CameraIntrinsics> {
    (
        any::<u32>(),
        any::<u32>(),
        prop::array::uniform4(float()),
        prop::array::uniform5(float()),
    )
        .prop_map(
            |(width, height, [fx, fy, cx, cy], distortion)| CameraIntrinsics {
                width,
                height,
                fx,
                fy,
                cx,
                cy,
                distortion,
            },
        )
}

pub fn detected_object() -> impl Strategy<Value = DetectedObject> {
    detected_object_with(float().boxed())
}

/// Millimetre-precision numbers, which JSON text represents exactly.
pub fn decimal() -> impl Strategy<Value = f64> {
    (-10_000_000i64..10_000_000).prop_map(|i| i as f64 / 1000.0)
}

pub fn detected_object_with(float: BoxedStrategy<f64>) -> impl Strategy<Value = DetectedObject> {
    let rel_point = || (float.clone(), float.clone()).prop_map(|(u, v)| RelPoint { u, v });
    let point3 =
        || (float.clone(), float.clone(), float.clone()).prop_map(|(x, y, z)| Point3::new(x, y, z));
    let float = || float.clone();
    let image = (rel_point(), rel_point(), prop::array::uniform4(float())).prop_map(
        |(center_rel, center_of_mass_rel, [u_min, v_min, u_max, v_max])| ImageCoordinates {
            center_rel,
            center_of_mass_rel,
            bounding_box_rel: RelBox {
                u_min,
                v_min,
                u_max,
                v_max,
            },
        },
    );
    (
        (text(), text(), text(), float()),
        (point3(), point3()),
        image,
        prop::array::uniform3(float()),
        (float(), float(), any::<i64>()),
    )
        .prop_map(
            |(
                (id, label, workspace_id, timestamp_unix_s),
                (center_of_mass, center),
                image_coordinates,
                [width_m, height_m, size_m2],
                (gripper_rotation_rad, confidence, class_id),
            )| DetectedObject {
                id,
                label,
                workspace_id,
                timestamp_unix_s,
                position: ObjectPosition {
                    center_of_mass,
                    center,
                },
                image_coordinates,
                dimensions: Dimensions {
                    width_m,
                    height_m,
                    size_m2,
                },
                gripper_rotation_rad,
                confidence,
                class_id,
            },
        )
}

pub fn objects() -> impl Strategy<Value = Vec<DetectedObject>> {
    prop::collection::vec(detected_object(), 0..4)
}

pub fn detections() -> impl Strategy<Value = Detections> {
    (
        any::<u64>(),
        text(),
        any::<u64>(),
        text(),
        any::<bool>(),
        objects(),
    )
        .prop_map(
            |(frame_id, workspace_id, timestamp_unix_ns, source, steady, objects)| Detections {
                frame_id,
                workspace_id,
                timestamp_unix_ns,
                source,
                steady,
                objects,
            },
        )
}

// ---------------------------------------------------------------- strategies: workspace

pub fn workspace_info() -> impl Strategy<Value = WorkspaceInfo> {
    (text(), robot_model(), point2(), point2(), pose()).prop_map(
        |(id, robot, upper_left, lower_right, observation_pose)| WorkspaceInfo {
            id,
            robot,
            upper_left,
            lower_right,
            observation_pose,
        },
    )
}

pub fn workspace_request() -> impl Strategy<Value = WorkspaceRequest> {
    prop_oneof![
        (
            location(),
            prop::option::of(point2()),
            prop::option::of(text())
        )
            .prop_map(
                |(location, coordinate, label)| WorkspaceRequest::GetObjects {
                    location,
                    coordinate,
                    label
                }
            ),
        (point2(), prop::option::of(text()))
            .prop_map(|(coordinate, label)| WorkspaceRequest::GetObjectNear { coordinate, label }),
        Just(WorkspaceRequest::GetLargestObject),
        Just(WorkspaceRequest::GetSmallestObject),
        any::<bool>().prop_map(|ascending| WorkspaceRequest::GetObjectsSorted { ascending }),
        Just(WorkspaceRequest::GetLargestFreeSpace),
        (text(), workspace_point()).prop_map(|(workspace_id, point)| {
            WorkspaceRequest::GetWorkspacePoint {
                workspace_id,
                point,
            }
        }),
        Just(WorkspaceRequest::GetLabels),
        text().prop_map(|label| WorkspaceRequest::AddLabel { label }),
        text().prop_map(|workspace_id| WorkspaceRequest::GetObservationPose { workspace_id }),
        Just(WorkspaceRequest::ListWorkspaces),
        text().prop_map(|object_id| WorkspaceRequest::ObjectPicked { object_id }),
        (text(), point2())
            .prop_map(|(object_id, at)| WorkspaceRequest::ObjectPlaced { object_id, at }),
        (text(), text())
            .prop_map(|(object_id, label)| WorkspaceRequest::LabelObject { object_id, label }),
    ]
}

pub fn workspace_query() -> impl Strategy<Value = WorkspaceQuery> {
    (
        workspace_request(),
        prop::option::of(any::<u64>()),
        any::<u64>(),
    )
        .prop_map(
            |(request, fresh_after_unix_ns, max_wait_ms)| WorkspaceQuery {
                request,
                fresh_after_unix_ns,
                max_wait_ms,
            },
        )
}

pub fn tracked_objects() -> impl Strategy<Value = TrackedObjects> {
    let ids = prop::collection::vec(text(), 0..3);
    (text(), any::<u64>(), any::<u64>(), objects(), text(), ids).prop_map(
        |(workspace_id, frame_id, timestamp_unix_ns, objects, source, detection_ids)| {
            TrackedObjects {
                workspace_id,
                frame_id,
                timestamp_unix_ns,
                objects,
                source,
                detection_ids,
            }
        },
    )
}

pub fn workspace_reply() -> impl Strategy<Value = WorkspaceReply> {
    let error = prop_oneof![
        (text(), texts()).prop_map(|(workspace_id, known)| WorkspaceError::UnknownWorkspace {
            workspace_id,
            known
        }),
        location().prop_map(|location| WorkspaceError::CoordinateRequired { location }),
        text().prop_map(|reason| WorkspaceError::NoFreshDetection { reason }),
        text().prop_map(|reason| WorkspaceError::InvalidRequest { reason }),
        text().prop_map(|reason| WorkspaceError::Unavailable { reason }),
    ];
    prop_oneof![
        objects().prop_map(|objects| WorkspaceReply::Objects { objects }),
        prop::option::of(detected_object()).prop_map(|object| WorkspaceReply::Object { object }),
        (float(), point2())
            .prop_map(|(area_m2, center)| WorkspaceReply::FreeSpace { area_m2, center }),
        point2().prop_map(|coordinate| WorkspaceReply::Coordinate { coordinate }),
        (texts(), texts()).prop_map(|(labels, builtin)| WorkspaceReply::Labels { labels, builtin }),
        (text(), any::<bool>()).prop_map(|(label, already_known)| WorkspaceReply::LabelAdded {
            label,
            already_known
        }),
        (detected_object(), text(), text(), any::<bool>()).prop_map(
            |(object, previous, detected_as, label_added)| WorkspaceReply::ObjectLabelled {
                object,
                previous,
                detected_as,
                label_added
            }
        ),
        pose().prop_map(|pose| WorkspaceReply::ObservationPose { pose }),
        prop::collection::vec(workspace_info(), 0..3)
            .prop_map(|workspaces| WorkspaceReply::Workspaces { workspaces }),
        error.prop_map(WorkspaceReply::from),
    ]
}

pub fn detectable_labels() -> impl Strategy<Value = DetectableLabels> {
    (texts(), prop::option::of(text()), texts()).prop_map(|(labels, added, builtin)| {
        DetectableLabels {
            labels,
            added,
            builtin,
        }
    })
}

// ---------------------------------------------------------------- strategies: speech, agent, health

pub fn speak_request() -> impl Strategy<Value = SpeakRequest> {
    (text(), any::<u8>(), text()).prop_map(|(text, priority, source)| SpeakRequest {
        text,
        priority,
        source,
    })
}

pub fn speech_event() -> impl Strategy<Value = SpeechEvent> {
    prop_oneof![
        text().prop_map(|text| SpeechEvent::Started { text }),
        (text(), any::<u64>())
            .prop_map(|(text, duration_ms)| SpeechEvent::Finished { text, duration_ms }),
        (text(), text()).prop_map(|(text, reason)| SpeechEvent::Dropped { text, reason }),
    ]
}

pub fn text_overlay() -> impl Strategy<Value = TextOverlay> {
    (
        text(),
        prop::sample::select(vec![
            OverlayKind::UserTask,
            OverlayKind::RobotSpeech,
            OverlayKind::SystemMessage,
        ]),
        float(),
        prop::option::of(text()),
    )
        .prop_map(|(text, kind, duration_s, tool_name)| TextOverlay {
            text,
            kind,
            duration_s,
            tool_name,
        })
}

pub fn agent_request() -> impl Strategy<Value = AgentRequest> {
    (text(), text()).prop_map(|(request_id, text)| AgentRequest { request_id, text })
}

pub fn agent_cancel() -> impl Strategy<Value = AgentCancel> {
    text().prop_map(|request_id| AgentCancel { request_id })
}

pub fn agent_event() -> impl Strategy<Value = AgentEvent> {
    let kind = prop_oneof![
        text().prop_map(|text| AgentEventKind::Plan { text }),
        (text(), text(), text()).prop_map(|(call_id, name, arguments_json)| {
            AgentEventKind::ToolCall {
                call_id,
                name,
                arguments_json,
            }
        }),
        (text(), text(), text(), any::<bool>()).prop_map(|(call_id, name, text, ok)| {
            AgentEventKind::ToolResult {
                call_id,
                name,
                text,
                ok,
            }
        }),
        text().prop_map(|text| AgentEventKind::Answer { text }),
        text().prop_map(|message| AgentEventKind::Error { message }),
        Just(AgentEventKind::Cancelled),
    ];
    (text(), any::<u32>(), kind).prop_map(|(request_id, seq, event)| AgentEvent {
        request_id,
        seq,
        event,
    })
}

pub fn actor_state() -> impl Strategy<Value = ActorState> {
    prop::sample::select(vec![
        ActorState::Starting,
        ActorState::Running,
        ActorState::Restarting,
        ActorState::SafeState,
        ActorState::Failed,
        ActorState::Stopped,
    ])
}

pub fn actor_health() -> impl Strategy<Value = ActorHealth> {
    (
        text(),
        actor_state(),
        any::<u32>(),
        prop::option::of(text()),
    )
        .prop_map(|(actor, state, restarts, last_error)| ActorHealth {
            actor,
            state,
            restarts,
            last_error,
        })
}

pub fn restart_event() -> impl Strategy<Value = RestartEvent> {
    (
        text(),
        any::<u32>(),
        text(),
        any::<u64>(),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_map(
            |(actor, attempt, reason, backoff_ms, safe_state_ok, budget_exhausted)| RestartEvent {
                actor,
                attempt,
                reason,
                backoff_ms,
                safe_state_ok,
                budget_exhausted,
            },
        )
}

pub fn emergency_stop() -> impl Strategy<Value = EmergencyStop> {
    (any::<bool>(), text(), text()).prop_map(|(engaged, reason, source)| EmergencyStop {
        engaged,
        reason,
        source,
    })
}

pub fn estop_release() -> impl Strategy<Value = EStopRelease> {
    (text(), text(), prop::option::of(text())).prop_map(|(confirm, by, only_if_reason)| {
        EStopRelease {
            confirm,
            by,
            only_if_reason,
        }
    })
}

pub fn estop_state() -> impl Strategy<Value = EStopState> {
    (any::<bool>(), text()).prop_map(|(engaged, reason)| EStopState { engaged, reason })
}

pub fn system_status() -> impl Strategy<Value = SystemStatus> {
    (
        text(),
        robot_model(),
        text(),
        prop::option::of(pose()),
        prop::collection::vec(actor_health(), 0..4),
        any::<bool>(),
        any::<u64>(),
    )
        .prop_map(
            |(robot_id, robot_model, workspace_id, pose, actors, estop_engaged, uptime_ms)| {
                SystemStatus {
                    robot_id,
                    robot_model,
                    workspace_id,
                    pose,
                    actors,
                    estop_engaged,
                    uptime_ms,
                }
            },
        )
}

pub fn ping() -> impl Strategy<Value = Ping> {
    (any::<u64>(), prop::collection::vec(any::<u8>(), 0..128))
        .prop_map(|(seq, payload)| Ping { seq, payload })
}

pub fn pong() -> impl Strategy<Value = Pong> {
    (
        any::<u64>(),
        prop::collection::vec(any::<u8>(), 0..128),
        any::<u32>(),
    )
        .prop_map(|(seq, payload, served_by_pid)| Pong {
            seq,
            payload,
            served_by_pid,
        })
}

pub fn test_pattern_request() -> impl Strategy<Value = TestPatternRequest> {
    (any::<u64>(), any::<u8>()).prop_map(|(frame_id, seed)| TestPatternRequest { frame_id, seed })
}

pub fn test_pattern_reply() -> impl Strategy<Value = TestPatternReply> {
    (any::<u64>(), any::<u64>(), any::<u32>(), text()).prop_map(
        |(frame_id, delivered_to, served_by_pid, robotd_said)| TestPatternReply {
            frame_id,
            delivered_to,
            served_by_pid,
            robotd_said,
        },
    )
}

pub fn hardware_info() -> impl Strategy<Value = HardwareInfo> {
    let motor =
        (text(), text(), prop::option::of(text())).prop_map(|(name, model, firmware)| MotorInfo {
            name,
            model,
            firmware,
        });
    (
        prop::option::of(text()),
        prop::option::of(text()),
        prop::collection::vec(motor, 0..4),
        prop::option::of(text()),
        texts(),
    )
        .prop_map(
            |(hardware_version, software_version, motors, tool, not_reported)| HardwareInfo {
                hardware_version,
                software_version,
                motors,
                tool,
                not_reported,
            },
        )
}

pub fn hardware_query() -> impl Strategy<Value = HardwareQuery> {
    Just(HardwareQuery {})
}

pub fn hardware_report() -> impl Strategy<Value = HardwareReport> {
    (
        text(),
        any::<bool>(),
        intrinsics(),
        prop_oneof![hardware_info().prop_map(Ok), text().prop_map(Err)],
        prop::option::of(text()),
    )
        .prop_map(
            |(driver, commissioning, intrinsics, versions, estop)| HardwareReport {
                driver,
                commissioning,
                intrinsics,
                versions,
                estop,
            },
        )
}
