//! The MJPEG camera against real HTTP streams on loopback: frames of a test-pattern camera
//! served as an IP camera would, a server that is not a camera, and a stream that goes away.

use robotd_driver::{CameraDriver, CaptureInfo, DriverError};
use robotd_driver_mjpeg::{serve, MjpegCamera};
use std::sync::Arc;
use std::time::Duration;

/// A 640×480 camera that sees a fixed picture: smooth colour gradients with dark and bright
/// blocks, edges a JPEG encoder must keep (the real driver's fake needs no simulator).
struct TestPattern;

impl CameraDriver for TestPattern {
    fn size(&self) -> (u32, u32) {
        (640, 480)
    }

    fn intrinsics(&self) -> robotd_protocol::camera::CameraIntrinsics {
        robotd_driver::hardware::ned2_camera_intrinsics()
    }

    fn capture_into(&self, out: &mut [u8]) -> Result<CaptureInfo, DriverError> {
        for (i, pixel) in out.chunks_exact_mut(3).enumerate() {
            let (u, v) = (i % 640, i / 640);
            let block = (u / 80 + v / 80) % 3;
            let rgb = match block {
                0 => [(u * 255 / 640) as u8, (v * 255 / 480) as u8, 128],
                1 => [30, 30, 40],
                _ => [230, 225, 210],
            };
            pixel.copy_from_slice(&rgb);
        }
        Ok(CaptureInfo {
            camera_pose: nalgebra::Isometry3::identity(),
            timestamp_unix_ns: robotd_protocol::envelope::unix_now_ns(),
        })
    }
}

fn pattern_camera() -> Arc<dyn CameraDriver> {
    Arc::new(TestPattern)
}

fn mjpeg_camera(url: &str, source: &Arc<dyn CameraDriver>) -> Arc<MjpegCamera> {
    MjpegCamera::new(
        url,
        source.intrinsics(),
        Duration::from_millis(100),
        Arc::new(|| None),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_of_a_stream_arrive_decoded_and_dated_before_their_arrival() {
    let source = pattern_camera();
    let server = serve("127.0.0.1:0".parse().unwrap(), source.clone(), 30.0)
        .await
        .unwrap();
    let camera = mjpeg_camera(&server.url(), &source);
    let receiver = tokio::spawn(camera.clone().run_receiver());
    let (w, h) = camera.size();
    let mut frame = vec![0u8; (w * h * 3) as usize];
    let mut direct = frame.clone();
    source.capture_into(&mut direct).unwrap();
    for _ in 0..3 {
        tokio::time::timeout(Duration::from_secs(5), camera.frame_ready())
            .await
            .expect("a frame within 5 s")
            .unwrap();
        let before = robotd_protocol::envelope::unix_now_ns();
        let info = camera.capture_into(&mut frame).unwrap();
        assert!(info.timestamp_unix_ns + 100_000_000 <= before + 1_000_000);
    }
    // The decoded JPEG is the camera's image (to JPEG precision).
    let mean_error = frame
        .iter()
        .zip(&direct)
        .map(|(a, b)| f64::from(a.abs_diff(*b)))
        .sum::<f64>()
        / frame.len() as f64;
    assert!(mean_error < 6.0, "mean pixel error {mean_error}");
    receiver.abort();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_server_that_is_not_a_camera_and_a_stream_that_ends_are_named() {
    let source = pattern_camera();
    // A web server that answers HTML.
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let address = listener.local_addr().unwrap();
    tokio::spawn(async move {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        loop {
            let (mut stream, _) = listener.accept().await.unwrap();
            let mut buf = [0u8; 1024];
            let _ = stream.read(&mut buf).await;
            let _ = stream
                .write_all(
                    b"HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: 2\r\n\r\nhi",
                )
                .await;
        }
    });
    let camera = mjpeg_camera(&format!("http://{address}/"), &source);
    let receiver = tokio::spawn(camera.clone().run_receiver());
    let error = tokio::time::timeout(Duration::from_secs(5), camera.frame_ready())
        .await
        .unwrap()
        .unwrap_err();
    assert!(
        error.to_string().contains("is not an MJPEG stream"),
        "{error}"
    );
    receiver.abort();

    // A stream that goes away, then comes back on the same port.
    let server = serve("127.0.0.1:0".parse().unwrap(), source.clone(), 30.0)
        .await
        .unwrap();
    let address = server.address;
    let camera = mjpeg_camera(&server.url(), &source);
    let receiver = tokio::spawn(camera.clone().run_receiver());
    camera.frame_ready().await.unwrap();
    drop(server);
    let mut frame = vec![0u8; (640 * 480 * 3) as usize];
    let _ = camera.capture_into(&mut frame);
    let error = loop {
        match tokio::time::timeout(Duration::from_secs(5), camera.frame_ready())
            .await
            .unwrap()
        {
            Err(e) => break e,
            Ok(()) => {
                let _ = camera.capture_into(&mut frame);
            }
        }
    };
    assert!(error.to_string().contains("camera stream"), "{error}");
    let _server = serve(address, source.clone(), 30.0).await.unwrap();
    let back = tokio::time::timeout(Duration::from_secs(5), async {
        while camera.frame_ready().await.is_err() {}
    })
    .await;
    assert!(back.is_ok(), "the camera did not find the stream again");
    receiver.abort();
}
