//! `robotd bench niryo`: the niryo driver against the fake Ned2 on loopback.
//!
//! - a command round trip that moves nothing (`GET_JOINTS` through the driver's link: framing,
//!   JSON, reply matching), beside a raw TCP echo of the same request bytes in the same run;
//! - camera images through the link (`GET_IMAGE_COMPRESSED`: the fake renders and encodes,
//!   the driver receives and decodes), beside the JPEG decode alone;
//! - perception on what a Ned2 sends: random scenes seen through the Ned2's distorted lens,
//!   each frame through the fake's JPEG (q90) and the driver's decoder, then the detector —
//!   recall and position error beside the same frames without the JPEG round trip, and the
//!   time from the received JPEG to objects (decode + detector).
//!
//! Both the fake and the driver run in this process, on this machine's two cores: the camera
//! figure includes the fake's rendering and JPEG encoding, which a real robot does on its own
//! computer.

use super::Latency;
use anyhow::{Context, Result};
use robotd_driver::RobotConfig;
use robotd_driver_niryo::{wire, NiryoCamera};
use robotd_fake_niryo::{FakeFaults, FakeNiryo};
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
    /// Objects found / objects on the table, through JPEG.
    pub jpeg_recall: f64,
    /// Position error p50 / p95 through JPEG, mm.
    pub jpeg_pos_err_p50_mm: f64,
    /// Position error p95 through JPEG, mm.
    pub jpeg_pos_err_p95_mm: f64,
    /// Recall on the same frames without the JPEG round trip.
    pub raw_recall: f64,
    /// Position error p95 on the same frames without the JPEG round trip, mm.
    pub raw_pos_err_p95_mm: f64,
    /// Received JPEG → objects (decode + detector), p50, ms.
    pub jpeg_to_objects_ms_p50: f64,
    /// Objects on the table over all scenes.
    pub objects: usize,
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
             JPEG decode alone p50                     {:>7.2} ms\n\
             perception through JPEG q90, {} objects:\n\
             · recall                                  {:>7.1} %          100 %\n\
             · position error p50 / p95                {:>7.2} / {:>5.2} mm   p95 ≤ 3 mm\n\
             · same frames without JPEG: recall, p95   {:>7.1} %, {:>5.2} mm\n\
             · received JPEG → objects p50             {:>7.2} ms          ≤ 30 ms\n",
            self.command.p50_us,
            self.command.p99_us,
            self.raw_echo.p50_us,
            self.raw_echo.p99_us,
            self.ratio_p50,
            self.camera_fps,
            self.decode_ms_p50,
            self.objects,
            self.jpeg_recall * 100.0,
            self.jpeg_pos_err_p50_mm,
            self.jpeg_pos_err_p95_mm,
            self.raw_recall * 100.0,
            self.raw_pos_err_p95_mm,
            self.jpeg_to_objects_ms_p50,
        )
    }
}

/// Runs the benchmark.
pub fn run(round_trips: usize, images: usize, scenes: usize) -> Result<NiryoFigures> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    let mut figures = runtime.block_on(measure(round_trips.max(10), images.max(2)))?;
    perception_through_jpeg(scenes.max(1), &mut figures)?;
    Ok(figures)
}

