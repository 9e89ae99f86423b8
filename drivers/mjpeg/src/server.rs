//! An MJPEG-over-HTTP server: frames of any camera driver, as an IP camera sends them.
//!
//! Every GET gets `multipart/x-mixed-replace` with one JPEG part (with Content-Length) per
//! frame, at most `fps` per second. Each client gets its own frames; a slow client only
//! slows itself. For `robotd fake-widowx` and the tests.

use robotd_driver::CameraDriver;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

const BOUNDARY: &str = "robotdframe";

/// A running MJPEG server.
#[derive(Debug)]
pub struct MjpegServer {
    /// Where it listens.
    pub address: SocketAddr,
    task: tokio::task::JoinHandle<()>,
}

impl MjpegServer {
    /// The stream's URL.
    pub fn url(&self) -> String {
        format!("http://{}/stream.mjpg", self.address)
    }
}

impl Drop for MjpegServer {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Serves `camera`'s frames on `listen` at up to `fps` frames per second.
pub async fn serve(
    listen: SocketAddr,
    camera: Arc<dyn CameraDriver>,
    fps: f64,
) -> std::io::Result<MjpegServer> {
    let listener = TcpListener::bind(listen).await?;
    let address = listener.local_addr()?;
    let period = Duration::from_secs_f64(1.0 / fps.clamp(0.1, 120.0));
    let task = tokio::spawn(async move {
        // The clients' streams live in this set: dropping the server (aborting this task)
        // ends them all, as unplugging a camera would.
        let mut clients = tokio::task::JoinSet::new();
        loop {
            tokio::select! {
                accepted = listener.accept() => {
                    let Ok((stream, _)) = accepted else { continue };
                    let camera = camera.clone();
                    clients.spawn(async move {
                        if let Err(e) = stream_to(stream, camera, period).await {
                            tracing::debug!(error = %e, "MJPEG client left");
                        }
                    });
                }
                Some(_) = clients.join_next(), if !clients.is_empty() => {}
            }
        }
    });
    Ok(MjpegServer { address, task })
}

async fn stream_to(
    mut stream: TcpStream,
    camera: Arc<dyn CameraDriver>,
    period: Duration,
) -> std::io::Result<()> {
    // Read the request head (and ignore it: every path is the stream).
    let mut head = Vec::new();
    let mut buf = [0u8; 1024];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = stream.read(&mut buf).await?;
        if n == 0 || head.len() > 16 * 1024 {
            return Ok(());
        }
        head.extend_from_slice(&buf[..n]);
    }
    stream
        .write_all(
            format!(
                "HTTP/1.1 200 OK\r\nContent-Type: multipart/x-mixed-replace; boundary={BOUNDARY}\r\n\
                 Cache-Control: no-cache\r\nConnection: close\r\n\r\n"
            )
            .as_bytes(),
        )
        .await?;
    let (width, height) = camera.size();
    let mut rgb = vec![0u8; (width * height * 3) as usize];
    let mut ticker = tokio::time::interval(period);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        ticker.tick().await;
        let captured = {
            let camera = camera.clone();
            let mut frame = std::mem::take(&mut rgb);
            tokio::task::spawn_blocking(move || {
                let result = camera.capture_into(&mut frame).map(|_| ());
                (frame, result)
            })
            .await
        };
        let Ok((frame, result)) = captured else {
            return Ok(());
        };
        rgb = frame;
        if result.is_err() {
            continue;
        }
        let jpeg = robotd_jpeg::encode_jpeg(&rgb, width, height, 90)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        let header = format!(
            "--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
            jpeg.len()
        );
        stream.write_all(header.as_bytes()).await?;
        stream.write_all(&jpeg).await?;
        stream.write_all(b"\r\n").await?;
    }
}
