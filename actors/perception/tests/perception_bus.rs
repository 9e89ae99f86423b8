//! The perception actor on a real bus: frames in shared memory in, detections out.

use robotd_perception::detector::{ColourDetector, ColourDetectorSettings};
use robotd_perception::eval::{random_objects, rng, Lab};
use robotd_perception::labels::LabelTable;
use robotd_perception::{Perception, Pipeline};
use robotd_protocol::arm::ArmState;
use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::objects::Detections;
use robotd_runtime::bus::{Bus, BusOptions, FramePublisher, Subscriber};
use robotd_topics::{ARM_STATE, CAMERA_FRAMES, CAMERA_INTRINSICS, PERCEPTION_DETECTIONS};
use std::time::Duration;

fn publish(publisher: &FramePublisher, rgb: &[u8], frame_id: u64) -> u64 {
    let mut frame = publisher.loan().unwrap();
    frame.pixels_mut()[..rgb.len()].copy_from_slice(rgb);
    let header = frame.header_mut();
    header.frame_id = frame_id;
    let now = unix_now_ns();
    header.timestamp_unix_ns = now;
    frame.send().unwrap();
    now
}

/// The perception actor on `bus` with the built-in colour detector and `table`, measuring with
/// `intrinsics` on the sheet of `workspace`.
fn start_perception(
    bus: &Bus,
    intrinsics: &robotd_protocol::camera::CameraIntrinsics,
    workspace: &robotd_protocol::workspace::WorkspaceInfo,
    table: LabelTable,
) -> Perception {
    let pipeline = Pipeline::new(
        intrinsics,
        vec![workspace.clone()],
        Box::new(ColourDetector::new(
            table.clone(),
            ColourDetectorSettings::default(),
        )),
    )
    .unwrap();
    Perception::start(bus, pipeline, table).unwrap()
}