/// Random scenes through the Ned2's lens, detected with and without the JPEG round trip.
fn perception_through_jpeg(scenes: usize, figures: &mut NiryoFigures) -> Result<()> {
    use robotd_perception::eval::{quantile, random_objects, rng, score, Lab};
    let mut lab = Lab::new(2.0, true).context("setting up the simulated camera")?;
    let table = robotd_perception::labels::LabelTable::builtin();
    let workspace = lab.workspace().clone();
    let mut rng = rng(2026);
    let (mut objects, mut found_jpeg, mut found_raw) = (0, 0, 0);
    let (mut jpeg_errors, mut raw_errors, mut times) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..scenes {
        let specs = random_objects(&mut rng, &table, &workspace, 5);
        lab.set_objects(&specs).context("placing objects")?;
        let (id, ts) = lab.capture().context("rendering")?;
        let raw = lab.detect(id, ts).context("detecting")?;
        let jpeg = robotd_render::encode_jpeg(lab.frame(), 640, 480, 90)?;
        let started = Instant::now();
        let decoded = robotd_driver_niryo::camera::decode(&jpeg).map_err(anyhow::Error::msg)?;
        lab.frame_mut().copy_from_slice(&decoded);
        let through = lab.detect(id, ts).context("detecting")?;
        times.push(started.elapsed());
        let truth = lab.objects();
        for (detections, found, errors) in [
            (&raw, &mut found_raw, &mut raw_errors),
            (&through, &mut found_jpeg, &mut jpeg_errors),
        ] {
            for o in score(&truth, &detections.objects).objects {
                if let Some(p) = o.position_error_m {
                    *found += 1;
                    errors.push(p * 1000.0);
                }
            }
        }
        objects += truth.len();
    }
    figures.objects = objects;
    figures.jpeg_recall = found_jpeg as f64 / objects.max(1) as f64;
    figures.raw_recall = found_raw as f64 / objects.max(1) as f64;
    figures.jpeg_pos_err_p50_mm = quantile(&jpeg_errors, 0.5);
    figures.jpeg_pos_err_p95_mm = quantile(&jpeg_errors, 0.95);
    figures.raw_pos_err_p95_mm = quantile(&raw_errors, 0.95);
    figures.jpeg_to_objects_ms_p50 = Latency::of(&mut times).p50_us / 1000.0;
    Ok(())
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

    let link = robotd_driver_niryo::Link::new(
        robotd_driver_niryo::link::LinkSettings {
            host: "127.0.0.1".into(),
            port,
            connect_timeout: Duration::from_secs(2),
            query_timeout: Duration::from_secs(3),
            reconnect_max: Duration::from_secs(2),
            // The fake starts calibrated; a link without a policy never calibrates by itself.
            auto_calibrate: false,
            calibrate_timeout: Duration::from_secs(60),
        },
        None,
    );
    let reconnector = tokio::spawn(link.clone().run_reconnector());
    link.wait_connected(Duration::from_secs(5))
        .await
        .map_err(anyhow::Error::msg)?;

    // Interleaved, one of each per round, so both see the same machine.
    let request = wire::encode_request("GET_JOINTS", &[])?;
    let mut echo = Echo::start(request.len()).await?;
    let (mut commands, mut echoes) = (
        Vec::with_capacity(round_trips),
        Vec::with_capacity(round_trips),
    );
    for _ in 0..round_trips {
        let started = Instant::now();
        link.call("GET_JOINTS", &[], Duration::from_secs(3)).await?;
        commands.push(started.elapsed());
        echoes.push(echo.round_trip(&request).await?);
    }
    let command = Latency::of(&mut commands);
    let raw_echo = Latency::of(&mut echoes);

    let camera = NiryoCamera::new(link.clone(), false);
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
        jpeg_recall: f64::NAN,
        jpeg_pos_err_p50_mm: f64::NAN,
        jpeg_pos_err_p95_mm: f64::NAN,
        raw_recall: f64::NAN,
        raw_pos_err_p95_mm: f64::NAN,
        jpeg_to_objects_ms_p50: f64::NAN,
        objects: 0,
        round_trips,
        images,
    })
}

/// A bare echo server on loopback and a client connected to it.
struct Echo {
    stream: TcpStream,
    back: Vec<u8>,
    server: tokio::task::JoinHandle<()>,
}

impl Echo {
    /// Starts the server for messages of `size` bytes and connects to it.
    async fn start(size: usize) -> Result<Echo> {
        let listener = TcpListener::bind("127.0.0.1:0").await?;
        let address = listener.local_addr()?;
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
        let stream = TcpStream::connect(address).await?;
        stream.set_nodelay(true)?;
        Ok(Echo {
            stream,
            back: vec![0u8; size],
            server,
        })
    }

    /// One round trip of `bytes`.
    async fn round_trip(&mut self, bytes: &[u8]) -> Result<Duration> {
        let started = Instant::now();
        self.stream.write_all(bytes).await?;
        self.stream.read_exact(&mut self.back).await?;
        Ok(started.elapsed())
    }
}

impl Drop for Echo {
    fn drop(&mut self) {
        self.server.abort();
    }
}
