//! The bytes on the wire: what other processes (and other languages) actually see.

use robotd_protocol::arm::{ArmCommand, ArmReply, PathKind};
use robotd_protocol::camera::{CameraFrameHeader, CameraImage, ImageEncoding};
use robotd_protocol::envelope::{decode, encode, encode_to_vec, DecodeError, Envelope, Message};
use robotd_protocol::geometry::{Point3, Pose};
use robotd_protocol::objects::{
    DetectedObject, Dimensions, ImageCoordinates, ObjectPosition, RelBox, RelPoint,
};
use serde::{Deserialize, Serialize};

fn image(len: usize) -> CameraImage {
    CameraImage {
        header: CameraFrameHeader {
            frame_id: 42,
            timestamp_unix_ns: 1_700_000_000_123_456_789,
            width: 640,
            height: 480,
            channels: 3,
            encoding: ImageEncoding::Jpeg,
            camera_pose: Pose::new(0.173, -0.002, 0.277, -3.042, 1.327, -3.027),
            workspace_id: Some("niryo_ws".into()),
        },
        // Bytes ≥ 0x80 would take two bytes each if encoded as an array of integers.
        data: (0..len).map(|i| 0x80 | (i % 128) as u8).collect(),
    }
}

#[test]
fn image_bytes_are_msgpack_bin_not_an_array() {
    let img = image(10_000);
    let without = encode_to_vec(&Envelope::new(image(0))).unwrap();
    let with = encode_to_vec(&Envelope::new(img.clone())).unwrap();

    // bin16: marker 0xc5, big-endian u16 length, then the bytes verbatim.
    let mut expected = vec![0xc5, 0x27, 0x10];
    expected.extend_from_slice(&img.data);
    assert!(
        with.windows(expected.len())
            .any(|w| w == expected.as_slice()),
        "payload not found as a bin16 blob"
    );
    // Exactly the payload plus the 3-byte bin16 header more than an empty image (bin8, 2 bytes).
    assert_eq!(with.len() - without.len(), 10_000 + 3 - 2);

    let back: Envelope<CameraImage> = decode(&with).unwrap();
    assert_eq!(back.body, img);
}

#[test]
fn a_full_frame_costs_its_own_size() {
    let img = image(640 * 480 * 3);
    let bytes = encode_to_vec(&Envelope::new(img)).unwrap();
    let overhead = bytes.len() - 640 * 480 * 3;
    assert!(overhead < 400, "overhead {overhead} bytes");
    // bin32 marker for payloads ≥ 64 KiB.
    assert!(bytes
        .windows(5)
        .any(|w| w == [0xc6, 0x00, 0x0e, 0x10, 0x00]));
}

#[test]
fn decode_refuses_another_message_type() {
    let bytes = encode_to_vec(&Envelope::new(ArmCommand::Stop)).unwrap();
    let err = decode::<ArmReply>(&bytes).unwrap_err();
    assert!(
        matches!(&err, DecodeError::WrongType { expected: "arm.reply", got } if got == "arm.command")
    );
    assert_eq!(
        err.to_string(),
        "expected a 'arm.reply' message but got 'arm.command'"
    );
}

/// A future version of `ArmCommand`, as a newer sender would write it.
#[derive(Debug, Serialize, Deserialize)]
struct ArmCommandV2 {
    kind: String,
}

impl Message for ArmCommandV2 {
    const TYPE: &'static str = "arm.command";
    const SCHEMA_VERSION: u16 = 2;
}

#[test]
fn decode_refuses_another_schema_version() {
    let bytes = encode_to_vec(&Envelope::new(ArmCommandV2 {
        kind: "stop".into(),
    }))
    .unwrap();
    let err = decode::<ArmCommand>(&bytes).unwrap_err();
    assert!(matches!(
        err,
        DecodeError::UnsupportedVersion {
            msg_type: "arm.command",
            got: 2,
            supported: 1
        }
    ));
    assert_eq!(
        err.to_string(),
        "'arm.command' schema version 2 is not supported (this build reads version 1); \
         upgrade the older side"
    );
}

#[test]
fn decode_refuses_garbage_and_truncation() {
    let err = decode::<ArmCommand>(b"\x01\x02\x03").unwrap_err();
    assert!(matches!(
        err,
        DecodeError::Malformed {
            expected: "arm.command",
            ..
        }
    ));
    assert!(
        err.to_string()
            .starts_with("malformed 'arm.command' message: "),
        "{err}"
    );

    let bytes = encode_to_vec(&Envelope::new(ArmCommand::move_to(Pose::default()))).unwrap();
    let err = decode::<ArmCommand>(&bytes[..bytes.len() - 4]).unwrap_err();
    assert!(matches!(err, DecodeError::Malformed { .. }), "{err}");
}

