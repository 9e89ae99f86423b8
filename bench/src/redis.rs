//! `robotd bench redis`: camera frames to Redis, beside the bus's own frame rate.
//!
//! One run, one simulated 640×480 camera frame of a random scene (rendered once), against a
//! real `redis-server` (started on a free port unless `--redis URL` names one):
//!
//! 1. **Bus baseline**: frames published on `camera/frames` and read back in shared memory,
//!    as fast as they go.
//! 2. **Publish path**: each frame from the bus → copied → JPEG quality 85 → base64 entry →
//!    `XADD robot_camera MAXLEN ~ 5` acknowledged by Redis, one after the other. Per-frame
//!    time (receipt to acknowledgement) and frames per second; JPEG and XADD times apart.
//! 3. **The running edge**: the real [`RedisEdge`] at `camera_fps` = 60 while frames are
//!    published as fast as possible for a few seconds: what it published per second, what it
//!    dropped, and the camera's publish rate meanwhile (it must not slow down: the edge never
//!    makes the camera wait).

use super::Latency;
use anyhow::{bail, Context, Result};
use robotd_perception::eval::{random_objects, rng, Lab};
use robotd_perception::labels::LabelTable;
use robotd_protocol::envelope::unix_now_ns;
use robotd_protocol::geometry::Pose;
use robotd_redis::camera::encode_jpeg;
use robotd_redis::wire::{camera_entry, FrameMeta, ROBOT_CAMERA};
use robotd_redis::{RedisEdge, RedisEdgeSettings, Trust};
use robotd_runtime::bus::{Bus, BusOptions, FramePublisher};
use robotd_topics::CAMERA_FRAMES;
use serde::Serialize;
use std::time::{Duration, Instant};

/// Everything `robotd bench redis` measures.
#[derive(Debug, Clone, Serialize)]
pub struct RedisFigures {
    /// Frames per second through `camera/frames` alone (publish + read in shared memory).
    pub bus_frames_per_s: f64,
    /// Frames per second from the bus to an acknowledged `XADD` (sequential).
    pub frames_per_s: f64,
    /// Median time from a frame's receipt to Redis's acknowledgement, ms.
    pub publish_ms_p50: f64,
    /// 99th percentile of the same, ms.
    pub publish_ms_p99: f64,
    /// Median JPEG encoding time (quality 85), ms.
    pub jpeg_ms_p50: f64,
    /// Median `XADD` round trip of one entry, ms.
    pub xadd_ms_p50: f64,
    /// Size of one `robot_camera` entry (JPEG as base64 plus fields), KiB.
    pub entry_kib: f64,
    /// Entries per second the running edge published at `camera_fps` = 60.
    pub edge_frames_per_s: f64,
    /// Frames the running edge dropped (queue full) in that time.
    pub edge_dropped: u64,
    /// The camera's publish rate while the edge ran, frames per second.
    pub bus_frames_per_s_with_edge: f64,
    /// The camera's publish rate without the edge, same loop, same run.
    pub bus_publish_per_s_alone: f64,
    /// Frames measured in 1 and 2.
    pub frames: usize,
}

impl RedisFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        format!(
            "measure                                         value\n\
             bus only: camera/frames publish + read          {:>9.0} frames/s\n\
             bus → JPEG q85 → XADD acknowledged              {:>9.1} frames/s\n\
             publish per frame p50 / p99                     {:>6.2} / {:>6.2} ms\n\
             of which JPEG encode p50                        {:>9.2} ms\n\
             of which XADD round trip p50                    {:>9.2} ms\n\
             robot_camera entry                              {:>9.1} KiB\n\
             running edge at camera_fps = 60                 {:>9.1} frames/s ({} dropped)\n\
             camera publish rate alone / with the edge       {:>6.0} / {:>6.0} frames/s\n",
            self.bus_frames_per_s,
            self.frames_per_s,
            self.publish_ms_p50,
            self.publish_ms_p99,
            self.jpeg_ms_p50,
            self.xadd_ms_p50,
            self.entry_kib,
            self.edge_frames_per_s,
            self.edge_dropped,
            self.bus_publish_per_s_alone,
            self.bus_frames_per_s_with_edge,
        )
    }
}

/// A redis-server this benchmark started; killed when dropped.
struct OwnRedis(std::process::Child);

