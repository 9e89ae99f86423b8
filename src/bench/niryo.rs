//! `robotd bench niryo`: the niryo driver against the fake Ned2 on loopback.
//!
//! - a command round trip that moves nothing (`GET_JOINTS` through the driver's link: framing,
//!   JSON, reply matching), beside a raw TCP echo of the same request bytes in the same run;
//! - camera images through the link (`GET_IMAGE_COMPRESSED`: the fake renders and encodes,
//!   the driver receives and decodes), beside the JPEG decode alone.
//!
//! Both the fake and the driver run in this process, on this machine's two cores: the camera
//! figure includes the fake's rendering and JPEG encoding, which a real robot does on its own
//! computer.

use super::Latency;
use anyhow::{Context, Result};
use robotd_driver::RobotConfig;
use robotd_driver_niryo::fake::{FakeFaults, FakeNiryo};
use robotd_driver_niryo::{wire, NiryoCamera};
use serde::Serialize;
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};

/// Everything `robotd bench niryo` measures.
#[derive(Debug, Clone, Serialize)]
pub struct NiryoFigures {
    /// `GET_JOINTS` through the driver's link.
    pub command: Latency,
    /// The same request bytes echoed by a bare TCP server.
    pub raw_echo: Latency,
    /// command p50 / raw echo p50.
    pub ratio_p50: f64,
    /// Camera images fetched and decoded per second through the link.
    pub camera_fps: f64,
    /// Decoding one 640×480 JPEG alone, ms (p50).
    pub decode_ms_p50: f64,
    /// Round trips measured per variant.
    pub round_trips: usize,
    /// Images fetched.
    pub images: usize,
}

impl NiryoFigures {
    /// The human-readable table.
    pub fn table(&self) -> String {
        format!(
            "measure                                   value              target\n\
             GET_JOINTS round trip p50 / p99           {:>7.1} / {:>7.1} µs\n\
             raw TCP echo, same bytes p50 / p99        {:>7.1} / {:>7.1} µs\n\
             ratio p50                                 {:>7.2}            ≤ 1.5\n\
             camera: images/s through TCP + decode     {:>7.1}\n\
             JPEG decode alone p50                     {:>7.2} ms\n",
            self.command.p50_us,
            self.command.p99_us,
            self.raw_echo.p50_us,
            self.raw_echo.p99_us,
            self.ratio_p50,
            self.camera_fps,
            self.decode_ms_p50,
        )
    }
}

/// Runs the benchmark.
pub fn run(round_trips: usize, images: usize) -> Result<NiryoFigures> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    runtime.block_on(measure(round_trips.max(10), images.max(2)))
}

async fn measure(round_trips: usize, images: usize) -> Result<NiryoFigures> {
    let mut sim_config: RobotConfig = robotd_config::Config::default().robot;
    sim_config.time_scale = 0.05;
    sim_config.camera.lens_distortion = true;
    let sim = robotd_driver_sim::open(&sim_config)?;
    let fake = FakeNiryo::new(sim.robot, FakeFaults::default());
    let listener = TcpListener::bind("127.0.0.1:0").await?;
    let port = listener.local_addr()?.port();
    let served = tokio::spawn(fake.serve(listener));

    let link = robotd_driver_niryo::Link::new(robotd_driver_niryo::link::LinkSettings {
        host: "127.0.0.1".into(),
        port,
        connect_timeout: Duration::from_secs(2),
        query_timeout: Duration::from_secs(3),
        reconnect_max: Duration::from_secs(2),
        auto_calibrate: true,
        calibrate_timeout: Duration::from_secs(60),
    });
    let reconnector = tokio::spawn(link.clone().run_reconnector());
    link.wait_connected(Duration::from_secs(5))
        .await
        .map_err(anyhow::Error::msg)?;

    let mut samples = Vec::with_capacity(round_trips);
    for _ in 0..round_trips {
        let started = Instant::now();
        link.call("GET_JOINTS", &[], Duration::from_secs(3)).await?;
        samples.push(started.elapsed());
    }
    let command = Latency::of(&mut samples);

    let request = wire::encode_request("GET_JOINTS", &[])?;
    let raw_echo = echo_round_trips(&request, round_trips).await?;

    let camera = NiryoCamera::new(link.clone());
    let started = Instant::now();
    for _ in 0..images {
        camera.fetch().await.map_err(anyhow::Error::msg)?;
    }
    let camera_fps = images as f64 / started.elapsed().as_secs_f64();
    let (_, jpeg) = link
        .call("GET_IMAGE_COMPRESSED", &[], Duration::from_secs(3))
        .await?;
    let mut decodes = Vec::new();
    for _ in 0..images {
        let started = Instant::now();
        robotd_driver_niryo::camera::decode(&jpeg).map_err(anyhow::Error::msg)?;
        decodes.push(started.elapsed());
    }
    let decode_ms_p50 = Latency::of(&mut decodes).p50_us / 1000.0;
    reconnector.abort();
    served.abort();
    Ok(NiryoFigures {
        ratio_p50: command.p50_us / raw_echo.p50_us,
        command,
        raw_echo,
        camera_fps,
        decode_ms_p50,
        round_trips,
        images,
    })
}

/// Round trips of `bytes` through a bare echo server on loopback.
async fn echo_round_trips(bytes: &[u8], count: usize) -> Result<Latency> {
    let listener = TcpListener::bind("127.0.0.1:0").await?;
    let address = listener.local_addr()?;
    let size = bytes.len();
    let server = tokio::spawn(async move {
        let Ok((mut stream, _)) = listener.accept().await else {
            return;
        };
        let _ = stream.set_nodelay(true);
        let mut buffer = vec![0u8; size];
        while stream.read_exact(&mut buffer).await.is_ok() {
            if stream.write_all(&buffer).await.is_err() {
                return;
            }
        }
    });
    let mut stream = TcpStream::connect(address).await?;
    stream.set_nodelay(true)?;
    let mut back = vec![0u8; size];
    let mut samples = Vec::with_capacity(count);
    for _ in 0..count {
        let started = Instant::now();
        stream.write_all(bytes).await?;
        stream.read_exact(&mut back).await?;
        samples.push(started.elapsed());
    }
    server.abort();
    Ok(Latency::of(&mut samples))
}