#[test]
fn decode_refuses_an_unknown_variant() {
    #[derive(Debug, Serialize, Deserialize)]
    struct Fake {
        kind: String,
    }
    impl Message for Fake {
        const TYPE: &'static str = "arm.command";
    }
    let bytes = encode_to_vec(&Envelope::new(Fake { kind: "fly".into() })).unwrap();
    let err = decode::<ArmCommand>(&bytes).unwrap_err();
    assert!(err.to_string().contains("unknown variant `fly`"), "{err}");
}

#[test]
fn envelope_reads_as_plain_named_fields() {
    // What a Python `msgpack.unpackb(raw)` would see, via serde_json's generic value.
    let cmd = ArmCommand::MoveToPose {
        target: Pose::new(0.25, 0.0, 0.1, 0.0, 1.5, 0.0),
        path: PathKind::Linear,
    };
    let mut bytes = Vec::new();
    encode(&Envelope::new(cmd), &mut bytes).unwrap();
    let v: serde_json::Value = rmp_serde::from_slice(&bytes).unwrap();
    assert_eq!(v["msg_type"], "arm.command");
    assert_eq!(v["schema_version"], 1);
    assert_eq!(
        v["body"],
        serde_json::json!({
            "kind": "move_to_pose",
            "target": {"x": 0.25, "y": 0.0, "z": 0.1, "roll": 0.0, "pitch": 1.5, "yaw": 0.0},
            "path": "linear"
        })
    );
}

fn sample_object() -> DetectedObject {
    DetectedObject {
        id: "obj-7".into(),
        label: "red cube".into(),
        workspace_id: "niryo_ws".into(),
        timestamp_unix_s: 1_700_000_000.5,
        position: ObjectPosition {
            center_of_mass: Point3::new(0.28, 0.04, 0.015),
            center: Point3::new(0.281, 0.041, 0.015),
        },
        image_coordinates: ImageCoordinates {
            center_rel: RelPoint { u: 0.5, v: 0.25 },
            center_of_mass_rel: RelPoint { u: 0.5, v: 0.26 },
            bounding_box_rel: RelBox {
                u_min: 0.45,
                v_min: 0.2,
                u_max: 0.55,
                v_max: 0.3,
            },
        },
        dimensions: Dimensions {
            width_m: 0.03,
            height_m: 0.03,
            size_m2: 0.0009,
        },
        gripper_rotation_rad: 0.785,
        confidence: 0.91,
        class_id: 3,
    }
}

#[test]
fn detected_object_has_the_exact_json_shape_of_the_spec() {
    let json = serde_json::to_string(&sample_object()).unwrap();
    assert_eq!(
        json,
        concat!(
            r#"{"id":"obj-7","label":"red cube","workspace_id":"niryo_ws","timestamp":1700000000.5,"#,
            r#""position":{"center_of_mass":{"x":0.28,"y":0.04,"z":0.015},"center":{"x":0.281,"y":0.041,"z":0.015}},"#,
            r#""image_coordinates":{"center_rel":{"u":0.5,"v":0.25},"center_of_mass_rel":{"u":0.5,"v":0.26},"#,
            r#""bounding_box_rel":{"u_min":0.45,"v_min":0.2,"u_max":0.55,"v_max":0.3}},"#,
            r#""dimensions":{"width_m":0.03,"height_m":0.03,"size_m2":0.0009},"#,
            r#""gripper_rotation":0.785,"confidence":0.91,"class_id":3}"#
        )
    );
}

#[test]
fn detected_object_reads_python_json() {
    // As the Python server prints it (indent 2, its own key order).
    let python = r#"{
      "label": "red cube", "id": "obj-7", "workspace_id": "niryo_ws", "timestamp": 1700000000.5,
      "position": {"center": {"x": 0.281, "y": 0.041, "z": 0.015},
                   "center_of_mass": {"x": 0.28, "y": 0.04, "z": 0.015}},
      "image_coordinates": {"center_rel": {"u": 0.5, "v": 0.25},
                            "center_of_mass_rel": {"u": 0.5, "v": 0.26},
                            "bounding_box_rel": {"u_min": 0.45, "v_min": 0.2, "u_max": 0.55, "v_max": 0.3}},
      "dimensions": {"width_m": 0.03, "height_m": 0.03, "size_m2": 0.0009},
      "gripper_rotation": 0.785, "confidence": 0.91, "class_id": 3
    }"#;
    let obj: DetectedObject = serde_json::from_str(python).unwrap();
    assert_eq!(obj, sample_object());
}