impl Drop for OwnRedis {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn start_redis() -> Result<(OwnRedis, String)> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let child = std::process::Command::new("redis-server")
        .args(["--port", &port.to_string(), "--bind", "127.0.0.1"])
        .args(["--save", "", "--appendonly", "no"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .context("starting redis-server (install it, or pass --redis URL)")?;
    let guard = OwnRedis(child);
    let deadline = Instant::now() + Duration::from_secs(10);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        if Instant::now() > deadline {
            bail!("redis-server did not listen on port {port} within 10 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok((guard, format!("redis://127.0.0.1:{port}/0")))
}

fn publish(publisher: &FramePublisher, rgb: &[u8], id: u64) -> Result<()> {
    let mut frame = publisher.loan()?;
    frame.pixels_mut()[..rgb.len()].copy_from_slice(rgb);
    let header = frame.header_mut();
    header.frame_id = id;
    header.timestamp_unix_ns = unix_now_ns();
    frame.send()?;
    Ok(())
}

/// Publishes frames as fast as the loop goes (yielding to the runtime between frames) for
/// 3 s; returns how many and the seconds taken.
async fn publish_flat_out(
    publisher: &FramePublisher,
    rgb: &[u8],
    first_id: u64,
) -> Result<(u64, f64)> {
    let started = Instant::now();
    let mut published = 0u64;
    while started.elapsed() < Duration::from_secs(3) {
        publish(publisher, rgb, first_id + published)?;
        published += 1;
        tokio::task::yield_now().await;
    }
    Ok((published, started.elapsed().as_secs_f64()))
}

/// Runs the benchmark with `frames` frames, against `redis_url` or a redis-server of its own.
pub fn run(frames: usize, redis_url: Option<String>) -> Result<RedisFigures> {
    let (_own, url) = match redis_url {
        Some(url) => (None, url),
        None => {
            let (guard, url) = start_redis()?;
            (Some(guard), url)
        }
    };
    let mut lab = Lab::new(2.0, false).context("setting up the simulated camera")?;
    let workspace = lab.workspace().clone();
    let specs = random_objects(&mut rng(11), &LabelTable::builtin(), &workspace, 5);
    lab.set_objects(&specs)?;
    lab.capture()?;
    let rgb = lab.frame().to_vec();
    let (w, h) = (640usize, 480usize);

    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let namespace = format!("bench-redis-{}", std::process::id());
        let bus = Bus::open(BusOptions::new(&namespace, "bench-redis"))?;
        let publisher = bus.frame_publisher(&CAMERA_FRAMES)?;
        let mut subscriber = bus.frame_subscriber(&CAMERA_FRAMES)?;

        // 1. The bus alone.
        let started = Instant::now();
        for i in 0..frames as u64 {
            publish(&publisher, &rgb, i)?;
            let sample = subscriber.recv().await?;
            std::hint::black_box(sample.pixels()[w * h * 3 / 2]);
        }
        let bus_frames_per_s = frames as f64 / started.elapsed().as_secs_f64();

        // 2. The publish path, frame by frame.
        let client = redis::Client::open(url.as_str())?;
        let mut conn = robotd_redis::writer::connect(&client)
            .await
            .with_context(|| format!("connecting to {url}"))?;
        let (mut totals, mut jpegs, mut xadds) = (Vec::new(), Vec::new(), Vec::new());
        let mut entry_bytes = 0;
        let started = Instant::now();
        for i in 0..frames as u64 {
            publish(&publisher, &rgb, 1_000_000 + i)?;
            let sample = subscriber.recv().await?;
            let t0 = Instant::now();
            let pixels = sample.pixels()[..w * h * 3].to_vec();
            drop(sample);
            let jpeg = encode_jpeg(&pixels, w, h).map_err(anyhow::Error::msg)?;
            let t1 = Instant::now();
            let meta = FrameMeta {
                frame_id: i,
                timestamp_unix_s: unix_now_ns() as f64 / 1e9,
                size: (w as u32, h as u32),
                workspace_id: &workspace.id,
                robot_pose: Pose::new(0.17, 0.0, 0.28, 0.0, 1.5, 0.0),
            };
            let entry = camera_entry("bench", &meta, &jpeg, None);
            entry_bytes = entry.value_bytes();
            let mut cmd = redis::cmd("XADD");
            cmd.arg(ROBOT_CAMERA).arg("MAXLEN").arg("~").arg(5).arg("*");
            for (k, v) in &entry.fields {
                cmd.arg(*k).arg(v.as_bytes());
            }
            let t2 = Instant::now();
            let _: String = cmd.query_async(&mut conn).await?;
            let t3 = Instant::now();
            totals.push(t3 - t0);
            jpegs.push(t1 - t0);
            xadds.push(t3 - t2);
        }
        let frames_per_s = frames as f64 / started.elapsed().as_secs_f64();
        let total = Latency::of(&mut totals);
        let jpeg = Latency::of(&mut jpegs);
        let xadd = Latency::of(&mut xadds);
        drop(subscriber);

        // 3. The camera publishing flat out, first alone, then with the edge running.
        let (alone, alone_s) = publish_flat_out(&publisher, &rgb, 3_000_000).await?;
        let target = robotd_redis::resolve_target(Some(&url), None, &|_| None)
            .map_err(anyhow::Error::msg)?
            .context("no Redis target")?;
        let edge = RedisEdge::start(
            &bus,
            RedisEdgeSettings {
                target,
                instance: "bench".into(),
                camera_fps: 60.0,
                annotated_fps: 0.0,
                objects_fps: 0.0,
                trust: Trust::Builtin,
                max_entry_bytes: 16 << 20,
                intrinsics: lab.intrinsics(),
                workspaces: vec![workspace.clone()],
                label_table: LabelTable::builtin(),
            },
        )?;
        let status = edge.status();
        let deadline = Instant::now() + Duration::from_secs(5);
        while status.state() != robotd_redis::LinkState::Connected {
            if Instant::now() > deadline {
                bail!("the edge did not connect to {url}");
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let before = status.counted(ROBOT_CAMERA, "published");
        let (published, elapsed) = publish_flat_out(&publisher, &rgb, 2_000_000).await?;
        tokio::time::sleep(Duration::from_millis(200)).await;
        let edge_published = status.counted(ROBOT_CAMERA, "published") - before;
        let edge_dropped = status.counted(ROBOT_CAMERA, "dropped_queue_full");
        edge.shutdown().await;

        Ok(RedisFigures {
            bus_frames_per_s,
            frames_per_s,
            publish_ms_p50: total.p50_us / 1000.0,
            publish_ms_p99: total.p99_us / 1000.0,
            jpeg_ms_p50: jpeg.p50_us / 1000.0,
            xadd_ms_p50: xadd.p50_us / 1000.0,
            entry_kib: entry_bytes as f64 / 1024.0,
            edge_frames_per_s: edge_published as f64 / elapsed,
            edge_dropped,
            bus_frames_per_s_with_edge: published as f64 / elapsed,
            bus_publish_per_s_alone: alone as f64 / alone_s,
            frames,
        })
    })
}