async fn detections_of(sub: &mut Subscriber<Detections>, frame_id: u64) -> Detections {
    loop {
        let msg = tokio::time::timeout(Duration::from_secs(5), sub.recv())
            .await
            .expect("detections within 5 s")
            .unwrap();
        if msg.body.frame_id == frame_id {
            return msg.body;
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_become_detections_with_their_frame_id_and_steadiness() {
    let mut lab = Lab::new(2.0, false).unwrap();
    let workspace = lab.workspace().clone();
    let table = LabelTable::builtin();
    let objects = random_objects(&mut rng(3), &table, &workspace, 4);
    lab.set_objects(&objects).unwrap();
    lab.capture().unwrap();

    let namespace = format!("test-perc-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "perception-test")).unwrap();
    let pipeline = Pipeline::new(
        &lab.intrinsics(),
        vec![workspace.clone()],
        Box::new(ColourDetector::new(
            table,
            ColourDetectorSettings::default(),
        )),
    )
    .unwrap();
    let perception = Perception::start(
        &bus,
        pipeline,
        robotd_perception::labels::LabelTable::builtin(),
    )
    .unwrap();
    let frames = bus.frame_publisher(&CAMERA_FRAMES).unwrap();
    let arm = bus.publisher(&ARM_STATE).unwrap();
    let mut detections = bus.subscriber(&PERCEPTION_DETECTIONS).unwrap();

    // A frame of the scene: every object, tagged with the frame's id and time.
    let taken = publish(&frames, lab.frame(), 1);
    let d = detections_of(&mut detections, 1).await;
    assert_eq!(d.workspace_id, "niryo_ws");
    assert_eq!(d.timestamp_unix_ns, taken);
    assert_eq!(d.source, "robotd");
    assert!(d.steady, "no arm heard of: a fixed camera is steady");
    assert_eq!(d.objects.len(), objects.len(), "{:?}", d.objects);

    // While the arm moves, frames are published as not steady.
    let mut state = ArmState {
        joints: Default::default(),
        tool_pose: workspace.observation_pose,
        moving: true,
        collision_detected: false,
        calibrated: true,
        estop_engaged: false,
        still_since_unix_ns: 0,
    };
    // The state is in the actor's queue before the frame: it reads states on each frame.
    arm.publish(&state).unwrap();
    publish(&frames, lab.frame(), 2);
    assert!(!detections_of(&mut detections, 2).await.steady);

    // Once it has stopped, the next frame is steady again.
    state.moving = false;
    state.still_since_unix_ns = robotd_protocol::envelope::unix_now_ns();
    arm.publish(&state).unwrap();
    publish(&frames, lab.frame(), 3);
    assert!(detections_of(&mut detections, 3).await.steady);

    // A frame without the sheet (the camera looks elsewhere): no workspace, no objects.
    let grey = vec![90u8; lab.frame().len()];
    publish(&frames, &grey, 4);
    let d = detections_of(&mut detections, 4).await;
    assert_eq!(d.workspace_id, "");
    assert!(d.objects.is_empty());
    // Taken at rest at the observation pose: the health report says the workspace is not seen.
    let view = perception
        .stats()
        .workspace_view()
        .expect("a view from the pose");
    assert!(!view.visible, "{view:?}");
    assert_eq!(view.workspace_id, "niryo_ws");
    assert!(
        view.reason
            .starts_with("no workspace in view: none of the 4 workspace markers"),
        "{view:?}"
    );
    publish(&frames, lab.frame(), 5);
    detections_of(&mut detections, 5).await;
    assert!(perception.stats().workspace_view().unwrap().visible);

    let stats = perception.stats();
    assert!(stats.frames.load(std::sync::atomic::Ordering::Relaxed) >= 4);
    perception.shutdown();
}

/// Waits for detections from `source`.
async fn detections_from(sub: &mut Subscriber<Detections>, source: &str) -> Detections {
    loop {
        let msg = tokio::time::timeout(Duration::from_secs(5), sub.recv())
            .await
            .expect("detections within 5 s")
            .unwrap();
        if msg.body.source == source {
            return msg.body;
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pixel_detections_from_the_bus_are_placed_like_robotds_own_or_refused_with_a_reason() {
    use robotd_protocol::pixels::{PixelDetection, PixelDetections};
    use robotd_topics::PERCEPTION_PIXEL_DETECTIONS;
    use std::sync::atomic::Ordering;

    let mut lab = Lab::new(2.0, false).unwrap();
    let workspace = lab.workspace().clone();
    let table = LabelTable::builtin();
    let objects = random_objects(&mut rng(5), &table, &workspace, 1);
    lab.set_objects(&objects).unwrap();
    lab.capture().unwrap();
    let namespace = format!("test-perc-px-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "perception-test")).unwrap();
    let perception = start_perception(&bus, &lab.intrinsics(), &workspace, table);
    let frames = bus.frame_publisher(&CAMERA_FRAMES).unwrap();
    let pixels = bus.publisher(&PERCEPTION_PIXEL_DETECTIONS).unwrap();
    let mut detections = bus.subscriber(&PERCEPTION_DETECTIONS).unwrap();

    publish(&frames, lab.frame(), 1);
    let ours = detections_of(&mut detections, 1).await;
    let object = &ours.objects[0];
    let b = &object.image_coordinates.bounding_box_rel;
    let (w, h) = (640.0, 480.0);
    let bbox_px = [
        (b.u_min * w) as u32,
        (b.v_min * h) as u32,
        (b.u_max * w).ceil() as u32,
        (b.v_max * h).ceil() as u32,
    ];
    let message = |frame_id, camera_pose| PixelDetections {
        frame_id,
        camera_pose,
        source: "test-detector".into(),
        objects: vec![PixelDetection {
            label: "Thing".into(),
            confidence: 0.8,
            class_id: 3,
            bbox_px,
            mask_pixels: None,
        }],
    };
    // The frame perception just processed (its header pose is all zeros).
    pixels.publish(&message(1, [0.0; 6])).unwrap();
    let theirs = detections_from(&mut detections, "test-detector").await;
    assert_eq!(theirs.frame_id, 1);
    assert_eq!(theirs.workspace_id, "niryo_ws");
    let placed = &theirs.objects[0];
    assert_eq!(placed.label, "thing");
    assert_eq!(placed.class_id, 3);
    let (a, c) = (placed.xy(), object.xy());
    let apart = ((a.x_m - c.x_m).powi(2) + (a.y_m - c.y_m).powi(2)).sqrt();
    assert!(
        apart < 0.01,
        "placed {apart:.4} m from robotd's own detection"
    );
    assert_eq!(perception.stats().external.placed.load(Ordering::SeqCst), 1);

    // A frame from another camera pose: refused, with the reason.
    pixels
        .publish(&message(7, [0.3, 0.0, 0.2, 0.0, 1.5, 0.0]))
        .unwrap();
    // An invalid message: refused too.
    let mut bad = message(1, [0.0; 6]);
    bad.source = "robotd".into();
    pixels.publish(&bad).unwrap();
    let stats = perception.stats();
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    while stats.external.refused.load(Ordering::SeqCst) < 2 {
        assert!(std::time::Instant::now() < deadline, "two refusals");
        // Perception reads pixel detections between frames: give it frames.
        publish(&frames, lab.frame(), 2);
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let reason = stats.external.last_refusal.lock().unwrap().clone().unwrap();
    assert!(reason.contains("source"), "{reason}");
    assert_eq!(stats.external.placed.load(Ordering::SeqCst), 1);
    perception.shutdown();
}

/// The mean distance, mm, from each object of `objects` to the nearest detection (and how
/// many objects had none within 2 cm).
fn placement_error(objects: &[robotd_sim::ObjectSpec], d: &Detections) -> (f64, usize) {
    let mut total = 0.0;
    let mut missed = 0;
    for o in objects {
        let nearest = d
            .objects
            .iter()
            .map(|seen| {
                let p = seen.xy();
                (p.x_m - o.x_m).hypot(p.y_m - o.y_m)
            })
            .fold(f64::INFINITY, f64::min);
        if nearest < 0.02 {
            total += nearest * 1000.0;
        } else {
            missed += 1;
        }
    }
    (total / (objects.len() - missed).max(1) as f64, missed)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn intrinsics_that_change_on_the_bus_are_measured_with_from_the_next_frame() {
    // The image carries the lens's distortion; perception starts with the lens unknown (no
    // distortion), as it does when the robot sends its calibration only once it connects.
    let mut lab = Lab::new(0.0, true).unwrap();
    let workspace = lab.workspace().clone();
    let table = LabelTable::builtin();
    let objects = random_objects(&mut rng(11), &table, &workspace, 6);
    lab.set_objects(&objects).unwrap();
    lab.capture().unwrap();
    let lens = lab.intrinsics();
    let mut unknown_lens = lens.clone();
    unknown_lens.distortion = [0.0; 5];

    let namespace = format!("test-perc-k-{}", std::process::id());
    let bus = Bus::open(BusOptions::new(&namespace, "perception-test")).unwrap();
    let perception = start_perception(&bus, &unknown_lens, &workspace, table);
    let frames = bus.frame_publisher(&CAMERA_FRAMES).unwrap();
    let intrinsics = bus.publisher(&CAMERA_INTRINSICS).unwrap();
    let mut detections = bus.subscriber(&PERCEPTION_DETECTIONS).unwrap();

    publish(&frames, lab.frame(), 1);
    let before = placement_error(&objects, &detections_of(&mut detections, 1).await);
    // The camera actor publishes the lens it now knows.
    intrinsics.publish(&lens).unwrap();
    publish(&frames, lab.frame(), 2);
    let after = placement_error(&objects, &detections_of(&mut detections, 2).await);
    eprintln!(
        "{} objects: {:.2} mm mean ({} missed) with the lens unknown, {:.2} mm ({} missed) once \
         it came on the bus",
        objects.len(),
        before.0,
        before.1,
        after.0,
        after.1
    );
    assert_eq!(after.1, 0, "every object seen once the lens is known");
    assert!(after.0 < 1.5, "{after:?}");
    assert!(
        before.1 > 0 || before.0 > after.0 + 0.5,
        "the lens made no difference: before {before:?}, after {after:?}"
    );
    perception.shutdown();
}
