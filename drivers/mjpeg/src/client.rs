//! The MJPEG camera driver: one stream, the newest decoded frame, the reason when there is none.

use bytes::Bytes;
use futures::StreamExt;
use robotd_driver::camera_feed::{CameraFeed, FedCamera, PoseSource};
use robotd_protocol::camera::CameraIntrinsics;
use robotd_runtime::backoff::Backoff;
use std::sync::Arc;
use std::time::Duration;

/// An MJPEG-over-HTTP camera.
pub struct MjpegCamera {
    url: String,
    feed: CameraFeed,
}

impl std::fmt::Debug for MjpegCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MjpegCamera")
            .field("url", &self.url)
            .finish_non_exhaustive()
    }
}

impl MjpegCamera {
    /// A camera on the stream at `url` whose frames are `intrinsics.width × height` and arrive
    /// `latency` after they were taken (each frame is dated that much before its arrival).
    pub fn new(
        url: &str,
        intrinsics: CameraIntrinsics,
        latency: Duration,
        pose: PoseSource,
    ) -> Arc<Self> {
        Arc::new(Self {
            url: url.to_owned(),
            feed: CameraFeed::new(
                url,
                intrinsics,
                latency,
                pose,
                format!("connecting to the camera stream {url}"),
            ),
        })
    }

    fn set_problem(&self, reason: String) {
        self.feed.set_problem(reason);
    }

    /// Reads the stream for as long as robotd runs (spawn it on the runtime).
    pub async fn run_receiver(self: Arc<Self>) {
        robotd_runtime::telemetry::install_tls_provider();
        let client = match reqwest::Client::builder()
            .connect_timeout(Duration::from_secs(3))
            .build()
        {
            Ok(client) => client,
            Err(e) => {
                self.set_problem(format!("cannot create an HTTP client: {e}"));
                return;
            }
        };
        let mut backoff = Backoff::up_to(Duration::from_secs(2));
        loop {
            let problem = self.receive(&client, &mut backoff).await;
            self.set_problem(problem);
            tokio::time::sleep(backoff.next_delay()).await;
        }
    }

    /// One connection: frames until it fails; returns why it ended.
    async fn receive(&self, client: &reqwest::Client, backoff: &mut Backoff) -> String {
        let url = &self.url;
        let response = match client.get(url).send().await {
            Ok(r) => r,
            Err(e) => return format!("camera stream {url} unreachable: {e}"),
        };
        if !response.status().is_success() {
            return format!("camera stream {url} answered HTTP {}", response.status());
        }
        let content_type = response
            .headers()
            .get(reqwest::header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_owned();
        let Some(boundary) = boundary_of(&content_type) else {
            return format!(
                "{url} is not an MJPEG stream (Content-Type '{content_type}', expected \
                 multipart/x-mixed-replace with a boundary)"
            );
        };
        let chunks = futures::stream::unfold(response, |mut response| async move {
            match response.chunk().await {
                Ok(Some(bytes)) => Some((Ok::<Bytes, reqwest::Error>(bytes), response)),
                Ok(None) => None,
                Err(e) => Some((Err(e), response)),
            }
        });
        let parts = multipart_stream::ParserBuilder::new()
            .max_body_bytes(crate::MAX_FRAME_BYTES)
            .parse(Box::pin(chunks), &boundary);
        let mut parts = Box::pin(parts);
        while let Some(part) = parts.next().await {
            let part = match part {
                Ok(part) => part,
                Err(e) => return format!("camera stream {url}: {e}"),
            };
            match self.decode(&part.body) {
                Ok(rgb) => {
                    backoff.reset();
                    self.publish(rgb);
                }
                Err(reason) => {
                    // One bad frame is not a broken stream: say so and wait for the next.
                    self.set_problem(reason);
                }
            }
        }
        format!("camera stream {url} ended")
    }

    fn decode(&self, jpeg: &[u8]) -> Result<Vec<u8>, String> {
        let (rgb, w, h) = robotd_jpeg::decode_jpeg(jpeg)
            .map_err(|e| format!("a frame of {} is not usable: {e}", self.url))?;
        if (w, h) != (self.feed.intrinsics().width, self.feed.intrinsics().height) {
            return Err(format!(
                "the camera sends {w}×{h} frames but its intrinsics are for {}×{}; set \
                 robot.widowx.camera_intrinsics for this camera",
                self.feed.intrinsics().width,
                self.feed.intrinsics().height
            ));
        }
        Ok(rgb)
    }

    fn publish(&self, rgb: Vec<u8>) {
        self.feed.publish(rgb);
    }
}

/// The `boundary` parameter of a multipart Content-Type, without quotes or a leading `--`.
fn boundary_of(content_type: &str) -> Option<String> {
    let mut parts = content_type.split(';');
    let kind = parts.next()?.trim();
    if !kind.eq_ignore_ascii_case("multipart/x-mixed-replace") {
        return None;
    }
    parts.find_map(|p| {
        let (key, value) = p.split_once('=')?;
        if !key.trim().eq_ignore_ascii_case("boundary") {
            return None;
        }
        let value = value.trim().trim_matches('"');
        let value = value.strip_prefix("--").unwrap_or(value);
        (!value.is_empty()).then(|| value.to_owned())
    })
}

impl FedCamera for MjpegCamera {
    fn feed(&self) -> &CameraFeed {
        &self.feed
    }
}

#[cfg(test)]
mod tests {
    use super::boundary_of;

    #[test]
    fn boundaries_are_read_as_servers_write_them() {
        assert_eq!(
            boundary_of("multipart/x-mixed-replace; boundary=frame").as_deref(),
            Some("frame")
        );
        assert_eq!(
            boundary_of("multipart/x-mixed-replace;boundary=\"--myboundary\"").as_deref(),
            Some("myboundary")
        );
        assert_eq!(boundary_of("image/jpeg"), None);
        assert_eq!(boundary_of("multipart/x-mixed-replace"), None);
    }
}
