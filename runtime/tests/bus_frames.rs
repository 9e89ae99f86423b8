//! Camera frames: written once into shared memory, read in place, latest wins.

mod common;

use robotd_runtime::bus::{FrameTopic, Overflow, FRAME_BYTES};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frame_arrives_with_its_header_and_pixels() {
    const FRAMES: FrameTopic = FrameTopic::new("camera", Overflow::latest_wins(2));
    let bus = common::fresh_bus("frames");
    let mut first = bus.frame_subscriber(&FRAMES).unwrap();
    let mut second = bus.frame_subscriber(&FRAMES).unwrap();
    let publisher = bus.frame_publisher(&FRAMES).unwrap();
    let mut frame = publisher.loan().unwrap();
    frame.header_mut().frame_id = 42;
    frame.header_mut().camera_pose = [0.17, 0.0, 0.28, 0.0, 1.57, 0.0];
    for (i, pixel) in frame.pixels_mut().iter_mut().enumerate() {
        *pixel = (i % 251) as u8;
    }
    assert_eq!(frame.send().unwrap(), 2);
    let a = first.recv().await.unwrap();
    let b = second.recv().await.unwrap();
    for sample in [&a, &b] {
        assert_eq!(sample.header().frame_id, 42);
        assert_eq!(sample.header().camera_pose[4], 1.57);
        assert_eq!(sample.pixels().len(), FRAME_BYTES);
        assert!(sample
            .pixels()
            .iter()
            .enumerate()
            .all(|(i, &p)| p == (i % 251) as u8));
        assert!(sample.header().timestamp_unix_ns > 0);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_slow_viewer_gets_the_newest_frames_and_the_camera_never_waits() {
    const FRAMES: FrameTopic = FrameTopic::new("camera", Overflow::latest_wins(2));
    let bus = common::fresh_bus("frames");
    let mut viewer = bus.frame_subscriber(&FRAMES).unwrap();
    let publisher = bus.frame_publisher(&FRAMES).unwrap();
    for id in 0..6 {
        let mut frame = publisher.loan().unwrap();
        frame.header_mut().frame_id = id;
        frame.send().unwrap();
    }
    assert_eq!(viewer.recv().await.unwrap().header().frame_id, 4);
    assert_eq!(viewer.recv().await.unwrap().header().frame_id, 5);
    assert!(viewer.try_recv().unwrap().is_none());
}
